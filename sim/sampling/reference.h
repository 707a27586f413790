// Matched-pair sampling against a reference design (rtsim run --reference DIR; Ekman and
// Stenstrom, ISPASS 2005, compare two designs on the same sample).
//
// An architect sweeping designs knows one of them in full: DIR is the output folder of a skip run
// of that reference design that measured every unit of the frame (--set
// sim.sample_period_units=1: counter for counter the full run; its stats.json gives the frame's
// totals). A sampled run of another design on the same frame then also
// runs the reference design with its own sampling plan, same seed, same units (a child process,
// once per plan: the result is kept in DIR for the sweep's other points), and regresses each of
// its units' figures on the reference's figure in the same unit, whose frame total DIR knows,
// before the four functional auxiliaries (sim/sampling/sampler.h). Two designs' units differ far
// less from each other than units differ from what the functional tracer can say of them: box and
// triangle units twice as slow, paired with the default design, on the 24 1080p frames of
// bench_sampled.py at 1 in 20, took the cycles' mean error from 1.26% to 0.31% (worst frame 2.67%
// to 0.54%); offline, slower DRAM gave 2.3% -> 0.8% and L1 and L2 eight and sixteen times smaller
// 2.8% -> 2.0% (docs/sampling.md). The reference's measured units
// were simulated with the same warm-up and cache replay as the run's own, so the simulation's
// bias in them mostly cancels: bunny primary's +1.2 points fell to +0.2.
#pragma once

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/sampling/frame_profile.h"
#include "sim/sampling/sampler.h"

namespace rtsim {

// A sampled_units.csv: a column per name, a row per unit.
struct UnitTable {
    std::vector<std::string> names;
    std::map<std::string, std::vector<double>> cols;
    size_t rows = 0;
    bool has(const std::string& name) const { return cols.count(name) != 0; }
};

// Parses sampled_units.csv text; `path` names it in errors (InputError).
UnitTable parse_units_csv(const std::string& text, const std::string& path);

// The units of the run in folder `dir` (one that measured every unit: --set
// sim.sample_period_units=1 in the skip design, in units whose size divides `unit_tiles`), merged
// to this run's units of `unit_tiles` tiles in frame order and put in order of their summed cycles
// (ties by unit), for SamplingParams::unit_order. `what` names the option in errors (InputError:
// not such a run, units that do not divide this run's, or a damaged table).
std::vector<uint32_t> read_unit_order(const std::string& dir, const std::string& what,
                                      uint64_t unit_tiles);

// read_unit_order's units balanced on the frame's work per cycle (balance_unit_order, `units`
// the frame profile's): the order a sampled run's strata are cut from. InputError also when
// the run has not as many units as `units`.
std::vector<uint32_t> read_strata_order(const std::string& dir, const std::string& what,
                                        uint64_t unit_tiles, const std::vector<AuxFigures>& units,
                                        uint64_t period_units);

// Strata of a period's units in order of the reference's cycles are cut in groups of this many;
// within a group the units are put in order of their functional work per reference cycle.
constexpr uint64_t kBalancedStrata = 4;

// Reorders `order` (units by their `unit_cycles`, as read_unit_order gives them) within each run
// of kBalancedStrata * period_units consecutive units by work per cycle (the profile's
// `units`; a unit without cycles counts 0; ties by unit), so that the strata cut from the group
// span its range of work per cycle as well as of cycles (docs/sampling.md).
// std::invalid_argument when the sizes differ.
void balance_unit_order(std::vector<uint32_t>& order, const std::vector<double>& unit_cycles,
                        const std::vector<AuxFigures>& units, uint64_t period_units);

// A counter's column in sampled_units.csv: like blocks summed ("core[3].rays" -> "core.rays").
std::string summed_counter_name(std::string name);

struct Reference {
    std::string dir;
    nlohmann::json summary;  // stats.json's sampling.reference
    // Every sampled_units.csv column's frame total (like blocks summed), from the full run.
    std::map<std::string, double> totals;
    UnitTable matched;  // the reference design's sample with this run's plan
    std::map<uint64_t, size_t> row_of_unit;
    // The cycles after the last hand-out, in the reference's full run and in its matched
    // sample: a sampled run's own drain follows its last detailed rays, not the frame's, and
    // the pair corrects it by the reference's difference (exactly, for the reference design).
    double drain_full_cycles = 0, drain_matched_cycles = 0;
    // The matched sample's column `name` (a row per measured unit); nullptr if it has none.
    const std::vector<double>* column(const std::string& name) const;
    // The matched sample's row of each of `units`; throws InputError, naming DIR, for a unit it
    // did not measure.
    std::vector<size_t> rows_of(const std::vector<uint64_t>& units) const;
};

// What a paired run (or --sample-order) reads of an every-unit run: its stats.json's fields
// that a paired run uses, and its units' cycles. Parsing the whole 55 KB
// stats.json and scanning the 1.5 MB sampled_units.csv of a 1080p frame took 16 million
// instructions, a tenth of a 1-in-50 paired run of a small frame; the first run keeps both in a
// digest beside them, keyed by the two files' XXH3 (a rerun into the folder changes them, and
// its digest is then made again). A folder that cannot take it only costs the next run a parse.
struct EveryUnitRun {
    nlohmann::json stats;
    std::vector<double> cycles;  // per unit
    uint64_t merge = 1;          // its units per unit of the reading run
    // Its units, merged to the reading run's, in order of their cycles (for
    // SamplingParams::unit_order).
    std::vector<uint32_t> order() const;
    // That order balanced on the frame's work per cycle (balance_unit_order): the strata's.
    std::vector<uint32_t> strata_order(const std::vector<AuxFigures>& units,
                                       uint64_t period_units) const;
};

// The every-unit run in folder `dir`, in units of `unit_tiles` tiles; `where` names it in errors
// (InputError: not such a run, units that do not divide the reader's, a damaged table).
EveryUnitRun read_every_unit_run(const std::string& dir, const std::string& where,
                                 uint64_t unit_tiles);

}  // namespace rtsim

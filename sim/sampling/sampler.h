// Sampled simulation (sim.sampled = true): systematic sampling of the ray stream
// with functional warming, as SMARTS (Wunderlich et al., ISCA 2003) samples instruction streams.
//
// The stream of rays, in the order the work source hands them out, is cut into units of
// sample_unit_rays. One unit in sample_period_units is measured, from a start unit drawn from
// the workload seed; the sample_warmup_rays before it run in detail unmeasured (they fill the
// cores' slots, MSHRs and queues), and so does the ray after it (its hand-out ends the unit).
// Every other ray is fast-forwarded: its fetches warm the caches it would have reached
// (MemoryPort::warm: tags and replacement order, no time, no counts) and it never reaches a
// core. A measured unit contributes, between the hand-out of its first ray and of the ray after
// it, the cycles that passed and the change of every registered counter. Each total is then
// estimated with a 95% confidence interval (sim/sampling/estimators.h) by regression on what the
// functional tracer knows of every ray before timing (the auxiliaries below: work, first-touched
// lines, node steps, rays), and the cycles also get the drain the sampled run measured after its
// last hand-out. Units of background pixels and units of dense geometry differ in cycles many times
// over, far less in cycles per step: a ratio to work alone has a far narrower interval than a
// ratio to rays (on a 96x96 bunny frame, 13 measured units: +-42% over rays).
//
// Tracing every ray bounds the speed-up: the fast model costs about what the functional tracer
// does (docs/sampling.md). With skip = true (sim.sample_fast_forward = skip)
// units are groups of unit_tiles tiles of the image instead, and a tile far from a measured unit
// is never generated or traced: only the warm_tiles before each measured unit warm the caches
// functionally, and the warmup_tiles right before it run in detail unmeasured (more, going back,
// until they hold warmup_tile_rays rays). What the skipped
// tiles would have told comes from the frame's profile (sim/sampling/frame_profile.h), computed
// once per frame and cached: the units' auxiliaries for the same regression, and the lines each
// skipped tile fetched, which are loaded into the caches where the tile would have run. Without the
// profile the totals could only be expanded from the measured units (+-20-50% on 1080p frames at 1
// in 10), and a cold L2 biased DRAM bytes by +144% (bunny AO, 1 in 10). The profile's tile lines,
// run through an LRU of the L2's geometry, also count the frame's capacity misses unit by unit
// (sim/sampling/functional_l2.h), known then like its first fills.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "models/core.h"
#include "models/stats.h"
#include "models/timing.h"
#include "sim/sampling/estimators.h"
#include "sim/sampling/frame_profile.h"
#include "sim/sampling/functional_l2.h"
#include "sim/sampling/registry.h"
#include "workloads/step.h"

namespace rtsim {

class Cache;

struct Reference;  // sim/sampling/reference.h

// Above this share of a frame's work in units heavier than any measured unit, the cycles'
// estimate extrapolates: it is given without an interval, and a caveat says why.
constexpr double kMaxExtrapolatedWorkShare = 0.10;

struct SamplingParams {
    uint64_t unit_rays = 1024;
    uint64_t period_units = 10;  // one unit measured in this many
    uint64_t warmup_rays = 512;  // detailed, unmeasured, before each measured unit
    uint64_t seed = 1;           // picks the measured units
    int64_t first_unit = -1;     // systematic: this start, if 0 or more
    // Stratified: one unit drawn at random in each run of period_units (a systematic sample's
    // fixed stride can alias with the image: 1080p rows of 240 tiles against a stride of 160
    // tiles put every measured unit in 3 column bands). Systematic: every period_units-th.
    bool stratified = true;
    // Skip design (above): units of unit_tiles tiles of a frame of `tiles` tiles.
    bool skip = false;
    uint64_t unit_tiles = 4, warm_tiles = 0, warmup_tiles = 2, warmup_tile_rays = 128, tiles = 0;
    // Skip design: per tile, its rays that reach the cores (FrameProfile::tile_rays; empty:
    // unknown). A measured unit's detailed warm-up then reaches back past its warmup_tiles
    // until it holds warmup_tile_rays rays: the slots hold the last rays before the unit whatever
    // tiles they came from, and background tiles bring none.
    std::vector<uint32_t> tile_rays;
    // Skip design: per tile, its work (steps and rays; empty: unknown), and the least work the
    // warm-up holds besides its rays. The rays of the last window still run when the next one
    // starts, as they did in the full run for about as long as their work takes; a warm-up of
    // background rays (no steps, no time) does not outlast them, and the measured unit after it
    // shares the chip with rays from far away. Reaching back until it holds its rays' share of
    // the frame's work, it holds what in the full run was in flight when the unit started.
    std::vector<uint64_t> tile_work;
    uint64_t warmup_work = 0;
    // Skip design: the frame's units in the order the strata are cut from (empty: the frame's
    // own order, so a stratum is period_units neighbouring units). Units sorted by what they
    // cost in a run that measured every unit (--sample-order; a paired run's reference) put
    // like units in a stratum: docs/sampling.md.
    std::vector<uint32_t> unit_order;
    std::string unit_order_of;  // the run whose units' cycles gave unit_order (reported)
    // Skip design, sim.sample_design = work: per unit, its work (steps + rays) from the frame's
    // profile. The sample is then drawn where the work is (SampleDesign says how).
    bool by_work = false;
    std::vector<uint64_t> unit_work;
    // Design `work`: per unit, its rays (from the profile), and the rays of the frame's first
    // units with work that are measured outright as its start-up (0: none).
    std::vector<uint64_t> unit_ray_counts;
    uint64_t startup_rays = 0;
};

// An estimate as stats.json holds it ({value, lo, hi, half_width_pct}), scaled by `scale` and
// moved by `offset`.
// An infinite half-width (no interval the data support) is written as null lo, hi and
// half_width_pct; a caveat, when there is one, beside them.
nlohmann::json estimate_json(const Estimate& e, double scale = 1.0, double offset = 0.0);

// An estimate's half_width_pct from its JSON: infinite where it is null.
double half_width_pct_of(const nlohmann::json& estimate);

// Which units a sample measures, and in the skip design what becomes of each tile; a value
// type, so the work source's helper thread can ask it which tiles to generate.
class SampleDesign {
  public:
    explicit SampleDesign(const SamplingParams& params);
    bool measured_unit(uint64_t unit) const;
    // The unit measured first in the order strata are cut from.
    uint64_t first_unit() const;
    // Stratified design: the unit measured in stratum k (a hash of the seed and k).
    uint64_t pick(uint64_t stratum) const;
    // The unit drawn in stratum k of `size` units: a hash of the seed and k, below size.
    uint64_t draw(uint64_t stratum, uint64_t size) const;
    // Skip design: what becomes of tile t.
    enum class TileRole { Skipped, Warming, Warmup, Measured, After };
    TileRole tile_role(uint64_t tile) const;
    // Whether tile t is generated at all: not when skipped, nor when its rays are known and it
    // has none (it would hand nothing on; a sparse frame's warm-ups reach back over many:
    // 1080p camel diffuse, 1 in 50, generated 2,000 tiles and traced their primaries for the
    // 73 that had rays).
    bool wants_tile(uint64_t tile) const {
        return tile_role(tile) != TileRole::Skipped &&
               (params_.tile_rays.size() != params_.tiles || params_.tile_rays[tile] > 0);
    }
    const SamplingParams& params() const { return params_; }
    // Design `work`: whether unit u is measured with certainty (one of the frame's heaviest),
    // and the units the rest of the sample is drawn from (every unit with work that is not a
    // certainty unit). Units without work are never measured: they take no cycles.
    bool certainty_unit(uint64_t unit) const {
        return unit < certainty_.size() && certainty_[unit];
    }
    uint64_t certainty_units() const { return certainty_count_; }
    uint64_t drawn_population() const { return drawn_population_; }
    // Design `work`: strata of the drawn part (units of like work, equal work per stratum).
    uint64_t drawn_strata() const { return drawn_strata_; }
    // Design `work`: the units a measured unit stands for (its stratum's size; 1 for a
    // certainty unit).
    double design_weight(uint64_t unit) const {
        return unit < design_weight_.size() ? design_weight_[unit] : 0.0;
    }
    // Skip design: units in the frame.
    uint64_t units() const {
        return (params_.tiles + params_.unit_tiles - 1) / std::max<uint64_t>(1, params_.unit_tiles);
    }

  private:
    SamplingParams params_;
    uint64_t first_unit_ = 0;
    // Design `work`: the sample as a unit mask, the certainty units among it.
    void draw_by_work();
    std::vector<uint32_t> rank_;   // per unit, its place in params_.unit_order (empty: itself)
    std::vector<TileRole> roles_;  // skip design: every tile's, worked out once
    std::vector<uint8_t> measured_, certainty_;  // design `work`: per unit
    std::vector<double> design_weight_;          // design `work`: per unit
    uint64_t certainty_count_ = 0, drawn_population_ = 0, drawn_strata_ = 0;
};

// Meets each line once per pass: a stamp per line and a new stamp per pass, so starting a pass
// costs nothing (the replays below make thousands of passes over a few million line entries).
class LinePass {
  public:
    void resize(size_t lines) {
        stamp_.assign(lines, 0);
        now_ = 0;
    }
    void next() {
        if (++now_ == 0) {  // the stamp wrapped: forget every earlier pass
            std::fill(stamp_.begin(), stamp_.end(), 0);
            now_ = 1;
        }
    }
    // True the first time `line` is met in this pass.
    bool first(uint32_t line) {
        uint32_t& s = stamp_[line];
        if (s == now_) return false;
        s = now_;
        return true;
    }

  private:
    std::vector<uint32_t> stamp_;
    uint32_t now_ = 0;
};

// LinePass per (core, line), for up to 64 cores, over the lines of one L1 window (a few thousand
// of a frame's hundreds of thousands): a mask of the cores met per line, in an open-addressing
// table that grows past half full. Its slots carry the pass that filled them, so a new pass
// clears nothing. (A slot per line of the frame was 2.75 MB for 1080p bunny, every page of it a
// fresh-page fault, and a host cache miss per line met.)
class CoreLinePass {
  public:
    static constexpr size_t kMaxCores = 64;
    // Ready for passes meeting about `lines` distinct lines (more grow it).
    void reserve(size_t lines) {
        size_t slots = 64;
        while (slots < 2 * lines) slots *= 2;
        rehash(slots);
        now_ = 1;
        enabled_ = true;
    }
    bool enabled() const { return enabled_; }
    void next() {
        count_ = 0;
        if (++now_ == 0) {  // the stamp wrapped: forget every earlier pass
            std::fill(slots_.begin(), slots_.end(), Slot{});
            now_ = 1;
        }
    }
    // Of the cores in `cores` (a bit each), those that meet `line` for the first time in this
    // pass. `new_line`: whether the pass meets `line` for the first time.
    uint64_t first(uint32_t line, uint64_t cores, bool& new_line) {
        if (count_ >= grow_at_) rehash(2 * slots_.size());
        Slot& s = find(line);
        new_line = s.pass != now_;
        if (new_line) {
            s = Slot{0, line, now_};
            ++count_;
        }
        const uint64_t fresh = cores & ~s.met;
        s.met |= cores;
        return fresh;
    }

  private:
    struct Slot {
        uint64_t met = 0;  // the cores met in pass `pass`
        uint32_t line = 0;
        uint32_t pass = 0;  // the pass that filled the slot (0: none)
    };
    // Line's slot in this pass, or the free slot where it goes.
    Slot& find(uint32_t line) {
        size_t i = size_t((uint64_t(line) * 0x9E3779B97F4A7C15ull) >> shift_);
        while (slots_[i].pass == now_ && slots_[i].line != line) i = (i + 1) & mask_;
        return slots_[i];
    }
    void rehash(size_t slots) {
        std::vector<Slot> old = std::move(slots_);
        slots_.assign(slots, Slot{});
        mask_ = slots - 1;
        grow_at_ = slots / 2;  // grown when a line would fill more than half
        shift_ = 64;
        for (size_t n = slots; n > 1; n /= 2) --shift_;
        for (const Slot& s : old)
            if (s.pass == now_ && now_ != 0) find(s.line) = s;
    }
    std::vector<Slot> slots_;
    uint32_t now_ = 0, shift_ = 64;
    size_t mask_ = 0, grow_at_ = 0;
    size_t count_ = 0;  // lines met in this pass
    bool enabled_ = false;
};

// What skipped work would have taken: a least-squares fit of measured units' cycles on
// [1, work, new lines, rays], kept as running normal equations as units close. Below 8 units
// (twice its terms) it predicts cycles in proportion to work; with none, 0.
struct SkippedCyclesFit {
    static constexpr size_t kTerms = 4;
    using Terms = std::array<double, kTerms>;
    // The terms of `share` of a unit's (or a tile's, a ray's) figures, counted as `units` units.
    static Terms terms(const AuxFigures& aux, double units, double share = 1.0);
    std::array<Terms, kTerms> xtx{};
    Terms xty{};
    // A measured unit's terms (its count term 1) and cycles.
    void add(const Terms& x, double y);
    // Never below 0.
    double predict(const Terms& x) const;
};

class Sampler {
  public:
    // `ports`: per core, per StepKind, where its fetches enter the memory hierarchy (warmed in
    // turn, core by core, as the cores would have taken the rays). `counters`: what is measured.
    // `design`: the sample design of `params`, if one was made already (the run's ray source asks
    // it which tiles to generate); made here otherwise. The plan is read from the design, which
    // holds the one copy of it (a frame's per-tile rays and unit order among it).
    Sampler(const SamplingParams& params, std::vector<std::array<MemoryPort*, kStepKinds>> ports,
            const StatsRegistry& counters, std::shared_ptr<const SampleDesign> design = nullptr);

    // The next ray of the stream (work.rays of them: a packet counts its rays): true if it is
    // fast-forwarded (its fetches have warmed the caches and no core is to run it).
    // `tile`: the tile the ray came from (the skip design's units are tiles).
    bool fast_forward(const RayWork& work, int64_t tile = -1);
    // Fast-forwarded rays also warm what the traversal writes (stack spills and refills, hit
    // records) through each core's local memory, as the cores in `cores` would make them.
    void set_write_warming(std::vector<const Core*> cores) { write_cores_ = std::move(cores); }
    // With a prefetcher, the first fills are the lines rays first ask for (LineFirstTouches):
    // the skipped tiles' lines are marked asked for as the replay loads them.
    void set_first_demands(LineFirstTouches* touches) { first_demands_ = touches; }
    // The ray just judged detailed is handed out at `now`.
    void handed_out(Cycle now);
    // Whether the ray just judged detailed starts a window: rays were fast-forwarded, or tiles
    // with rays skipped, since the last detailed one.
    bool window_start() const { return window_start_; }
    // The cycles the work fast-forwarded or skipped right before the window that the ray just
    // judged starts would have taken in the full run: predicted from the units measured so far
    // (SkippedCyclesFit), 0 before any. The window waits that long (sim.sample_window_hold =
    // predicted).
    double window_hold_cycles() const;
    // The ray just judged detailed, which starts a window, is held at `now` until the chip has
    // drained: a measured unit still open ends now, where a slot asked for the next ray.
    void held(Cycle now);
    // The addresses rays fetch from ([base, end), in lines of line_bytes): every ray's first
    // touches of lines are then counted, a second auxiliary figure (DRAM traffic follows new
    // lines far more than work: compulsory misses).
    void set_line_range(uint64_t base, uint64_t end, uint32_t line_bytes);
    // Skip design: the frame's profile (its units' auxiliaries and each tile's lines), and the
    // L2, loaded with the lines of the tiles it skips where no core's memories are known (they
    // go through the cores' L1s otherwise). The run's own line counting (set_line_range) is
    // then not needed. Without a reference design and with an LRU L2, the frame's L2 misses are
    // counted functionally here, unit by unit (sim/sampling/functional_l2.h), through the cache in
    // `cache_dir` (the profile's folder; empty: none).
    void set_profile(const FrameProfile* profile, Cache* l2,
                     const std::string& cache_dir = std::string());
    // Per core and step kind, the L1 behind its port, when every port is an L1 whose warm()
    // reaches the L2 through nothing but links (a crossbar): the replay may then check each
    // line's tags itself (the direct route). Before set_profile.
    void set_l1s_over_l2(std::vector<std::array<Cache*, kStepKinds>> l1s) {
        l1s_over_l2_ = std::move(l1s);
    }
    // Skip design: matched-pair estimates against a reference design's figures in the same
    // units (sim/sampling/reference.h); each figure is regressed on the reference's first. Before
    // set_profile (a paired run does not count capacity misses).
    void set_reference(const Reference* reference) { reference_ = reference; }
    // The caches a fast-forward warms, asked for their geometry: how many lines an L1 holds and
    // whether the L1s and the L2 replace the least recently used line (replay_skipped_tiles),
    // the L2's line, sets and ways (its misses counted functionally over the whole frame:
    // sim/sampling/functional_l2.h), and what an L2 first fill adds to l2.fill_bytes and
    // dram.bytes (`dram_bytes_per_fill`, counter_estimates). Before set_profile, as
    // set_reference is.
    void set_caches(const Cache& l1, const Cache& l2, uint64_t dram_bytes_per_fill);

    // Waits for the functional counts of the frame's L2 and L1 misses (set_profile starts each on
    // a thread of its own) and returns the L2 count's host seconds (0: none), so that a run's host
    // time includes it.
    double wait_functional_l2();
    // The L1 count's host seconds, once waited for (0: none; stats.json's host.functional_l1_s).
    double functional_l1_seconds() const { return functional_l1_.seconds; }
    // What the cache of that count did ("off", "hit", "built", "rebuilt: why"; empty: no count).
    const std::string& functional_l2_cache() const { return functional_l2_.cache; }
    // Skip design: host seconds spent loading skipped tiles' lines into the caches (part of the
    // simulation's; stats.json's host.replay_s).
    double replay_seconds() const { return replay_seconds_; }
    // stats.json's "sampling" section: the plan, what ran in detail, and each estimate with
    // its interval. `end_cycle`: the sampled run's last cycle.
    nlohmann::json report(Cycle end_cycle);
    // After report: every counter's estimate and the frame's cycles ("cycles"), with their
    // jackknife replicates, for figures that combine them (energy; sim/energy.h). Empty when
    // report made no estimates.
    const JointEstimates& joint_estimates() const { return joint_; }
    // One line per measured unit (after report): its index, auxiliaries, cycles and the change of
    // every counter (like blocks' summed into one column), as CSV with a header. With every unit
    // measured (sample_period_units = 1) it is the frame's per-unit truth, for studying
    // estimators and sample designs offline (scripts/sampled_offline.py).
    std::string units_csv() const;
    // Closes a measured unit the frame ended in: its rays up to the last hand-out count, and
    // the cycles to it (called by report).
    void finish();

    // Whether the replay takes the direct route (set_profile; tests).
    bool replays_directly() const { return direct_l2_ != nullptr; }
    uint64_t rays_seen() const { return index_; }
    uint64_t rays_detailed() const { return detailed_; }

  private:
    // Per measured unit, the summed change of the counters named prefix...suffix ("l1[" and
    // ".hits": every L1's hits); `blocks` gets how many counters matched.
    std::vector<double> unit_sums(const std::string& prefix, const std::string& suffix,
                                  size_t* blocks = nullptr) const;
    // What is known of every ray before timing, the auxiliaries the totals are regressed on, in
    // the order they are fitted (sim/sampling/estimators.h): its work (steps plus one, its setup:
    // units of background pixels and of dense geometry differ in cycles many times over, far less
    // in cycles per step), the lines it touched first in the frame (DRAM traffic follows them:
    // compulsory misses), its node steps (node and triangle steps cost differently) and its
    // rays (an intercept per ray). On 1080p bunny frames, fitting all four rather than the
    // first two narrows a unit's residual from 27% to 20% of its cycles (primary rays) and from
    // 7.1% to 6.8% (AO).
    enum {
        kWork = kAuxWork,
        kNewLines = kAuxNewLines,
        kNodeSteps = kAuxNodeSteps,
        kRays = kAuxRays
    };
    using Aux = AuxFigures;
    SkippedCyclesFit hold_fit_;
    // The fit's terms of the work skipped since the last detailed ray, and of the work skipped
    // before the window the last detailed ray started.
    SkippedCyclesFit::Terms skipped_terms_{}, window_skipped_terms_{};
    // `share` of the work of `aux` skipped, as `units` units.
    void add_skipped(const Aux& aux, double units, double share = 1.0) {
        const SkippedCyclesFit::Terms x = SkippedCyclesFit::terms(aux, units, share);
        for (size_t i = 0; i < SkippedCyclesFit::kTerms; ++i) skipped_terms_[i] += x[i];
    }
    // Skip design, at the first ray of traced tile `tile`: loads the caches with the lines of
    // the tiles skipped since the last traced one, tile by tile: each line into the L1s of as
    // many cores as the tile had rays fetching it, and through them the L2. (Into the L2 alone,
    // the L1s stayed cold where the warm-up tiles before a unit had few rays: camel and homer
    // primary 1080p frames' cycles were 4-6% high.)
    void replay_skipped_tiles(uint64_t tile);
    // Loads the profile's tile lines [from, to), then the entries `then`, into the L2.
    void warm_l2_lines(uint32_t from, uint32_t to, const std::vector<uint32_t>& then = {});
    // Skip design: the measured units that handed out no ray, entered as zeros.
    void add_rayless_units(uint64_t units);
    // Records the open unit as measured: its auxiliaries, and the cycles and counter changes
    // from its start to `end`.
    void close_unit(const Aux& aux, Cycle end);
    // Every counter that moved in a measured unit, its total estimated by `total`; those that
    // follow the L2's first fills, from the frame's first fills (its distinct lines) and the
    // rest (less the measured units' `capacity` misses, and plus the frame's, where they were
    // counted functionally: capacity.x empty otherwise). `units`: in the frame.
    // `total(y, column, per_fill)`: the total of y, the change of the counter summed into
    // sampled_units.csv's `column`, less per_fill times the unit's L2 first fills.
    using TotalFn = std::function<Estimate(const std::vector<double>&, const std::string&, double)>;
    // Each counter's estimate as stats.json holds it, also added to `joint`.
    // `drawn`: the measured units the totals' spread comes from (of `units`).
    nlohmann::json counter_estimates(const TotalFn& total, double frame_first_fills,
                                     const Auxiliary& capacity, uint64_t units, size_t drawn,
                                     JointEstimates& joint) const;
    // Counters the functional tracer knows the frame's total of (box and triangle operations,
    // L1 accesses and bytes requested), calibrated to it in `joint` and `counters` (stats.json's)
    // where this run's own detailed rays show the identity; returns what was applied.
    nlohmann::json apply_functional_totals(nlohmann::json& counters, JointEstimates& joint,
                                           const std::array<double, kAuxiliaries>& frame) const;
    // Derived figures (hit rates, bandwidth, utilisations, stall shares) with their intervals.
    nlohmann::json figures(uint64_t units) const;
    // The ratio sum(y) / sum(x) over the frame from the measured units' changes: in design
    // `work`, combined over the certainty units (known) and the drawn ones.
    Estimate ratio_of(const std::vector<double>& y, const std::vector<double>& x,
                      uint64_t units) const;
    // Design `work`: positions (in cycles_) of the measured certainty units and drawn units.
    std::vector<size_t> certain_pos_, drawn_pos_;
    bool measured_unit(uint64_t unit) const { return design_->measured_unit(unit); }
    // Whether ray `i` runs in detail: in a measured unit, in the warm-up before one, or the
    // ray right after one.
    bool detailed_ray(uint64_t i) const;

    std::shared_ptr<const SampleDesign> design_;  // shared with the ray source, read only
    const SamplingParams& params_;                // the design's
    std::vector<std::array<MemoryPort*, kStepKinds>> ports_;
    uint32_t l2_line_bytes_ = 0;  // 0: no counter estimated from first fills
    uint64_t dram_bytes_per_fill_ = 0;
    uint64_t l1_lines_ = 0;  // 0: every skipped tile's lines go through the L1s
    bool l1_lru_ = false;
    bool l2_lru_ = false;
    uint64_t l2_sets_ = 0;
    uint32_t l2_ways_ = 0;
    uint64_t l1_sets_ = 0;
    uint32_t l1_ways_ = 0;
    // Skip design without a reference design, LRU L2: the frame's L2 misses counted
    // functionally, per unit (sim/sampling/functional_l2.h); unit_capacity_misses empty otherwise.
    // Counted on a thread of its own while the run simulates (45-75 ms for the 5.2 million tile
    // lines of a 1080p Cornell 2-bounce path frame), taken in report.
    std::future<FunctionalL2> functional_l2_pending_;
    FunctionalL2 functional_l2_;
    // Skip design without a reference design: the units' L1 misses as estimated functionally
    // (sim/sampling/functional_l2.h), a predictor the regression fits; counted beside the L2's.
    std::future<FunctionalL1> functional_l1_pending_;
    FunctionalL1 functional_l1_;
    const StatsRegistry& counters_;
    uint64_t index_ = 0;     // rays judged so far
    uint64_t detailed_ = 0;  // of them, run in detail
    size_t next_core_ = 0;   // whose memories the next fast-forwarded ray warms
    std::vector<const Core*> write_cores_;
    void warm_writes(const Core& core, const RayWork& work) const;
    uint64_t current_ = 0;  // index of the ray just judged
    // The ray just judged: its unit, and whether it is the first of it.
    uint64_t current_unit_ = 0;
    bool current_first_ = false;
    int64_t last_tile_ = -1;  // skip design: the tile of the ray before
    // Rays fast-forwarded or tiles with rays skipped since the last detailed ray; whether the
    // ray just judged detailed came after such a gap.
    bool gap_ = false, window_start_ = false;
    uint64_t tiles_traced_ = 0;  // skip design
    bool prefetching_ = false;   // a cache prefetches (set_caches): the replay warms through warm()
    LineFirstTouches* first_demands_ = nullptr;
    // The measured unit in progress: its start cycle and counters.
    bool open_ = false;
    uint64_t open_unit_ = 0;
    Cycle open_cycle_ = 0;
    std::vector<uint64_t> open_counts_;
    Cycle last_handout_ = 0;
    LineTracker lines_;
    const FrameProfile* profile_ = nullptr;
    const Reference* reference_ = nullptr;
    JointEstimates joint_;
    Cache* l2_ = nullptr;
    std::vector<std::array<Cache*, kStepKinds>> l1s_over_l2_;
    // The replay's direct route (set_profile), when every port is an L1 whose misses reach the
    // L2 through nothing but links, with the profile's line size at both levels: per core and
    // step kind its L1 (warm_line), and the L2; otherwise empty, and lines go through warm().
    std::vector<std::array<Cache*, kStepKinds>> direct_l1_;
    Cache* direct_l2_ = nullptr;
    uint64_t direct_first_line_ = 0;  // profile line 0 in lines of the caches
    void warm_l2_line(uint32_t entry);
    uint64_t replayed_tiles_ = 0;  // tiles before this one were traced or replayed
    double replay_seconds_ = 0;    // host seconds in replay_skipped_tiles
    size_t replay_core_ = 0;       // the core whose L1 the next replayed line goes to first
    // replay_skipped_tiles' L1 window and warm_l2_lines' last touches each meet a line once.
    LinePass line_pass_;
    std::vector<uint32_t> last_touches_;  // warm_l2_lines: the replay's last touches
    std::vector<uint32_t> l1_misses_;     // the L1 window's misses, in order, for the L2
    // The L1 window's last touches, (line entry, core), from the last.
    CoreLinePass core_line_pass_;
    std::vector<std::pair<uint32_t, uint32_t>> l1_last_touches_;
    Aux total_aux_{};     // of every ray judged
    Aux detailed_aux_{};  // of the rays run in detail
    // The lines (at the L1's line size) and bytes the rays' steps fetch: of the rays run in
    // detail, and (the design without a profile) of every ray judged.
    uint64_t detailed_fetch_lines_ = 0, detailed_fetch_bytes_ = 0;
    uint64_t total_fetch_lines_ = 0, total_fetch_bytes_ = 0;
    LineTracker l1_fetch_lines_{0, 0, 64};
    Aux current_aux_{};  // of the ray just judged
    Aux unit_aux_{};     // of the open unit's rays handed out so far
    // Per measured unit: its auxiliaries, cycles, and each counter's change.
    std::array<std::vector<double>, kAuxiliaries> aux_;
    std::vector<uint64_t> unit_index_;
    std::vector<double> cycles_;
    std::vector<std::vector<double>> deltas_;  // [counter][unit]
};

// What a sampler reaches of the chip it samples: the blocks a fast-forward warms and the
// counters a measured unit reads. A model knows nothing of sampling; the run assembles this.
struct SampledChip {
    // Per core, per StepKind, where its fetches enter the memory hierarchy.
    std::vector<std::array<MemoryPort*, kStepKinds>> ports;
    // The same as caches when every port is an L1 whose warm() reaches the L2 through nothing
    // but links (Sampler::set_l1s_over_l2); empty otherwise.
    std::vector<std::array<Cache*, kStepKinds>> l1s_over_l2;
    const StatsRegistry* counters = nullptr;
    std::vector<const Core*> cores;  // their traversal writes (spills, hit records) are warmed
    const Cache* l1 = nullptr;       // one core's L1: every core's has its geometry
    Cache* l2 = nullptr;
    uint64_t dram_bytes_per_l2_fill = 0;
};

// What a sampler knows of the frame before timing it.
struct SampledFrame {
    std::shared_ptr<const SampleDesign> design;  // made already (the ray source asks it)
    const FrameProfile* profile = nullptr;       // the skip layer's
    const Reference* reference = nullptr;        // a paired run's
    std::string cache_dir;                       // where profiles and their counts are kept
    uint64_t fetch_begin = 0, fetch_end = 0;     // the addresses rays fetch from (BVH layout)
};

}  // namespace rtsim

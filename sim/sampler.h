// Sampled simulation (sim.fidelity = sampled; issue 16): systematic sampling of the ray stream
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
// estimated with a 95% confidence interval (sim/sampling.h) by regression on what the functional
// tracer knows of every ray before timing (the auxiliaries below: work, first-touched lines,
// node steps, rays), and the cycles also get the drain the sampled run measured after its last
// hand-out. Units of background pixels and units of dense geometry differ in cycles many times
// over, far less in cycles per step: a ratio to work alone has a far narrower interval than a
// ratio to rays (on a 96x96 bunny frame, 13 measured units: +-42% over rays).
#pragma once

#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "models/core.h"
#include "models/stats.h"
#include "models/timing.h"
#include "workloads/step.h"

namespace rtsim {

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
};

class Sampler {
  public:
    // `ports`: per core, per StepKind, where its fetches enter the memory hierarchy (warmed in
    // turn, core by core, as the cores would have taken the rays). `counters`: what is measured.
    Sampler(const SamplingParams& params, std::vector<std::array<MemoryPort*, kStepKinds>> ports,
            const StatsRegistry& counters);

    // The next ray of the stream (work.rays of them: a packet counts its rays): true if it is
    // fast-forwarded (its fetches have warmed the caches and no core is to run it).
    bool fast_forward(const RayWork& work);
    // Fast-forwarded rays also warm what the traversal writes (stack spills and refills, hit
    // records) through each core's local memory, as the cores in `cores` would make them.
    void set_write_warming(std::vector<const Core*> cores) { write_cores_ = std::move(cores); }
    // The ray just judged detailed is handed out at `now`.
    void handed_out(Cycle now);
    // The addresses rays fetch from ([base, end), in lines of line_bytes): every ray's first
    // touches of lines are then counted, a second auxiliary figure (DRAM traffic follows new
    // lines far more than work: compulsory misses).
    void set_line_range(uint64_t base, uint64_t end, uint32_t line_bytes);

    // stats.json's "sampling" section: the plan, what ran in detail, and each estimate with
    // its interval. `end_cycle`: the sampled run's last cycle.
    nlohmann::json report(Cycle end_cycle);
    // Closes a measured unit the frame ended in: its rays up to the last hand-out count, and
    // the cycles to it (called by report).
    void finish();

    uint64_t rays_seen() const { return index_; }
    uint64_t rays_detailed() const { return detailed_; }

  private:
    // Per measured unit, the summed change of the counters named prefix...suffix ("l1[" and
    // ".hits": every L1's hits); `blocks` gets how many counters matched.
    std::vector<double> unit_sums(const std::string& prefix, const std::string& suffix,
                                  size_t* blocks = nullptr) const;
    // What is known of every ray before timing, the auxiliaries the totals are regressed on, in
    // the order they are fitted (sim/sampling.h): its work (steps plus one, its setup: units of
    // background pixels and of dense geometry differ in cycles many times over, far less in
    // cycles per step), the lines it touched first in the frame (DRAM traffic follows them:
    // compulsory misses), its node steps (node and triangle steps cost differently) and its
    // rays (an intercept per ray). On 1080p bunny frames, fitting all four rather than the
    // first two narrows a unit's residual from 27% to 20% of its cycles (primary rays) and from
    // 7.1% to 6.8% (AO).
    enum AuxIndex { kWork, kNewLines, kNodeSteps, kRays, kAuxiliaries };
    using Aux = std::array<uint64_t, kAuxiliaries>;
    // Records the open unit as measured: its auxiliaries, and the cycles and counter changes
    // from its start to `end`.
    void close_unit(const Aux& aux, Cycle end);
    // Derived figures (hit rates, bandwidth, utilisations, stall shares) with their intervals.
    nlohmann::json figures(uint64_t units) const;
    bool measured_unit(uint64_t unit) const {
        return unit % params_.period_units ==
               (params_.stratified ? pick(unit / params_.period_units) : first_unit_);
    }
    // Stratified design: the unit measured in stratum k (a hash of the seed and k).
    uint64_t pick(uint64_t stratum) const;
    // Whether ray `i` runs in detail: in a measured unit, in the warm-up before one, or the
    // ray right after one.
    bool detailed_ray(uint64_t i) const;

    SamplingParams params_;
    std::vector<std::array<MemoryPort*, kStepKinds>> ports_;
    const StatsRegistry& counters_;
    uint64_t first_unit_ = 0;
    uint64_t index_ = 0;     // rays judged so far
    uint64_t detailed_ = 0;  // of them, run in detail
    size_t next_core_ = 0;   // whose memories the next fast-forwarded ray warms
    std::vector<const Core*> write_cores_;
    void warm_writes(const Core& core, const RayWork& work) const;
    uint64_t current_ = 0;  // index of the ray just judged
    // The measured unit in progress: its start cycle and counters.
    bool open_ = false;
    uint64_t open_unit_ = 0;
    Cycle open_cycle_ = 0;
    std::vector<uint64_t> open_counts_;
    Cycle last_handout_ = 0;
    uint64_t first_line_ = 0, line_shift_ = 6;
    std::vector<uint64_t> touched_;  // a bit per line of the range: fetched before
    Aux total_aux_{};                // of every ray judged
    Aux current_aux_{};              // of the ray just judged
    Aux unit_aux_{};                 // of the open unit's rays handed out so far
    // Per measured unit: its auxiliaries, cycles, and each counter's change.
    std::array<std::vector<double>, kAuxiliaries> aux_;
    std::vector<double> cycles_;
    std::vector<std::vector<double>> deltas_;  // [counter][unit]
};

}  // namespace rtsim

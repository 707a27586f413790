// Chip assembly: instantiates the SystemC models a config asks for and wires them
// cores -> L1 -> shared L2 -> DRAM, registering every block's counters in one registry.
#pragma once

#include <functional>

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "models/cache.h"
#include "models/core.h"
#include "models/crossbar.h"
#include "models/dram.h"
#include "models/memory_block.h"
#include "models/ray_buffer.h"
#include "models/stats.h"
#include "models/unit.h"
#include "sim/dram_regions.h"
#include "sim/params.h"
#include "workloads/bvh.h"

namespace rtsim {

class Chip {
  public:
    // `layout`: where the treelets are (treelet mode loads them); the chip sees only addresses.
    // `dram_front`: when given, made around the DRAM model and placed in front of it (what the
    // L2 sees), e.g. a recorder of the requests that reach memory.
    Chip(const Params& params, RayWorkSource* source, const BvhLayout& layout,
         std::function<std::unique_ptr<DramModel>(DramModel&)> dram_front = {});
    // Cycle the last ray finished (valid after the simulation ran).
    Cycle total_cycles() const;
    // stats.json's sections "units", "caches", "bandwidth", "stalls", and "ray_buffer" and
    // "packets" when those blocks ran, each block's part from the block itself.
    nlohmann::json report(const ReportContext& ctx) const;
    // stats.json's "out_of_order": per kind of shared state, the requests it served after a
    // request that arrived later in simulated time. The fast model serves in the order the
    // simulator meets requests; where it claims exactness (a private L1 behind its in-order
    // issue port) these are 0.
    nlohmann::json out_of_order_report() const;
    // Every L1: the unified ones, or a split L1's node and triangle caches.
    std::vector<const Cache*> all_l1() const;

    StatsRegistry stats;
    // The stages the blocks run under the time-ordered engine (sim.fidelity = accurate).
    StageQueue stages;
    std::unique_ptr<DramModel> dram;
    std::unique_ptr<DramModel> dram_front;      // in front of dram, when asked for
    std::unique_ptr<DramRegions> dram_regions;  // in front of both: traffic by region
    std::unique_ptr<DramPort> dram_port;        // the L2's socket's way to dram_regions
    // memory_path.below_l2 (between the L2 and DRAM) and below_l1 (one per core, between its L1s
    // and the crossbar), when the config places blocks there.
    std::unique_ptr<MemoryBlock> below_l2;
    std::vector<std::unique_ptr<MemoryBlock>> below_l1_blocks;
    std::unique_ptr<Cache> l2;
    std::unique_ptr<LineFirstTouches> first_demands;  // sampled, with a prefetcher
    std::unique_ptr<Crossbar> crossbar;  // between the L1s and the L2 (none when unlimited)
    std::vector<std::unique_ptr<Cache>> l1;
    std::vector<std::unique_ptr<Cache>> l1_tri;          // l1.split: per-core triangle caches
    std::vector<std::unique_ptr<Cache>> treelet_caches;  // traversal.treelet_cache_kib > 0
    std::unique_ptr<IdealMemory> ideal_memory;           // sim.ideal_memory: the cores' only memory
    // Per StepKind, the units of the unit kind that tests it (box_unit[i], triangle_unit[i]).
    std::array<std::vector<std::unique_ptr<PipelinedUnit>>, kStepKinds> units;
    std::unique_ptr<RayBuffer> ray_buffer;  // traversal.mode = treelet
    std::vector<std::unique_ptr<Core>> cores;
    // Per core, per StepKind, the memory its fetches enter (L1, split L1, treelet cache).
    std::vector<std::array<MemoryPort*, kStepKinds>> core_memories;
    // The same as L1 caches, when every one reaches the L2 through nothing but the crossbar
    // (no treelet caches, no ideal memory); empty otherwise.
    std::vector<std::array<Cache*, kStepKinds>> l1s_over_l2;
    std::unique_ptr<ChipDriver> driver;  // runs the cores: the fidelity level's process
    // Per-window series (sim.window_cycles > 0), shared by all blocks of a kind.
    struct Series {
        std::unique_ptr<TimeSeries> dram_bytes, l1_fill_bytes, l2_fill_bytes, rays;
        std::array<std::unique_ptr<TimeSeries>, kStepKinds> unit_busy;  // per StepKind's units
    } series;
};

}  // namespace rtsim

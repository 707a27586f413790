// The effective config as typed block parameters. Every schema field reaches exactly one member
// through one table (config_bindings, sim/params.cpp): the schema path, the member, and the unit
// conversion if any. Nothing else reads a config value by its path, so a field cannot be dead or
// read twice (tests/sim/test_params.cpp checks the table against the schema).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "models/cache.h"
#include "models/core.h"
#include "models/dram.h"
#include "models/ray_buffer.h"
#include "models/timing.h"
#include "models/unit.h"
#include "workloads/bvh.h"

namespace rtsim {

struct TraversalParams {
    std::string mode;                  // a registered traversal mode
    int packet_size = 0;               // packet mode: rays per packet (SIMD lanes)
    uint64_t treelet_cache_bytes = 0;  // treelet mode: per-core treelet cache; 0: none
    Cycle treelet_cache_latency_cycles = 0;
};

struct SimParams {
    bool ideal_memory = false;
    bool ideal_units = false;
    uint64_t window_cycles = 0;  // time series windows; 0: none
    std::string fidelity;        // a registered fidelity level: the engine that times the rays
    bool sampled = false;        // sample the frame on that engine (sim/sampling/sampler.h)
    uint64_t sample_unit_rays = 1024, sample_period_units = 10, sample_warmup_rays = 512;
    int64_t sample_first_unit = -1;  // -1: drawn from the seed
    std::string sample_design = "stratified";
    uint64_t sample_seed = 0;  // 0: the workload's seed
    // "warm": every ray traced, the unmeasured ones warm the caches; "skip": units are tiles,
    // and tiles far from a measured unit are never generated or traced.
    std::string sample_fast_forward = "warm";
    uint64_t sample_unit_tiles = 4, sample_warm_tiles = 0, sample_warmup_tiles = 2,
             sample_warmup_tile_rays = 128;
    // A paired run's (--reference) unit size and warm-up, in place of the three above.
    uint64_t sample_paired_unit_tiles = 8, sample_paired_warmup_tiles = 1,
             sample_paired_warmup_tile_rays = 0;
    // The warm-up holds at least this many times the chip's ray slots (unpaired; paired).
    uint64_t sample_warmup_slot_fills = 4, sample_paired_warmup_slot_fills = 0;
    // An unpaired skip unit holds at least this many times the chip's ray slots in rays (0: off).
    uint64_t sample_unit_slot_fills = 0;
    uint64_t sample_startup_slot_fills = 8;
    // A detailed window after fast-forwarded rays starts after the cycles the skipped work would
    // have taken ("predicted"), once the rays before it have finished ("drain"), or at once
    // ("none"); a skip warm-up also holds its rays' share of the frame's work.
    std::string sample_window_hold = "predicted";
    // A predicted hold ends early once no more than this share of the chip's slots still
    // run rays from before the window.
    double sample_window_hold_release_share = 0.5;
    bool sample_warmup_work = true;
};

// energy.* (sim/energy.h): per-access and per-operation energies; the schema holds the defaults
// and their sources.
struct EnergyParams {
    double sram_8kib_pj = 0, sram_32kib_pj = 0, sram_1mib_pj = 0;
    double fp32_add_pj = 0, fp32_mul_pj = 0;
    double wire_pj_per_bit_mm = 0, crossbar_mm = 0;
    double dram_pj_per_byte = 0;
};

// Members outside the model structs have no meaningful C++ default: only binding sets them.
struct Params {
    std::string name;
    double clock_ghz = 0;
    int core_count = 0;
    CoreParams core;  // core.*, and traversal.treelet_prefetch
    // Per StepKind, the unit kind that tests it (box_unit.*, triangle_unit.*) and how many cores
    // share one (shared_by).
    std::array<UnitParams, kStepKinds> unit;
    std::array<int, kStepKinds> unit_shared_by{};
    CacheParams l1, l2;
    bool l1_split = false;
    double crossbar_bytes_per_cycle = 0;  // 0: no crossbar
    // memory_path.below_l1, below_l2: a registered memory block at each position, or "none";
    // each block's own section (memory_path.<block>) as the config gives it, by block name.
    std::array<std::string, 2> memory_path;
    nlohmann::json memory_block_config = nlohmann::json::object();
    std::string dram_model;  // a registered DRAM model
    DramParams dram;
    BvhBuildOptions bvh;
    uint32_t node_size_bytes = 0;  // 0: the stated size for the width and format
    uint32_t triangle_size_bytes = 0;
    uint32_t alpha_read_bytes = 16;  // the alpha data an any-hit shader call reads (0: none)
    TraversalParams traversal;
    RayBufferParams ray_buffer;  // ray_buffer.*, and traversal's treelet scheduler and batches
    SimParams sim;
    EnergyParams energy;
};

// One row of the table: a schema path and how its value reaches its member.
struct FieldBinding {
    std::string path;
    std::function<void(Params&, const nlohmann::json&)> set;
    // The member's value as JSON in the schema's unit (to compare a model struct's C++ default
    // with the schema's).
    std::function<nlohmann::json(const Params&)> get;
    // The member belongs to a model struct whose C++ default initializer must equal this field's
    // schema default (false where one struct serves two sections, e.g. CacheParams for l1 and
    // l2: its defaults are the first section's).
    bool cpp_default_mirrors_schema = true;
};

// Every schema field, in schema order.
const std::vector<FieldBinding>& config_bindings();

// Fills Params from an effective (validated) config document.
Params bind_params(const nlohmann::json& values);

}  // namespace rtsim

// Turns the registry's raw counters into stats.json: derived figures (rates, utilization,
// bandwidth) are computed here, at dump time, so counting stays cheap.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "models/stats.h"
#include "models/timing.h"

namespace rtsim {

struct ReportInputs {
    const StatsRegistry* stats = nullptr;
    Cycle total_cycles = 0;
    double clock_ghz = 1.0;
    int cores = 0;
    int box_pipelines_per_core = 1, triangle_pipelines_per_core = 1;  // per unit
    int box_units = 0, triangle_units = 0;  // unit instances (0: one per core)
    int ray_slots_per_core = 1;
    int dram_channels = 1;
    uint32_t ray_bytes = 0;     // treelet mode: bytes of one ray-buffer record
    uint64_t ray_capacity = 0;  // treelet mode: rays the buffer holds
    uint64_t rays = 0;          // rays simulated
};

// The stall causes of stats.json's "stalls" shares, in report order: the cores' causes
// (Core::stall_name), then "no_work" (slot cycles without a ray).
std::vector<std::string> stall_causes();
// A cause as people read it: "L1", "DRAM", "box unit".
std::string stall_cause_label(const std::string& cause);

// Sections "units", "caches", "bandwidth", "stalls", "counters" of stats.json, and
// "ray_buffer" (treelet mode) and "packets" (packet mode) when those blocks ran.
nlohmann::json timing_report(const ReportInputs& in);

}  // namespace rtsim

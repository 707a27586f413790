// The timing part of stats.json: the blocks' report sections (derived figures computed at dump
// time, so counting stays cheap) and every raw counter; the stall causes as people read them.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "models/stats.h"
#include "models/timing.h"
#include "sim/chip.h"

namespace rtsim {

// A cause as people read it: "L1", "DRAM", "box unit".
std::string stall_cause_label(const std::string& cause);

// total_cycles, simulated_seconds and the sections "units", "caches", "bandwidth", "stalls",
// "counters" of stats.json, and "ray_buffer" (treelet mode) and "packets" (packet mode) when
// those blocks ran. Each block reports its own part (Chip::report).
nlohmann::json timing_report(const Chip& chip, const ReportContext& ctx);

}  // namespace rtsim

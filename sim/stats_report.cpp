#include "sim/stats_report.h"

#include <fmt/format.h>
#include <algorithm>
#include <cctype>
#include <vector>

#include "models/core.h"

namespace rtsim {

using nlohmann::json;

std::string stall_cause_label(const std::string& cause) {
    if (cause == "l1" || cause == "l2" || cause == "dram") {
        std::string upper = cause;
        for (char& ch : upper) ch = char(std::toupper(static_cast<unsigned char>(ch)));
        return upper;
    }
    std::string label = cause;
    std::replace(label.begin(), label.end(), '_', ' ');
    return label;
}

json timing_report(const Chip& chip, const ReportContext& ctx) {
    json out = chip.report(ctx);
    out["total_cycles"] = ctx.total_cycles;
    out["simulated_seconds"] = ctx.seconds();
    json counters = json::object();
    for (const auto& e : chip.stats.entries()) counters[e.name] = *e.value;
    out["counters"] = counters;
    return out;
}

}  // namespace rtsim

#include "sim/fidelity_check.h"

#include "models/traversal_mode.h"

#include <fmt/format.h>

#include <algorithm>
#include <string>

namespace rtsim {

using nlohmann::json;

namespace {

// The 95th percentile of the fast engine's |error| (cycles or DRAM bytes, the larger) against
// the accurate engine, per regime, on the tuning set named in fidelity_check.h.
constexpr double kNoRegimeErrorPct = 1.0;
constexpr double kTreeletLoadsErrorPct = 18.0;
constexpr double kL1BoundErrorPct = 14.0;
constexpr double kCrossbarBoundErrorPct = 16.0;
constexpr double kCommandDramWritesErrorPct = 11.0;
constexpr double kMemoryPathOrderErrorPct = 14.0;
constexpr double kMemoryPathOrderShare = 0.01;
constexpr double kL1BoundStallShare = 0.40;
constexpr double kCrossbarBoundBusyShare = 0.30;

double number_at(const json& j, const json::json_pointer& p) {
    return j.contains(p) && j.at(p).is_number() ? j.at(p).get<double>() : 0.0;
}

}  // namespace

json fidelity_check(const Params& params, const json& out) {
    if (params.sim.fidelity != "fast")
        return {{"engine", params.sim.fidelity}, {"reference", true}};
    json regimes = json::array();
    double expected = kNoRegimeErrorPct;
    auto add = [&](const char* name, const std::string& measure, double threshold,
                   double error_pct) {
        regimes.push_back({{"name", name},
                           {"measure", measure},
                           {"threshold", threshold},
                           {"expected_error_pct", error_pct}});
        expected = std::max(expected, error_pct);
    };
    if (TraversalModeRegistry::at(params.traversal.mode).needs_treelets &&
        params.core.treelet_prefetch)
        add("treelet_loads", "traversal.treelet_prefetch", 1, kTreeletLoadsErrorPct);
    const double l1_share = number_at(out, json::json_pointer("/stalls/total/share/l1"));
    if (l1_share > kL1BoundStallShare)
        add("l1_bound", fmt::format("L1 stalls {:.0f}% of slot cycles", 100 * l1_share),
            kL1BoundStallShare, kL1BoundErrorPct);
    const double cycles = number_at(out, json::json_pointer("/total_cycles"));
    const double busy = number_at(out, json::json_pointer("/counters/crossbar.busy_cycles"));
    const double busy_share = cycles > 0 ? busy / cycles : 0.0;
    if (busy_share > kCrossbarBoundBusyShare)
        add("crossbar_bound", fmt::format("crossbar busy {:.0f}% of cycles", 100 * busy_share),
            kCrossbarBoundBusyShare, kCrossbarBoundErrorPct);
    // Command-level DRAM with the cores' writes in the L2: 3 of the 7 unflagged runs over 1% on
    // the tuning seed (the fast engine 1.8-7.7% short), 3 of the 8 such runs outside the
    // regimes above.
    const double writes = number_at(out, json::json_pointer("/counters/l2.write_requests"));
    if (params.dram_model == "command" && writes > 0)
        add("command_dram_writes",
            fmt::format("{:.0f} write requests at the L2, command-level DRAM", writes), 1,
            kCommandDramWritesErrorPct);
    // Blocks in the memory path whose state follows the order requests come in (a stream
    // buffer's read-aheads, a cache's replacement) and that met over 1% of their requests out of
    // time order. On the tuning seed 388002 the one such run (a stream buffer of 4 lines reading
    // 4 ahead below the L2, 2.9% of its reads out of order) was 14% off; every other run with a
    // block there met at most 0.2% out of order.
    double path_requests = 0, path_out_of_order = 0;
    if (out.contains("memory_path"))
        for (const auto& [name, block] : out["memory_path"].items()) {
            path_requests += block.value("requests", 0.0);
            path_out_of_order += block.value("out_of_order_requests", 0.0);
        }
    const double path_share = path_requests > 0 ? path_out_of_order / path_requests : 0.0;
    if (path_share > kMemoryPathOrderShare)
        add("memory_path_order",
            fmt::format("{:.1f}% of the memory-path blocks' requests out of time order",
                        100 * path_share),
            kMemoryPathOrderShare, kMemoryPathOrderErrorPct);
    const bool flagged = !regimes.empty();
    json check = {{"engine", "fast"},
                  {"regimes", regimes},
                  {"expected_error_pct", expected},
                  {"flagged", flagged}};
    if (flagged) {
        std::string names;
        for (const json& r : regimes)
            names += (names.empty() ? "" : ", ") + r["name"].get<std::string>() + " (" +
                     r["measure"].get<std::string>() + ")";
        check["note"] = fmt::format(
            "{}: runs like this were up to {:.0f}% off the time-ordered engine (95th percentile, "
            "bench/results/fidelity_random.md); rerun with --set sim.fidelity=accurate to check",
            names, expected);
    }
    return check;
}

}  // namespace rtsim

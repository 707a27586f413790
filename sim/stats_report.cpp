#include "sim/stats_report.h"

#include <fmt/format.h>
#include <algorithm>
#include <cctype>
#include <tuple>
#include <vector>

#include "models/core.h"

namespace rtsim {

using nlohmann::json;

std::vector<std::string> stall_causes() {
    std::vector<std::string> causes;
    for (int k = 0; k < Core::kStallKinds; ++k) causes.push_back(Core::stall_name(k));
    causes.push_back("no_work");
    return causes;
}

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

json timing_report(const ReportInputs& in) {
    const StatsRegistry& s = *in.stats;
    const double cycles = double(in.total_cycles);
    const double seconds = cycles / (in.clock_ghz * 1e9);
    auto gbps = [&](uint64_t bytes) { return seconds > 0 ? double(bytes) / seconds / 1e9 : 0.0; };
    auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };

    json out;
    out["total_cycles"] = in.total_cycles;
    out["simulated_seconds"] = seconds;

    json units = json::object();
    for (auto [kind, pipes, count] :
         {std::tuple<const char*, int, int>{"box_unit", in.box_pipelines_per_core,
                                            in.box_units ? in.box_units : in.cores},
          {"triangle_unit", in.triangle_pipelines_per_core,
           in.triangle_units ? in.triangle_units : in.cores}}) {
        for (int i = 0; i < count; ++i) {
            const std::string b = fmt::format("{}[{}]", kind, i);
            const uint64_t busy = s.get(b + ".busy_cycles");
            units[b] = {{"ops", s.get(b + ".ops")},
                        {"busy_cycles", busy},
                        {"queue_cycles", s.get(b + ".queue_cycles")},
                        {"utilization", ratio(double(busy), cycles * pipes)}};
        }
        const std::string prefix = std::string(kind) + "[";
        const uint64_t busy = s.sum(prefix, "busy_cycles");
        units[std::string(kind) + "_total"] = {
            {"ops", s.sum(prefix, "ops")},
            {"busy_cycles", busy},
            {"utilization", ratio(double(busy), cycles * pipes * count)}};
    }
    out["units"] = units;

    json caches = json::object();
    auto cache_entry = [&](const std::string& prefix, uint64_t acc, uint64_t hits, uint64_t misses,
                           uint64_t merged) {
        caches[prefix] = {{"accesses", acc},
                          {"hits", hits},
                          {"misses", misses},
                          {"merged_misses", merged},
                          {"hit_rate", ratio(double(hits), double(acc))}};
    };
    for (int i = 0; i < in.cores; ++i) {
        const std::string b = fmt::format("l1[{}]", i);
        cache_entry(b, s.get(b + ".accesses"), s.get(b + ".hits"), s.get(b + ".misses"),
                    s.get(b + ".merged_misses"));
    }
    // All L1s together: the unified ones, or node and triangle caches of a split L1.
    auto l1_sum = [&](const std::string& c) { return s.sum("l1[", c) + s.sum("l1_tri[", c); };
    for (int i = 0; i < in.cores; ++i) {
        const std::string b = fmt::format("l1_tri[{}]", i);
        if (s.has(b + ".accesses"))
            cache_entry(b, s.get(b + ".accesses"), s.get(b + ".hits"), s.get(b + ".misses"),
                        s.get(b + ".merged_misses"));
    }
    cache_entry("l1_total", l1_sum("accesses"), l1_sum("hits"), l1_sum("misses"),
                l1_sum("merged_misses"));
    if (s.has("treelet_cache[0].accesses")) {
        for (int i = 0; i < in.cores; ++i) {
            const std::string b = fmt::format("treelet_cache[{}]", i);
            cache_entry(b, s.get(b + ".accesses"), s.get(b + ".hits"), s.get(b + ".misses"),
                        s.get(b + ".merged_misses"));
        }
        auto tc = [&](const std::string& c) { return s.sum("treelet_cache[", c); };
        cache_entry("treelet_cache_total", tc("accesses"), tc("hits"), tc("misses"),
                    tc("merged_misses"));
    }
    cache_entry("l2", s.get("l2.accesses"), s.get("l2.hits"), s.get("l2.misses"),
                s.get("l2.merged_misses"));
    out["caches"] = caches;

    // Bytes crossing each boundary: core<-L1 (requested), L1<-L2 (L1 fills), L2<-DRAM (L2 fills).
    const uint64_t l1_bytes = l1_sum("bytes_requested");
    const uint64_t l2_bytes = l1_sum("fill_bytes");
    const uint64_t dram_bytes = s.get("dram.bytes");
    out["bandwidth"] = {
        {"l1", {{"bytes", l1_bytes}, {"gbps", gbps(l1_bytes)}}},
        {"l2", {{"bytes", l2_bytes}, {"gbps", gbps(l2_bytes)}}},
        {"dram",
         {{"bytes", dram_bytes},
          {"gbps", gbps(dram_bytes)},
          {"busy_cycles", s.get("dram.busy_cycles")},
          {"row_hits", s.get("dram.row_hits")},
          {"row_empty", s.get("dram.row_empty")},
          {"row_conflicts", s.get("dram.row_conflicts")},
          {"row_hit_rate", ratio(double(s.get("dram.row_hits")), double(s.get("dram.reads")))},
          {"utilization", ratio(double(s.get("dram.busy_cycles")), cycles * in.dram_channels)}}}};

    // Stall attribution: every ray-slot cycle charged to one cause; cycles without a ray are
    // "no_work". Per core and in total, in slot-cycles and as shares.
    std::vector<const char*> causes;  // the charged ones; no_work is what they leave
    for (int k = 0; k < Core::kStallKinds; ++k) causes.push_back(Core::stall_name(k));
    json stalls = json::object();
    auto stall_entry = [&](const std::string& prefix, bool one_core) {
        json e = json::object();
        uint64_t charged = 0;
        for (const char* c : causes) {
            const std::string counter = fmt::format("stall_{}_cycles", c);
            const uint64_t v = one_core ? s.get(prefix + "." + counter) : s.sum(prefix, counter);
            e[c] = v;
            charged += v;
        }
        const uint64_t slot_cycles =
            uint64_t(in.ray_slots_per_core) * in.total_cycles * uint64_t(one_core ? 1 : in.cores);
        e["no_work"] = slot_cycles >= charged ? slot_cycles - charged : 0;
        e["slot_cycles"] = slot_cycles;
        json share = json::object();
        for (const char* c : causes) share[c] = ratio(e[c].get<double>(), double(slot_cycles));
        share["no_work"] = ratio(e["no_work"].get<double>(), double(slot_cycles));
        e["share"] = share;
        return e;
    };
    for (int i = 0; i < in.cores; ++i)
        stalls[fmt::format("core[{}]", i)] = stall_entry(fmt::format("core[{}]", i), true);
    stalls["total"] = stall_entry("core[", false);
    out["stalls"] = stalls;

    if (s.has("crossbar.bytes"))
        out["bandwidth"]["crossbar"] = {
            {"bytes", s.get("crossbar.bytes")},
            {"gbps", gbps(s.get("crossbar.bytes"))},
            {"queue_cycles", s.get("crossbar.queue_cycles")},
            {"utilization", ratio(double(s.get("crossbar.busy_cycles")), cycles)}};

    if (s.has("ray_buffer.reads")) {
        const uint64_t accesses = s.get("ray_buffer.reads") + s.get("ray_buffer.writes");
        const uint64_t batches = s.get("ray_buffer.batches");
        out["ray_buffer"] = {
            {"capacity_rays", in.ray_capacity},
            {"size_bytes", in.ray_capacity * in.ray_bytes},
            {"reads", s.get("ray_buffer.reads")},
            {"writes", s.get("ray_buffer.writes")},
            {"bytes", accesses * in.ray_bytes},
            {"gbps", gbps(accesses * in.ray_bytes)},
            {"peak_rays", s.get("ray_buffer.peak_rays")},
            {"admission_blocked", s.get("ray_buffer.admission_blocked")},
            {"port_wait_cycles", s.get("ray_buffer.port_wait_cycles")},
            {"batches", batches},
            {"rays_per_batch", ratio(double(s.get("ray_buffer.batch_rays")), double(batches))},
            {"crossings", s.get("ray_buffer.crossings")},
            {"crossings_per_ray", ratio(double(s.get("ray_buffer.crossings")), double(in.rays))},
            {"treelet_loads", s.sum("core[", "treelet_loads")},
            {"treelet_load_bytes", s.sum("core[", "treelet_load_bytes")}};
    }
    if (s.has("core[0].lane_slots")) {
        const uint64_t active = s.sum("core[", "active_lanes"),
                       slots = s.sum("core[", "lane_slots");
        out["packets"] = {{"active_lanes", active},
                          {"lane_slots", slots},
                          {"lane_utilization", ratio(double(active), double(slots))}};
    }

    json counters = json::object();
    for (const auto& e : s.entries()) counters[e.name] = *e.value;
    out["counters"] = counters;
    return out;
}

}  // namespace rtsim

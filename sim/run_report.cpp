#include "sim/run_report.h"

#include "sim/fidelity_check.h"

#include <sys/resource.h>

#include <fmt/format.h>

#include <string>
#include <utility>
#include <vector>

#include "models/calendar.h"

namespace rtsim {

using nlohmann::json;

double peak_rss_mib() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return double(ru.ru_maxrss) / 1024.0;  // Linux reports KiB
}

namespace {

// Per-window figures for plots: bandwidth in GB/s at each level and unit utilisation.
json time_series_report(const Chip& chip, const ReportContext& ctx) {
    const auto& S = chip.series;
    const uint64_t window = S.rays->window_cycles();
    const size_t n = size_t((ctx.total_cycles + window - 1) / window);
    const double window_seconds = double(window) / (ctx.clock_ghz * 1e9);
    auto values = [&](const TimeSeries& t, double scale) {
        json a = json::array();
        for (size_t w = 0; w < n; ++w)
            a.push_back(w < t.buckets().size() ? double(t.buckets()[w]) * scale : 0.0);
        return a;
    };
    const double gbps = 1.0 / window_seconds / 1e9;
    json out = {{"window_cycles", window},
                {"windows", n},
                {"dram_gbps", values(*S.dram_bytes, gbps)},
                {"l2_to_l1_gbps", values(*S.l1_fill_bytes, gbps)},
                {"dram_to_l2_gbps", values(*S.l2_fill_bytes, gbps)},
                {"rays", values(*S.rays, 1.0)}};
    for (int k = 0; k < kStepKinds; ++k) {
        // Pipelines of all units of the kind (each unit has the same count).
        const auto& units = chip.units[size_t(k)];
        const double pipelines = double(units.size()) * units[0]->params().count;
        out[std::string(step_kind_info(k).unit) + "_utilization"] =
            values(*S.unit_busy[size_t(k)], 1.0 / (double(window) * pipelines));
    }
    return out;
}

// stats.json's "rays": per kind the rays and hits, counting the kinds the workload asked for
// (or, for rays from a file, those seen).
json rays_section(const json& workload, const CountingSource& source) {
    std::array<bool, kRayKindCount> listed{};
    const std::string kinds_text = workload.value("rays", std::string());
    if (!kinds_text.empty()) listed = parse_ray_kinds(kinds_text, "workload.rays");
    uint64_t total_rays = 0;
    json rays = json::object(), hits = json::object();
    for (int k = 0; k < kRayKindCount; ++k) {
        if (!listed[k] && source.rays_by_kind[k] == 0) continue;
        rays[ray_kind_name(RayKind(k))] = source.rays_by_kind[k];
        hits[ray_kind_name(RayKind(k))] = source.hits_by_kind[k];
        total_rays += source.rays_by_kind[k];
    }
    return {
        {"total", total_rays}, {"by_kind", rays}, {"hits_by_kind", hits}, {"steps", source.steps}};
}

}  // namespace

ReportContext report_context(const Params& P, const Chip& chip, uint64_t rays) {
    ReportContext ctx;
    ctx.total_cycles = chip.total_cycles();
    ctx.clock_ghz = P.clock_ghz;
    ctx.rays = rays;
    return ctx;
}

json run_report(const Config& cfg, const Chip& chip, const json& meta, const CountingSource& source,
                const HostTimes& host) {
    const json rays = rays_section(meta["workload"], source);
    // Every kind with rays is listed, so this is every ray simulated.
    const uint64_t total_rays = rays["total"].get<uint64_t>();
    const ReportContext ctx = report_context(cfg.typed, chip, total_rays);
    // The blocks' sections, total_cycles and simulated_seconds; the rest is added around them.
    json out = timing_report(chip, ctx);
    const double sim_s = ctx.seconds();
    // Host time split: the cores' scheduler running (models, and waiting for rays:
    // functional_s), the rest is the SystemC kernel.
    const double cores_busy = chip.driver->host_busy_seconds();

    out["rtsim_version"] = RTSIM_VERSION;
    out["config"] = cfg.values;
    out["config_hash"] = cfg.hash();
    out["config_files"] = cfg.files;
    out["config_overrides"] = cfg.overrides;
    for (const char* k : {"scene", "bvh", "workload"}) out[k] = meta[k];
    if (out["bvh"].contains("layout"))  // a trace's treelet tables stay in the trace
        for (const char* k : {"treelet_node_start", "treelet_tri_start"})
            out["bvh"]["layout"].erase(k);
    out["rays"] = rays;
    out["clock_ghz"] = ctx.clock_ghz;
    out["rays_per_second"] = sim_s > 0 ? double(total_rays) / sim_s : 0.0;
    out["traversal_mode"] = cfg.typed.traversal.mode;
    if (chip.series.rays) out["time_series"] = time_series_report(chip, ctx);
    out["fidelity_check"] = fidelity_check(cfg.typed, out);
    // Host timings live apart: everything outside "host" is identical for identical inputs.
    const double sim_seconds = host.simulation_s;
    out["host"] = {{"run_time_s", host.run_time_s},
                   {"run_cpu_s", host.run_cpu_s},
                   {"prepare_s", host.prepare_s},
                   {"simulation_s", sim_seconds},
                   {"functional_s", source.functional_seconds},
                   {"simulated_rays_per_host_second",
                    sim_seconds > 0 ? double(total_rays) / sim_seconds : 0.0},
                   {"models_s", std::max(0.0, cores_busy - source.functional_seconds)},
                   {"kernel_s", std::max(0.0, sim_seconds - cores_busy)},
                   {"peak_rss_mib", peak_rss_mib()}};
    if (host.bvh_build_s >= 0) out["host"]["bvh_build_s"] = host.bvh_build_s;
    if (!host.trace.empty()) out["host"]["trace"] = host.trace;
    if (!host.bvh_cache.empty()) out["host"]["bvh_cache"] = host.bvh_cache;
    if (host.scene_load_s >= 0) out["host"]["scene_load_s"] = host.scene_load_s;
    if (!host.mesh_cache.empty()) out["host"]["mesh_cache"] = host.mesh_cache;
    return out;
}

void print_run_summary(const json& out, const std::string& stats_path) {
    const json& bw = out["bandwidth"];
    const json& un = out["units"];
    const json& ca = out["caches"];
    std::string kinds;
    for (auto& [k, v] : out["rays"]["by_kind"].items())
        kinds += fmt::format("{}{} {}", kinds.empty() ? "" : ", ", k, v.get<uint64_t>());
    const json& sc = out["scene"];
    const json& bv = out["bvh"];
    const std::string trace = out["host"].value("trace", std::string());
    fmt::print("rtsim run  config {} ({})  scene {} ({} triangles){}\n",
               out["config"]["name"].get<std::string>(), out["config_hash"].get<std::string>(),
               sc.value("name", std::string("?")), sc.value("triangles", 0),
               trace.empty() ? std::string() : "  replayed from " + trace);
    fmt::print(
        "  bvh      {} BVH{} {}: {} nodes, {} leaves, depth {}, SAH cost {:.2f}, {:.2f} MiB\n",
        bv.value("builder", std::string("?")), bv.value("width", 0),
        bv.value("node_format", std::string("?")), bv.value("nodes", 0), bv.value("leaves", 0),
        bv.value("max_depth", 0), bv.value("sah_cost", 0.0), bv.value("bytes", 0.0) / 1048576.0);
    if (out["rays"].contains("traced"))  // the skip design: kinds and steps of the traced rays
        fmt::print("  rays     {} (traced {}: {}), {} steps\n",
                   out["rays"]["total"].get<uint64_t>(), out["rays"]["traced"].get<uint64_t>(),
                   kinds, out["rays"]["steps"].get<uint64_t>());
    else
        fmt::print("  rays     {} ({}), {} steps\n", out["rays"]["total"].get<uint64_t>(), kinds,
                   out["rays"]["steps"].get<uint64_t>());
    fmt::print("  cycles   {} = {:.3f} ms at {} GHz -> {:.2f} Mrays/s\n",
               out["total_cycles"].get<uint64_t>(), out["simulated_seconds"].get<double>() * 1e3,
               out["clock_ghz"].get<double>(), out["rays_per_second"].get<double>() / 1e6);
    if (out.contains("fidelity_check") && out["fidelity_check"].value("flagged", false))
        fmt::print("  caution  fast engine: {}\n",
                   out["fidelity_check"].value("note", std::string()));
    if (out.contains("sampling") && out["sampling"].value("in_full", false)) {
        const json& t = out["sampling"]["target"];
        fmt::print("  sampled  no: {} (pilot at 1 unit in {}: {:.2f} s)\n",
                   t.value("note", std::string()), t.value("pilot_period_units", 0),
                   t.value("pilot_host_s", 0.0));
    } else if (out.contains("sampling")) {
        // The figures above are the detailed part's; the frame's come from the sample.
        const json& sm = out["sampling"];
        fmt::print("  sampled  {:.1f}% of rays in detail ({} of {} units measured)",
                   100 * sm.value("detailed_share", 0.0), sm.value("units_measured", 0),
                   sm.value("units", 0));
        // "+- 2.4%", or "(no interval)" where the data support none.
        auto interval = [](const json& e) {
            return e["half_width_pct"].is_number()
                       ? fmt::format("+- {:.1f}%", e["half_width_pct"].get<double>())
                       : std::string("(no interval)");
        };
        std::vector<std::pair<std::string, std::string>> caveats;
        if (sm.contains("total_cycles")) {
            const json& c = sm["total_cycles"];
            fmt::print("; frame cycles {:.0f} {} (95%)", c["value"].get<double>(), interval(c));
            if (c.contains("caveat")) caveats.emplace_back("cycles", c["caveat"]);
        } else {
            // Nothing may pass for the frame's figure: the lines above are the measured units'.
            caveats.emplace_back("frame",
                                 "no estimate: the cycles, rate and traffic above are the "
                                 "measured units' only; " +
                                     sm.value("note", std::string("too few measured units")));
        }
        // The traffic line below is the detailed part's; the frame's DRAM bytes are estimated.
        if (sm.contains("counters") && sm["counters"].contains("dram.bytes")) {
            const json& d = sm["counters"]["dram.bytes"];
            fmt::print(", DRAM {:.2f} MB {}", d["value"].get<double>() / 1e6, interval(d));
            if (d.contains("caveat")) caveats.emplace_back("DRAM bytes", d["caveat"]);
        }
        if (sm.contains("energy")) {
            const json& e = sm["energy"]["per_ray_nj"];
            fmt::print(", energy {:.3g} nJ/ray {}", e["value"].get<double>(), interval(e));
        }
        fmt::print("\n");
        for (const auto& [what, why] : caveats) fmt::print("  caution  {}: {}\n", what, why);
        const bool skip = sm.value("fast_forward", std::string()) == "skip";
        if (skip)
            fmt::print(
                "  traced   {:.1f}% of rays (the rest skipped); frame profile {} ({:.2f} s)\n",
                100 * sm.value("traced_share", 0.0), sm["profile"].value("cache", std::string("?")),
                sm["profile"].value("seconds", 0.0));
        if (sm.contains("reference")) {
            const json& r = sm["reference"];
            // The warm-up is named: a paired run takes its own (sim.sample_paired_warmup_*).
            const uint64_t warmup = sm.value("warmup_tiles", uint64_t(0)),
                           warmup_rays = sm.value("warmup_tile_rays", uint64_t(0));
            fmt::print(
                "  paired   with reference design '{}' ({}), its sample {}; warm-up {} tile{}{} "
                "(sim.sample_paired_warmup_*); units of {} tiles (sim.sample_paired_unit_tiles)\n",
                r.value("config_name", std::string()), r.value("dir", std::string()),
                r.value("matched_sample", std::string()) == "cached"
                    ? "kept from an earlier run"
                    : fmt::format("run now ({:.2f} s)", r.value("matched_host_s", 0.0)),
                warmup, warmup == 1 ? "" : "s",
                warmup_rays ? fmt::format(" or more, to hold {} rays", warmup_rays) : "",
                sm.value("unit_tiles", uint64_t(0)));
        }
        if (sm.value("units_measured", 0) < 30)
            fmt::print(
                "  note     intervals from fewer than 30 measured units under-cover (50-90% for a "
                "nominal 95%, docs/sampling.md): lower sim.sample_period_units or "
                "sim.{}\n",
                !skip                      ? "sample_unit_rays"
                : sm.contains("reference") ? "sample_paired_unit_tiles"
                                           : "sample_unit_tiles");
        if (sm.contains("target")) {
            const json& t = sm["target"];
            fmt::print(
                "  target   {}% ({}): a pilot at 1 unit in {} gave {:.1f}%, so 1 unit in {} was "
                "measured\n",
                t.value("target_error_pct", 0.0), t.value("met", false) ? "met" : "NOT met",
                t.value("pilot_period_units", 0), t.value("pilot_half_width_pct", 0.0),
                t.value("period_units", 0));
        }
    }
    fmt::print("  units    box {:.1f}% busy, triangle {:.1f}% busy\n",
               100 * un["box_unit_total"]["utilization"].get<double>(),
               100 * un["triangle_unit_total"]["utilization"].get<double>());
    const json& share = out["stalls"]["total"]["share"];
    std::string slots;
    for (const std::string& cause : stall_causes()) {
        if (cause == "ray_buffer" && !out.contains("ray_buffer")) continue;
        slots += fmt::format("{}{} {:.1f}%", slots.empty() ? "" : ", ", stall_cause_label(cause),
                             100 * share.value(cause, 0.0));
    }
    fmt::print("  slots    {}\n", slots);
    if (out.contains("ray_buffer")) {
        const json& rb = out["ray_buffer"];
        fmt::print(
            "  treelets {} batches of {:.1f} rays, {:.2f} crossings per ray, {:.1f} MB of "
            "treelets loaded, ray buffer {:.1f} MB moved, peak {} rays\n",
            rb["batches"].get<uint64_t>(), rb["rays_per_batch"].get<double>(),
            rb["crossings_per_ray"].get<double>(), rb["treelet_load_bytes"].get<double>() / 1e6,
            rb["bytes"].get<double>() / 1e6, rb["peak_rays"].get<uint64_t>());
    }
    if (out.contains("packets"))
        fmt::print("  packets  lane utilisation {:.1f}%\n",
                   100 * out["packets"]["lane_utilization"].get<double>());
    fmt::print("  caches   L1 hit rate {:.1f}%, L2 hit rate {:.1f}%\n",
               100 * ca["l1_total"]["hit_rate"].get<double>(),
               100 * ca["l2"]["hit_rate"].get<double>());
    fmt::print(
        "  traffic  L1 {:.1f} MB ({:.1f} GB/s), L2 {:.1f} MB ({:.1f} GB/s), DRAM {:.1f} MB "
        "({:.1f} GB/s)\n",
        bw["l1"]["bytes"].get<double>() / 1e6, bw["l1"]["gbps"].get<double>(),
        bw["l2"]["bytes"].get<double>() / 1e6, bw["l2"]["gbps"].get<double>(),
        bw["dram"]["bytes"].get<double>() / 1e6, bw["dram"]["gbps"].get<double>());
    fmt::print(
        "  host     {:.2f} s total, {:.2f} s simulating -> {:.3f} M simulated rays per host "
        "second\n",
        out["host"]["run_time_s"].get<double>(), out["host"]["simulation_s"].get<double>(),
        out["host"]["simulated_rays_per_host_second"].get<double>() / 1e6);
    if (out.contains("bound"))
        fmt::print("  bound    ideal memory and units: {:.2f} Mrays/s; achieved {:.1f}% of it\n",
                   out["bound"]["rays_per_second"].get<double>() / 1e6,
                   100 * out["bound"]["achieved_over_bound"].get<double>());
    fmt::print("  stats    {}\n", stats_path);
}

}  // namespace rtsim

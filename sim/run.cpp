#include "sim/run.h"

#include <cmath>

#include <unistd.h>

#include <fmt/format.h>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <memory>
#include <systemc>
#include <thread>

#include "models/calendar.h"
#include "models/dram_device.h"
#include "models/traversal_mode.h"
#include "sim/bound.h"
#include "sim/chip.h"
#include "sim/energy.h"
#include "sim/errors.h"
#include "sim/interrupt.h"
#include "sim/mem_trace.h"
#include "sim/paired_run.h"
#include "sim/run_report.h"
#include "sim/sampling/reference.h"
#include "sim/sampling/sampler.h"
#include "sim/work_sources.h"
#include "workloads/bvh_cache.h"
#include "workloads/error.h"
#include "workloads/mesh_cache.h"
#include "workloads/output_file.h"
#include "workloads/scene_file.h"
#include "workloads/trace_file.h"

namespace rtsim {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
}

std::string fresh_out_dir() {
    const std::time_t now = std::time(nullptr);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", std::localtime(&now));
    for (int i = 0;; ++i) {
        std::string d = fmt::format("out/run-{}{}", stamp, i ? fmt::format("-{}", i) : "");
        if (!fs::exists(d)) return d;
    }
}

// The output folder, made before the long work so that a bad --out fails fast and nothing is
// half-written.
std::string make_out_dir(const RunOptions& opt) {
    const std::string out_dir = opt.out_dir.empty() ? fresh_out_dir() : opt.out_dir;
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec || !fs::is_directory(out_dir))
        throw InputError(
            fmt::format("--out {}: cannot create output folder: {}", out_dir, ec.message()));
    return out_dir;
}

// The rays a run simulates and what stats.json says of them: generated on the fly (scene, BVH,
// ray generator, functional tracer) or replayed from a trace (which carries its BVH layout).
struct Workload {
    json meta;  // scene, bvh and workload sections of stats.json
    std::unique_ptr<Scene> scene;
    MeshCacheStatus mesh_cache;
    BvhCacheStatus bvh_cache;
    std::unique_ptr<Bvh> bvh;
    std::unique_ptr<InstancedScene> instanced;  // a scene file: these instead of scene and bvh
    std::unique_ptr<TwoLevelBvh> two;
    double scene_file_s = 0, two_level_build_s = 0;
    size_t blas_cache_hits = 0;  // a scene of instances: BLASes read from the BVH cache
    std::unique_ptr<RayGenerator> gen;
    std::unique_ptr<TraceReader> reader;
    std::unique_ptr<CountingSource> source;
    std::unique_ptr<FrameProfile> profile;       // a sampled run's skip design
    std::shared_ptr<const SampleDesign> design;  // a sampled run's skip design: its sample
    std::unique_ptr<Reference> reference;        // --reference
    std::string cache_dir;                       // meshes, BVHs, profiles (empty: none)
    const BvhLayout& layout() const {
        return bvh ? bvh->layout : two ? two->layout : reader->layout();
    }
};

// A sampled run's plan from the config (the seed defaults to the workload's).
SamplingParams sampling_params(const RunOptions& opt, const Config& cfg) {
    const SimParams& s = cfg.typed.sim;
    SamplingParams sp;
    sp.unit_rays = s.sample_unit_rays;
    sp.period_units = s.sample_period_units;
    sp.warmup_rays = s.sample_warmup_rays;
    sp.seed = s.sample_seed ? s.sample_seed : opt.workload.gen.seed;
    sp.first_unit = s.sample_first_unit;
    SampleDesignRegistry::at(s.sample_design).configure(sp);
    sp.skip = FastForwardRegistry::at(s.sample_fast_forward).needs_profile;
    sp.warm_tiles = s.sample_warm_tiles;
    // A paired run's regression on its reference's same units takes up most of what a short
    // warm-up leaves (sim.sample_paired_warmup_tiles), and its units can be larger
    // (sim.sample_paired_unit_tiles): its reference's units are merged to them.
    const bool paired = !opt.reference_dir.empty();
    sp.unit_tiles = paired ? s.sample_paired_unit_tiles : s.sample_unit_tiles;
    sp.warmup_tiles = paired ? s.sample_paired_warmup_tiles : s.sample_warmup_tiles;
    sp.warmup_tile_rays = paired ? s.sample_paired_warmup_tile_rays : s.sample_warmup_tile_rays;
    // At least so many fills of the chip's ray slots (sim.sample_warmup_slot_fills), so that a
    // large chip's slots are full when a unit starts.
    const uint64_t fills = paired ? s.sample_paired_warmup_slot_fills : s.sample_warmup_slot_fills;
    sp.warmup_tile_rays =
        std::max<uint64_t>(sp.warmup_tile_rays, fills * uint64_t(cfg.typed.core_count) *
                                                    uint64_t(cfg.typed.core.ray_slots));
    return sp;
}

// A skip-design sampled run's frame profile (through the cache), the units' work, the order
// strata are cut from and the reference, then the design; returns the tiles it wants traced.
// `trace` traces the frame's rays over `layout`; `key` names what the rays' steps depend on.
std::function<bool(int)> prepare_skip_design(const RunOptions& opt, const Config& cfg,
                                             SamplingParams& sp, Workload& w,
                                             const BvhLayout& layout, const TraceRays& trace,
                                             const std::string& key) {
    // The profile traces the whole frame once, on every host core (nothing else runs yet).
    w.gen->set_record_steps(true);
    // Profiled per tile and merged to the run's units: one cache entry serves every unit size.
    w.profile = std::make_unique<FrameProfile>(profile_frame_cached(
        *w.gen, trace, 1, layout.fetch_begin(), layout.fetch_end(),
        uint32_t(cfg.typed.l2.line_bytes), int(std::max(1u, std::thread::hardware_concurrency())),
        key, w.cache_dir));
    sp.tiles = uint64_t(w.gen->tile_count());
    // A unit spans at least sim.sample_unit_slot_fills fills of the chip's ray slots, counted in
    // the rays of the frame's tiles that have any. Not in a run whose units must fit another
    // run's (a paired run, --sample-order) nor in an every-unit run, which is exact at any unit
    // size and serves as such a run's reference in the units it is given.
    if (opt.reference_dir.empty() && opt.sample_order_dir.empty() && sp.period_units > 1)
        sp.unit_tiles = std::max(sp.unit_tiles,
                                 unit_tiles_for_slot_fills(w.profile->tile_rays,
                                                           cfg.typed.sim.sample_unit_slot_fills *
                                                               uint64_t(cfg.typed.core_count) *
                                                               uint64_t(cfg.typed.core.ray_slots)));
    // Per tile (the profile's units are tiles until merged) its work, and the work the warm-up
    // holds: its rays at the frame's mean work per ray (sim.sample_warmup_work). Over 8 tuning
    // frames (default, 16 x 16 and 64 x 32 chips) the design-weighted bias of the measured units'
    // cycles against the same units of an every-unit run summed to 7.2 points over the frames,
    // against 13.4 with a warm-up of rays alone (primary frames +1.1% to +3.9%: background units
    // shared the chip with the last window's rays) and 8.2 draining the windows whose warm-up held
    // under half that work; at 1.0-1.5x the rays in detail (docs/sampling.md).
    if (cfg.typed.sim.sample_warmup_work) {
        sp.tile_work.resize(w.profile->units.size());
        uint64_t frame_work = 0, frame_rays = 0;
        for (size_t t = 0; t < w.profile->units.size(); ++t) {
            sp.tile_work[t] = w.profile->units[t][kAuxWork];
            frame_work += w.profile->units[t][kAuxWork];
            frame_rays += w.profile->units[t][kAuxRays];
        }
        if (frame_rays > 0)
            sp.warmup_work =
                uint64_t(double(sp.warmup_tile_rays) * double(frame_work) / double(frame_rays));
    }
    merge_profile_units(*w.profile, sp.unit_tiles);
    // A --target-error pilot measures about opt.pilot_units of the units its design draws from
    // (those with work, for the work design), at no finer a period than configured: its spread
    // sizes the run, and on a frame of many units a pilot at the configured period cost as much
    // as the run it sized (1080p bunny, 8 spp, 2-bounce diffuse, 64 x 32 cores: 119 units, 2.7 s
    // of an 8.1 s full run).
    if (opt.pilot_units > 0) {
        uint64_t drawable = w.profile->units.size();
        if (sp.by_work)
            drawable = uint64_t(std::count_if(w.profile->units.begin(), w.profile->units.end(),
                                              [](const AuxFigures& a) { return a[kAuxWork] > 0; }));
        sp.period_units = std::max<uint64_t>(sp.period_units, drawable / opt.pilot_units);
    }
    sp.tile_rays.assign(w.profile->tile_rays.begin(), w.profile->tile_rays.end());
    if (sp.by_work) {
        sp.unit_work.resize(w.profile->units.size());
        sp.unit_ray_counts.resize(w.profile->units.size());
        for (size_t u = 0; u < w.profile->units.size(); ++u) {
            sp.unit_work[u] = w.profile->units[u][kAuxWork];
            sp.unit_ray_counts[u] = w.profile->units[u][kAuxRays];
        }
        sp.startup_rays = cfg.typed.sim.sample_startup_slot_fills * uint64_t(cfg.typed.core_count) *
                          uint64_t(cfg.typed.core.ray_slots);
    }
    // The order strata are cut from, before the design is made: another run's units by their
    // cycles, or (a paired run) the reference's, once it is known to be this frame's.
    if (!opt.sample_order_dir.empty()) {
        sp.unit_order = read_strata_order(opt.sample_order_dir, "--sample-order", sp.unit_tiles,
                                          w.profile->units, sp.period_units);
        sp.unit_order_of = opt.sample_order_dir;
    }
    if (!opt.reference_dir.empty())
        w.reference = std::make_unique<Reference>(load_reference(opt, cfg, w.meta, *w.profile, sp));
    // Made once: the ray source's helper thread and the sampler read it.
    w.design = std::make_shared<const SampleDesign>(sp);
    return [design = w.design](int tile) { return design->wants_tile(uint64_t(tile)); };
}

// A scene of instances (a scene file, workloads/scene_file.h, or a mesh file whose nodes share
// meshes: `loaded`, read in `loaded_s`): its meshes' BLASes and the TLAS over its instances,
// built as the config's bvh section says, traced on the fly (a sampled run's skip design
// profiles the frame over both levels). Packets, which trace one level, are refused before
// anything runs.
void prepare_two_level(const RunOptions& opt, const Config& cfg, bool progress,
                       SamplingParams* sampling, Workload& w,
                       std::unique_ptr<InstancedScene> loaded = nullptr, double loaded_s = 0) {
    const std::string& file = opt.workload.scene;
    const char* or_flatten = loaded ? kOrFlatten : "";
    if (TraversalModeRegistry::at(cfg.typed.traversal.mode).packets)
        throw InputError(
            fmt::format("traversal.mode {}: {} is a scene of instances; packets trace one level{}",
                        cfg.typed.traversal.mode, file, or_flatten));
    const auto t0 = std::chrono::steady_clock::now();
    w.instanced = loaded ? std::move(loaded)
                         : std::make_unique<InstancedScene>(load_scene_file(file, w.cache_dir));
    const auto t1 = std::chrono::steady_clock::now();
    w.two = std::make_unique<TwoLevelBvh>(
        build_two_level_from_config(cfg, *w.instanced, w.cache_dir, &w.blas_cache_hits));
    w.scene_file_s = std::chrono::duration<double>(t1 - t0).count() + loaded_s;
    w.two_level_build_s = seconds_since(t1);
    w.gen = std::make_unique<RayGenerator>(*w.instanced, *w.two, opt.workload.gen);
    w.meta = {{"scene", scene_summary(*w.instanced)},
              {"bvh", bvh_summary(*w.two)},
              {"workload", workload_summary(opt.workload.gen, w.gen->ao_length())}};
    std::function<bool(int)> want_tile;
    if (sampling && sampling->skip) {
        // Keyed by the scene's content (meshes, instances, masks) and the two levels as built,
        // laid out and traversed, and the generator's settings.
        const std::string key =
            fmt::format("v1 two={:016x} {} {}", w.instanced->content_hash(),
                        json(w.meta["bvh"]).dump(), json(w.meta["workload"]).dump());
        want_tile =
            prepare_skip_design(opt, cfg, *sampling, w, w.two->layout, tracer_of(*w.two), key);
    }
    w.source = std::make_unique<GeneratedWorkSource>(*w.two, *w.gen, progress, opt.tracer_threads,
                                                     std::move(want_tile));
}

// `sampling`: a sampled run's plan; in the skip design the frame's tile count is filled in, and
// the source generates only the tiles the design wants.
Workload prepare_workload(const RunOptions& opt, const Config& cfg, bool progress,
                          SamplingParams* sampling) {
    Workload w;
    if (!opt.trace_path.empty()) {
        w.reader = std::make_unique<TraceReader>(opt.trace_path);
        w.meta = open_trace_metadata(*w.reader, opt.trace_path);
        check_trace_matches_config(w.meta["bvh"], cfg, opt.trace_path);
        if (cfg.typed.core.short_stack_entries > 0 && w.reader->version() < 3)
            throw InputError(fmt::format(
                "{}: core.short_stack_entries needs each step's stack depth, which trace format "
                "version {} does not record (version 3 does); record the trace again with rtsim "
                "trace",
                opt.trace_path, w.reader->version()));
        w.source = std::make_unique<TraceWorkSource>(*w.reader, progress);
        return w;
    }
    const RayGenOptions& rg = opt.workload.gen;
    // Meshes, BVHs and frame profiles share one cache folder.
    const std::string cache_dir = w.cache_dir = resolve_bvh_cache_dir(opt.bvh_cache);
    if (is_scene_file(opt.workload.scene)) {
        prepare_two_level(opt, cfg, progress, sampling, w);
        return w;
    }
    auto shared_meshes = std::make_unique<InstancedScene>();
    w.scene = std::make_unique<Scene>(
        load_scene_cached(opt.workload.scene, cache_dir, &w.mesh_cache,
                          opt.workload.flatten ? nullptr : shared_meshes.get()));
    if (!shared_meshes->instances.empty()) {  // a glTF's shared meshes: kept as instances
        w.scene.reset();
        prepare_two_level(opt, cfg, progress, sampling, w, std::move(shared_meshes),
                          w.mesh_cache.seconds);
        return w;
    }
    w.bvh = std::make_unique<Bvh>(
        build_bvh_from_config(cfg, *w.scene, cache_dir, &w.bvh_cache, w.mesh_cache.scene_hash));
    w.gen = std::make_unique<RayGenerator>(*w.scene, *w.bvh, rg);
    // The BVH cache hashed the scene's geometry already (a few ms for a large mesh).
    const bool cached = w.bvh_cache.outcome != BvhCacheOutcome::Off;
    const uint64_t scene_hash = cached ? w.bvh_cache.scene_hash : w.scene->content_hash();
    w.meta = {{"scene", scene_summary(*w.scene, scene_hash)},
              {"bvh", bvh_summary(*w.bvh)},
              {"workload", workload_summary(rg, w.gen->ao_length())}};
    const bool packets = TraversalModeRegistry::at(cfg.typed.traversal.mode).packets;
    std::function<bool(int)> want_tile;
    if (sampling && sampling->skip) {
        // Keyed by what the rays' steps depend on: the scene's content and the BVH build (the
        // BVH cache's key), the tree as laid out and traversed, and the generator's settings.
        const BvhLayout sizes = layout_sizes_from_config(cfg);
        const std::string key = fmt::format(
            "v1 bvh={:016x} {} {}",
            cached ? w.bvh_cache.key : bvh_cache_key(scene_hash, *w.scene, cfg.typed.bvh, sizes),
            json(w.meta["bvh"]).dump(), json(w.meta["workload"]).dump());
        want_tile =
            prepare_skip_design(opt, cfg, *sampling, w, w.bvh->layout, tracer_of(*w.bvh), key);
    }
    w.source = std::make_unique<GeneratedWorkSource>(*w.bvh, *w.gen, progress,
                                                     packets ? cfg.typed.traversal.packet_size : 0,
                                                     opt.tracer_threads, std::move(want_tile));
    return w;
}

// --target-error P (Stein's two-stage procedure): a pilot, the same frame sampled in a child
// process (at the configured period, or the coarser one that measures about kPilotUnits units in
// the skip design), measures how wide the intervals of the frame's cycles and DRAM
// bytes are with n units; the run then measures the n (h / P)^2 units a half-width of P needs,
// by choosing its period (one unit in N / that many). The pilot covers the whole frame, so its
// spread is the frame's, start-up transients included.
constexpr double kMinTargetUnits = 30;
// A plan that measures this share of the units it could draw from or more cannot beat the full
// run (a sampled unit costs its warm-up and cache replay besides its rays): the frame runs in
// full instead, exact.
constexpr double kFullRunShare = 0.5;

// The units a skip-design pilot measures, about (sim/run.cpp, prepare_skip_design): enough
// residual degrees of freedom for its spread on the regression's auxiliaries.
constexpr uint64_t kPilotUnits = 40;

// A skip-design plan first runs a quick pilot of about this many units; where its spread already
// asks for this many times the share that sends a frame in full, the frame runs in full without
// the pilot of kPilotUnits. With 10 units on up to six auxiliaries the spread is known to within
// a factor of about 2.8 in the units it asks for (95%, chi-square on 4 degrees of freedom), and a
// frame sent in full is exact, so the margin only costs frames that sampling would have won by
// little. Where the quick pilot gives no interval or a smaller need, the pilot of kPilotUnits
// runs as before (and the quick one's host time is counted with it). Heavy frames on 64 x 32
// cores asked for +-2% had run in full after a pilot of 20-23% of their rays in detail:
// 1.27-1.57x the full run's time (docs/benchmarks.md).
constexpr uint64_t kQuickPilotUnits = 10;
constexpr double kQuickFullMargin = 8;
// The quick pilot also sends a frame in full when the rays its need would put in detail (each
// measured unit brings its warm-up) are half the frame's even at the low end of that range: a
// need 2.8 times smaller. A 1024x768 bull frame of primary rays asked for +-2% had a quick pilot
// that needed about 2,000 of its 3,070 units (over 100% of the rays in detail at its units' cost)
// and then ran the pilot of 40 as well, whose plan (848 units, 85% of the rays) ran in full: two
// pilots' process starts and units before a 0.4 s full run.
constexpr double kQuickShareMargin = 2.8;

// The units a plan may draw from (the work design's are those with work, its period counts
// them), and the ones a +-target% interval on the pilot's worst figure needs before any floor.
struct PilotNeed {
    double worst_pct, units_measured, drawable, needed;
};
PilotNeed pilot_need(const json& sm, double target_pct) {
    PilotNeed p;
    p.worst_pct = half_width_pct_of(sm["total_cycles"]);
    if (sm["counters"].contains("dram.bytes"))
        p.worst_pct = std::max(p.worst_pct, half_width_pct_of(sm["counters"]["dram.bytes"]));
    p.units_measured = sm["units_measured"].get<double>();
    p.drawable = sm.contains("drawn_population")
                     ? sm["drawn_population"].get<double>() + sm.value("certainty_units", 0.0)
                     : sm["units"].get<double>();
    // The finite-population correction makes the pilot's n look better than it is near N; n
    // (h / P)^2 with h measured at n is then an overestimate, which only errs towards detail.
    // A quarter more: the pilot's spread is itself an estimate (n = 49 sized for 10% met 11.3%
    // without it, on the built-in cornell box at 512x512).
    const double ratio = p.worst_pct / target_pct;
    p.needed = std::ceil(1.25 * p.units_measured * ratio * ratio);
    return p;
}

// A plan's record of the pilot it came from: what the pilot measured, and the units it needs.
json pilot_record(double target_pct, const json& sm, const PilotNeed& need, double units_needed,
                  double host_s) {
    return {{"target_error_pct", target_pct},
            {"pilot_period_units", sm["period_units"]},
            {"pilot_units_measured", need.units_measured},
            {"pilot_half_width_pct", need.worst_pct},
            {"units_needed", units_needed},
            {"pilot_host_s", host_s}};
}

json plan_for_target(const RunOptions& opt, SamplingParams& sp) {
    double quick_host_s = 0;
    // Not for a paired run, whose regression on its reference narrows the spread and whose
    // pilots each sample the reference too (a child run and a matched table per pilot).
    if (sp.skip && opt.reference_dir.empty()) {
        const json quick =
            run_child(opt, {"--pilot-units", std::to_string(kQuickPilotUnits)}, "--target-error");
        quick_host_s = quick["host"]["run_time_s"].get<double>();
        const json& qm = quick["sampling"];
        if (qm.contains("total_cycles")) {
            const PilotNeed q = pilot_need(qm, opt.target_error_pct);
            // The share of the rays in detail at that need, from the quick pilot's share per
            // unit measured (not clipped at 1: how far beyond the frame the need reaches).
            const double detailed_per_unit =
                qm.value("detailed_share", 0.0) / std::max(1.0, q.units_measured);
            const double detailed = detailed_per_unit * std::max(kMinTargetUnits, q.needed);
            if (std::isfinite(q.worst_pct) &&
                (q.needed >= kQuickFullMargin * kFullRunShare * q.drawable ||
                 detailed >= kQuickShareMargin * kFullRunShare)) {
                json plan = pilot_record(opt.target_error_pct, qm, q, q.needed, quick_host_s);
                plan.update(
                    {{"in_full", true},
                     {"detailed_share_planned", detailed},
                     {"note", fmt::format("a quick pilot of {:.0f} units (+-{:.1f}%) needed about "
                                          "{:.0f} of {:.0f} units ({:.0f}% of the rays in "
                                          "detail): sampling cannot beat the full run, so the "
                                          "frame ran in full, exact",
                                          q.units_measured, q.worst_pct, q.needed, q.drawable,
                                          100 * detailed)}});
                return plan;
            }
        }
    }
    const json pilot =
        run_child(opt, {"--pilot-units", std::to_string(kPilotUnits)}, "--target-error");
    const double pilot_host_s = pilot["host"]["run_time_s"].get<double>() + quick_host_s;
    const json& sm = pilot["sampling"];
    if (!sm.contains("total_cycles")) {
        // Too short a frame to sample at this period: run it in full.
        return {{"pilot_period_units", sm.value("period_units", 0)},
                {"in_full", true},
                {"note", "the pilot measured fewer than 2 units: the frame ran in full, exact"},
                {"pilot_host_s", pilot_host_s}};
    }
    const PilotNeed need = pilot_need(sm, opt.target_error_pct);
    const double drawable = need.drawable;
    // At least 30 units: with fewer, the regression on four auxiliaries has too few degrees of
    // freedom for its spread to be known (8 units, sized for 15% from a pilot's 6.2% at 36 units
    // of a 192x192 bunny frame, gave 36.8%).
    const double needed = std::min(drawable, std::max(kMinTargetUnits, need.needed));
    sp.period_units = std::max<uint64_t>(1, uint64_t(drawable / std::max(2.0, needed)));
    // The share of the frame's rays the plan would run in detail, scaled from the pilot's: the
    // work design's draws lean to heavy units, so half its units can be two thirds of the rays
    // (1080p bunny, 8 spp, 2-bounce diffuse on 64 x 32 cores: 594 of 1,188 units, 67%).
    const double pilot_period = sm["period_units"].get<double>();
    const double detailed =
        std::min(1.0, sm.value("detailed_share", 0.0) * pilot_period / double(sp.period_units));
    json plan = pilot_record(opt.target_error_pct, sm, need, needed, pilot_host_s);
    if (needed >= kFullRunShare * drawable || detailed >= kFullRunShare) {
        plan.update({{"in_full", true},
                     {"detailed_share_planned", detailed},
                     {"note", fmt::format("the plan needed {:.0f} of {:.0f} units ({:.0f}% of the "
                                          "rays in detail): sampling cannot beat the full run, so "
                                          "the frame ran in full, exact",
                                          needed, drawable, 100 * detailed)}});
    } else {
        plan["period_units"] = sp.period_units;
    }
    return plan;
}

// Whether the frame's cycles and DRAM bytes came within the target.
bool target_met(const json& sampling, double target_pct) {
    if (!sampling.contains("total_cycles")) return false;
    if (half_width_pct_of(sampling["total_cycles"]) > target_pct) return false;
    const json& c = sampling["counters"];
    return !c.contains("dram.bytes") || half_width_pct_of(c["dram.bytes"]) <= target_pct;
}

// stats.json's "sampling" section (with the --target-error plan, if any), and the frame's cycles
// and rate replaced by the sample's estimates (their intervals are in "sampling"); the blocks'
// sections stay what the detailed part measured.
void add_sampling(json& out, json sampling, json plan, double target_pct, double hz) {
    if (!plan.is_null()) {
        plan["met"] = target_met(sampling, target_pct);
        sampling["target"] = std::move(plan);
    }
    // The skip design traced part of the frame; its profile counted every ray.
    if (sampling.contains("total_rays")) {
        out["rays"]["traced"] = out["rays"]["total"];
        out["rays"]["total"] = uint64_t(sampling["total_rays"].get<double>());
    }
    if (sampling.contains("total_cycles")) {
        const json& c = sampling["total_cycles"];
        const double cycles = c["value"].get<double>();
        const double rays = double(out["rays"]["total"].get<uint64_t>());
        const double seconds = cycles / hz;
        const double rate = seconds > 0 ? rays / seconds : 0.0;
        out["total_cycles"] = uint64_t(std::llround(std::max(0.0, cycles)));
        out["simulated_seconds"] = seconds;
        out["rays_per_second"] = rate;
        // Its interval is the cycles' one, inverted (none where the cycles have none).
        if (c["hi"].is_number()) {
            const double lo = rays * hz / c["hi"].get<double>(),
                         hi = c["lo"].get<double>() > 0 ? rays * hz / c["lo"].get<double>() : 0.0;
            sampling["figures"]["rays_per_second"] = {
                {"value", rate},
                {"lo", lo},
                {"hi", hi},
                {"half_width_pct", rate > 0 ? 100.0 * (hi - lo) / 2.0 / rate : 0.0}};
        } else {
            sampling["figures"]["rays_per_second"] = {
                {"value", rate}, {"lo", nullptr}, {"hi", nullptr}, {"half_width_pct", nullptr}};
        }
    }
    out["sampling"] = std::move(sampling);
}

// This process's CPU time, every thread's (not a child process's: a paired run's matched
// sample runs in one).
double process_cpu_seconds() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

}  // namespace

int run_command(const RunOptions& opt) {
    const auto host_start = Clock::now();
    const double cpu_start = process_cpu_seconds();
    const Config cfg = load_config(opt.config_path, opt.sets);
    check_config_combination(cfg, opt.trace_path);
    if (opt.target_error_pct > 0 && !cfg.typed.sim.sampled)
        throw InputError(
            "--target-error: needs a sampled run (this config runs the whole frame); add --set "
            "sim.sampled=true");
    const bool progress = !opt.quiet && isatty(STDERR_FILENO);

    bool sampled = cfg.typed.sim.sampled;
    const bool skip_layer =
        FastForwardRegistry::at(cfg.typed.sim.sample_fast_forward).needs_profile;
    if (!opt.reference_dir.empty() && (!sampled || !skip_layer))
        throw InputError(fmt::format(
            "--reference {}: needs sim.sampled=true and sim.sample_fast_forward=skip (the "
            "reference's units are groups of tiles)",
            opt.reference_dir));
    if (!opt.sample_order_dir.empty() && (!sampled || !skip_layer))
        throw InputError(fmt::format(
            "--sample-order {}: needs sim.sampled=true and sim.sample_fast_forward=skip (it "
            "orders units of tiles)",
            opt.sample_order_dir));
    if (sampled && SampleDesignRegistry::at(cfg.typed.sim.sample_design).needs_profile &&
        (!opt.reference_dir.empty() || !opt.sample_order_dir.empty()))
        throw InputError(fmt::format(
            "{}: cannot be combined with sim.sample_design=work (which orders the units by their "
            "work itself); drop one",
            opt.reference_dir.empty() ? "--sample-order" : "--reference"));
    SamplingParams sp;
    json plan;  // --target-error: the pilot and the period it chose
    if (sampled) {
        sp = sampling_params(opt, cfg);
        // Before the workload: the skip design generates only the tiles the period wants.
        if (opt.target_error_pct > 0) plan = plan_for_target(opt, sp);
        // Asking for a target never makes a run slower than the full one (beyond its pilot).
        if (plan.is_object() && plan.value("in_full", false)) sampled = false;
    }
    const auto t_prepare = Clock::now();
    Workload w = prepare_workload(opt, cfg, progress, sampled ? &sp : nullptr);
    const std::unique_ptr<Reference>& reference = w.reference;
    // After the workload: a scene or trace refused (or a reader stopped by its watchdog) leaves
    // no output folder behind.
    const std::string out_dir = make_out_dir(opt);
    HostTimes host;
    host.prepare_s = seconds_since(t_prepare);
    CountingSource& source = *w.source;

    MemTraceRecorder* recorder = nullptr;
    std::function<std::unique_ptr<DramModel>(DramModel&)> front;
    if (!opt.mem_trace_path.empty())
        front = [&recorder](DramModel& inner) {
            auto r = std::make_unique<MemTraceRecorder>(inner);
            recorder = r.get();
            return r;
        };
    if (sampled) {
        const std::string& hold = cfg.typed.sim.sample_window_hold;
        source.hold_windows(
            hold == "drain"       ? CountingSource::WindowHold::Drain
            : hold == "predicted" ? CountingSource::WindowHold::Predicted
                                  : CountingSource::WindowHold::None,
            uint64_t(cfg.typed.sim.sample_window_hold_release_share * double(cfg.typed.core_count) *
                     double(cfg.typed.core.ray_slots)));
    }
    Chip chip(cfg.typed, &source, w.layout(), front);
    std::unique_ptr<Sampler> sampler;
    if (sampled) {
        SampledChip view;
        view.ports = chip.core_memories;
        view.l1s_over_l2 = chip.l1s_over_l2;
        view.counters = &chip.stats;
        for (const auto& core : chip.cores) view.cores.push_back(core.get());
        view.l1 = chip.l1.front().get();
        view.l2 = chip.l2.get();
        view.dram_bytes_per_l2_fill = chip.dram->bytes_moved(chip.l2->params().line_bytes);
        SampledFrame frame;
        frame.design = w.design;
        frame.profile = w.profile.get();
        frame.reference = reference.get();
        frame.cache_dir = w.cache_dir;
        frame.fetch_begin = w.layout().fetch_begin();
        frame.fetch_end = w.layout().fetch_end();
        sampler = make_sampler(cfg.typed.sim.sample_fast_forward, sp, view, frame);
        sampler->set_first_demands(chip.first_demands.get());
        source.set_sampler(sampler.get());
    }
    const auto t_sim = Clock::now();
    // A run stopped by bad input mid-way reports its own one-line error; the kernel's note that
    // sc_stop() was called would only add noise on stdout.
    sc_core::sc_report_handler::set_actions("/OSCI/SystemC", sc_core::SC_INFO,
                                            sc_core::SC_DO_NOTHING);
    sc_core::sc_start();
    host.simulation_s = seconds_since(t_sim);
    source.finish_progress();
    if (source.interrupted_by) {
        std::error_code ec;
        fs::remove(out_dir, ec);  // only if empty: the folder this run made for its output
        return report_interrupt(source.interrupted_by, "no stats written");
    }
    if (source.failed()) return report_failure(source.failure, source.failure_is_input);
    if (chip.total_cycles() >= kCalendarCycleLimit)
        return report_failure(fmt::format("simulated time reached {} cycles, past the {} cycles "
                                          "the timing models can count",
                                          chip.total_cycles(), kCalendarCycleLimit),
                              false);

    // The functional count of the L2's misses ran beside the simulation: its host time is the
    // run's.
    const double functional_l2_s = sampler ? sampler->wait_functional_l2() : 0.0;
    host.run_time_s = seconds_since(host_start);
    host.run_cpu_s = process_cpu_seconds() - cpu_start;
    if (w.bvh) {
        host.bvh_build_s = w.bvh->quality.build_seconds;
        host.bvh_cache = bvh_cache_outcome_name(w.bvh_cache.outcome);
        host.scene_load_s = w.mesh_cache.seconds;
        host.mesh_cache = w.mesh_cache.outcome;
    }
    if (w.two) {
        host.bvh_build_s = w.two_level_build_s;
        host.scene_load_s = w.scene_file_s;
        host.bvh_cache = w.cache_dir.empty() ? "off"
                                             : fmt::format("{} of {} BLASes hit", w.blas_cache_hits,
                                                           w.two->blas.size());
    }
    if (w.reader) host.trace = opt.trace_path;
    json out = run_report(cfg, chip, w.meta, source, host);
    if (sampler && w.profile) out["host"]["replay_s"] = sampler->replay_seconds();
    if (sampler && !sampler->functional_l2_cache().empty()) {
        out["host"]["functional_l2_s"] = functional_l2_s;
        out["host"]["functional_l2_cache"] = sampler->functional_l2_cache();
    }
    if (sampler && sampler->functional_l1_seconds() > 0) {
        out["host"]["functional_l1_s"] = sampler->functional_l1_seconds();
    }
    if (sampler)
        add_sampling(out, sampler->report(chip.total_cycles()), std::move(plan),
                     opt.target_error_pct, cfg.typed.clock_ghz * 1e9);
    else if (!plan.is_null()) {
        // Run in full: every figure is the frame's own, exact; the plan says why.
        plan["met"] = true;
        out["sampling"] = {{"in_full", true}, {"target", std::move(plan)}};
    }
    out["energy"] = energy_report(cfg.typed, out);
    if (sampler && !sampler->joint_estimates().empty())
        out["sampling"]["energy"] =
            sampled_energy(cfg.typed, out, sampler->joint_estimates(), cfg.typed.clock_ghz * 1e9);
    if (opt.bound) out["bound"] = bound_section(out, run_bound(opt));

    if (recorder) {
        // The command-level model's device sets the clock and burst; else chip cycles and the
        // simple model's burst.
        const bool command = cfg.typed.dram_model == "command";
        const DramDeviceSpec spec = command ? command_dram_spec(cfg.typed.dram) : DramDeviceSpec{};
        recorder->save(opt.mem_trace_path,
                       command ? spec.burst_bytes() : uint32_t(cfg.typed.dram.burst_bytes),
                       cfg.typed.clock_ghz, command ? spec.tck_ns : 0.0);
    }
    const std::string stats_path = (fs::path(out_dir) / "stats.json").string();
    if (sampler)
        write_file_atomically((fs::path(out_dir) / "sampled_units.csv").string(),
                              sampler->units_csv());
    write_file_atomically(stats_path, out.dump(2) + "\n");
    if (!opt.quiet) print_run_summary(out, stats_path);
    return 0;
}

}  // namespace rtsim

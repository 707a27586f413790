#include "sim/run.h"

#include <unistd.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <deque>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <systemc>

#include "sim/chip.h"
#include "sim/config.h"
#include "sim/output_file.h"
#include "sim/stats_report.h"
#include "workloads/bvh.h"
#include "workloads/error.h"
#include "workloads/raygen.h"
#include "workloads/scene.h"
#include "workloads/tracer.h"

#ifndef RTSIM_VERSION
#define RTSIM_VERSION "dev"
#endif

namespace rtsim {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

void parse_resolution(const std::string& text, const std::string& what, int& width, int& height) {
    int w = 0, h = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') ||
        w <= 0 || h <= 0 || w > 65536 || h > 65536)
        throw InputError(
            fmt::format("{}: expected WIDTHxHEIGHT with each in 1..65536, got '{}'", what, text));
    width = w;
    height = h;
}

Bvh build_bvh_from_config(const Config& cfg, const Scene& scene) {
    BvhBuildOptions bo;
    bo.builder = parse_bvh_builder(cfg.string("bvh.builder"), "bvh.builder");
    bo.width = int(cfg.integer("bvh.width"));
    bo.restructure_passes = int(cfg.integer("bvh.restructure_passes"));
    bo.node_format = parse_node_format(cfg.string("bvh.node_format"), "bvh.node_format");
    bo.sah_buckets = int(cfg.integer("bvh.sah_buckets"));
    bo.max_leaf_size = int(cfg.integer("bvh.max_leaf_size"));
    BvhLayout layout;
    layout.node_size_bytes = uint32_t(cfg.integer("bvh.node_size_bytes"));
    layout.tri_size_bytes = uint32_t(cfg.integer("bvh.triangle_size_bytes"));
    return build_bvh(scene, bo, layout);
}

void WorkloadOptions::resolve() {
    parse_resolution(res, "--res", gen.width, gen.height);
    gen.kinds = parse_ray_kinds(rays, "--rays");
    gen.light = parse_light_kind(light, "--light");
    gen.validate();
}

void add_workload_options(CLI::App* cmd, WorkloadOptions& w) {
    cmd->add_option("--scene", w.scene,
                    "Mesh file (OBJ, PLY, OFF, STL, ...) or builtin:NAME (cornell, sphere)")
        ->capture_default_str();
    cmd->add_option("--rays", w.rays,
                    "Comma list of ray kinds: primary, shadow, ao, diffuse, reflection")
        ->capture_default_str();
    cmd->add_option("--res", w.res, "Image resolution WIDTHxHEIGHT")->capture_default_str();
    cmd->add_option("--spp", w.gen.spp, "Primary samples per pixel (jittered when more than 1)")
        ->capture_default_str();
    cmd->add_option("--seed", w.gen.seed, "Seed for sampled rays")->capture_default_str();
    cmd->add_option("--light", w.light, "Light for shadow rays: point or area")
        ->capture_default_str();
    cmd->add_option("--ao-samples", w.gen.ao_samples, "AO rays per primary hit")
        ->capture_default_str();
    cmd->add_option("--ao-length", w.gen.ao_length_fraction,
                    "AO ray length as a fraction of the scene diagonal")
        ->capture_default_str();
    cmd->add_option("--diffuse-depth", w.gen.diffuse_depth, "Diffuse bounces per primary hit")
        ->capture_default_str();
}

namespace {

// The chip's shared work queue, filled tile by tile from the ray generator. Each ray is traced
// functionally when a core takes it, so only the rays in flight hold step streams.
class GeneratedWorkSource : public RayWorkSource {
  public:
    GeneratedWorkSource(const Scene& scene, const Bvh& bvh, RayGenerator& gen, bool progress)
        : scene_(scene),
          bvh_(bvh),
          gen_(gen),
          total_tiles_(gen.tile_count()),
          progress_(progress) {}

    bool next(RayWork& work) override {
        if (pending_.empty()) {
            std::vector<GeneratedRay> tile;
            while (tile.empty()) {
                const auto t0 = Clock::now();
                const bool more = gen_.next_tile(tile);
                functional_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
                if (!more) return false;
                ++tiles_done_;
                report_progress();
            }
            pending_.assign(tile.begin(), tile.end());
        }
        const GeneratedRay r = pending_.front();
        pending_.pop_front();
        work.ray_id = r.id;
        work.kind = r.kind;
        work.steps.clear();
        const auto t0 = Clock::now();
        const Hit h = trace_ray(bvh_, r.ray, r.query, &work.steps);
        functional_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
        rays_by_kind[static_cast<int>(r.kind)]++;
        if (h.valid()) hits_by_kind[static_cast<int>(r.kind)]++;
        steps += work.steps.size();
        return true;
    }

    void finish_progress() {
        if (progress_ && printed_) std::fprintf(stderr, "\r%60s\r", "");
    }

    std::array<uint64_t, kRayKindCount> rays_by_kind{}, hits_by_kind{};
    uint64_t steps = 0;
    double functional_seconds = 0;

  private:
    void report_progress() {
        if (!progress_) return;
        const auto now = Clock::now();
        if (printed_ && now - last_print_ < std::chrono::milliseconds(250)) return;
        last_print_ = now;
        printed_ = true;
        uint64_t rays = 0;
        for (uint64_t r : rays_by_kind) rays += r;
        std::fprintf(stderr, "\r[rtsim] %5.1f%% of tiles, %llu rays, %.4g simulated us   ",
                     100.0 * tiles_done_ / std::max(1, total_tiles_), (unsigned long long)rays,
                     sc_core::sc_time_stamp().to_seconds() * 1e6);
        std::fflush(stderr);
    }

    const Scene& scene_;
    const Bvh& bvh_;
    RayGenerator& gen_;
    std::deque<GeneratedRay> pending_;
    int total_tiles_, tiles_done_ = 0;
    bool progress_, printed_ = false;
    Clock::time_point last_print_;
};

std::string fresh_out_dir() {
    const std::time_t now = std::time(nullptr);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", std::localtime(&now));
    for (int i = 0;; ++i) {
        std::string d = fmt::format("out/run-{}{}", stamp, i ? fmt::format("-{}", i) : "");
        if (!fs::exists(d)) return d;
    }
}

json aabb_json(const AABB& b) {
    return {{"lo", {b.lo.x, b.lo.y, b.lo.z}}, {"hi", {b.hi.x, b.hi.y, b.hi.z}}};
}

}  // namespace

int run_command(const RunOptions& opt) {
    const auto host_start = Clock::now();
    const Config cfg = load_config(opt.config_path, opt.sets);

    const RayGenOptions& rg = opt.workload.gen;
    // Checked before the long work, so a bad --out fails fast and nothing is half-written.
    const std::string out_dir = opt.out_dir.empty() ? fresh_out_dir() : opt.out_dir;
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec || !fs::is_directory(out_dir))
        throw InputError(
            fmt::format("--out {}: cannot create output folder: {}", out_dir, ec.message()));

    const auto t_scene = Clock::now();
    const Scene scene = load_scene(opt.workload.scene);
    const double scene_seconds = std::chrono::duration<double>(Clock::now() - t_scene).count();

    const Bvh bvh = build_bvh_from_config(cfg, scene);
    const BvhBuildOptions& bo = bvh.options;
    const BvhLayout& layout = bvh.layout;

    RayGenerator gen(scene, bvh, rg);
    const bool progress = !opt.quiet && isatty(STDERR_FILENO);
    GeneratedWorkSource source(scene, bvh, gen, progress);

    Chip chip(cfg, &source);
    const auto t_sim = Clock::now();
    sc_core::sc_start();
    const double sim_seconds = std::chrono::duration<double>(Clock::now() - t_sim).count();
    source.finish_progress();

    ReportInputs ri;
    ri.stats = &chip.stats;
    ri.total_cycles = chip.total_cycles();
    ri.clock_ghz = cfg.number("clock_ghz");
    ri.cores = int(cfg.integer("core.count"));
    ri.box_pipelines_per_core = int(cfg.integer("box_unit.count"));
    ri.triangle_pipelines_per_core = int(cfg.integer("triangle_unit.count"));
    json timing = timing_report(ri);

    uint64_t total_rays = 0;
    json rays = json::object(), hits = json::object();
    for (int k = 0; k < kRayKindCount; ++k) {
        if (!rg.kinds[k]) continue;
        rays[ray_kind_name(RayKind(k))] = source.rays_by_kind[k];
        hits[ray_kind_name(RayKind(k))] = source.hits_by_kind[k];
        total_rays += source.rays_by_kind[k];
    }
    const double sim_s = timing["simulated_seconds"].get<double>();
    const double host_total = std::chrono::duration<double>(Clock::now() - host_start).count();

    json out;
    out["rtsim_version"] = RTSIM_VERSION;
    out["config"] = cfg.values;
    out["config_hash"] = cfg.hash();
    out["config_files"] = cfg.files;
    out["config_overrides"] = cfg.overrides;
    out["scene"] = {{"name", scene.name},
                    {"source", scene.source},
                    {"triangles", scene.triangle_count()},
                    {"vertices", scene.vertices.size()},
                    {"hash", fmt::format("{:016x}", scene.content_hash())},
                    {"bounds", aabb_json(scene.bounds())}};
    const BvhQuality& q = bvh.quality;
    out["bvh"] = {{"builder", bvh_builder_name(bo.builder)},
                  {"restructure_passes", bo.restructure_passes},
                  {"width", bvh.width()},
                  {"node_format", node_format_name(bo.node_format)},
                  {"sah_cost", q.sah_cost},
                  {"sah_traversal_cost", bo.traversal_cost},
                  {"sah_intersection_cost", bo.intersection_cost},
                  {"nodes", q.node_count},
                  {"inner_nodes", q.inner_count},
                  {"leaves", q.leaf_count},
                  {"max_depth", q.max_depth},
                  {"mean_leaf_size", q.mean_leaf_size},
                  {"mean_children", q.mean_children},
                  {"node_size_bytes", layout.node_size_bytes},
                  {"triangle_size_bytes", layout.tri_size_bytes},
                  {"node_base_addr", bvh.layout.node_base_addr},
                  {"triangle_base_addr", bvh.layout.tri_base_addr},
                  {"bytes", q.bytes}};
    out["workload"] = {{"rays", ray_kinds_to_string(rg.kinds)},
                       {"resolution", fmt::format("{}x{}", rg.width, rg.height)},
                       {"seed", rg.seed},
                       {"spp", rg.spp},
                       {"light", light_kind_name(rg.light)},
                       {"diffuse_depth", rg.diffuse_depth},
                       {"ao_samples", rg.ao_samples},
                       {"ao_length_fraction", rg.ao_length_fraction},
                       {"ao_length", gen.ao_length()},
                       {"tile_size", rg.tile_size}};
    out["rays"] = {
        {"total", total_rays}, {"by_kind", rays}, {"hits_by_kind", hits}, {"steps", source.steps}};
    out["total_cycles"] = timing["total_cycles"];
    out["clock_ghz"] = ri.clock_ghz;
    out["simulated_seconds"] = sim_s;
    out["rays_per_second"] = sim_s > 0 ? double(total_rays) / sim_s : 0.0;
    for (const char* k : {"units", "caches", "bandwidth", "counters"}) out[k] = timing[k];
    // Host timings live apart: everything outside "host" is identical for identical inputs.
    out["host"] = {{"run_time_s", host_total},
                   {"scene_load_s", scene_seconds},
                   {"bvh_build_s", q.build_seconds},
                   {"simulation_s", sim_seconds},
                   {"functional_trace_s", source.functional_seconds},
                   {"simulated_rays_per_host_second",
                    sim_seconds > 0 ? double(total_rays) / sim_seconds : 0.0}};

    const std::string stats_path = (fs::path(out_dir) / "stats.json").string();
    write_file_atomically(stats_path, out.dump(2) + "\n");

    if (!opt.quiet) {
        const json& bw = out["bandwidth"];
        const json& un = out["units"];
        const json& ca = out["caches"];
        std::string kinds;
        for (auto& [k, v] : rays.items())
            kinds += fmt::format("{}{} {}", kinds.empty() ? "" : ", ", k, v.get<uint64_t>());
        fmt::print("rtsim run  config {} ({})  scene {} ({} triangles)\n", cfg.string("name"),
                   cfg.hash(), scene.name, scene.triangle_count());
        fmt::print(
            "  bvh      {} BVH{}: {} nodes, {} leaves, depth {}, SAH cost {:.2f}, {:.2f} MiB\n",
            bvh_builder_name(bo.builder), bvh.width(), q.node_count, q.leaf_count, q.max_depth,
            q.sah_cost, q.bytes / 1048576.0);
        fmt::print("  rays     {} ({}), {} steps\n", total_rays, kinds, source.steps);
        fmt::print("  cycles   {} = {:.3f} ms at {} GHz -> {:.2f} Mrays/s\n", ri.total_cycles,
                   sim_s * 1e3, ri.clock_ghz, out["rays_per_second"].get<double>() / 1e6);
        fmt::print("  units    box {:.1f}% busy, triangle {:.1f}% busy\n",
                   100 * un["box_unit_total"]["utilization"].get<double>(),
                   100 * un["triangle_unit_total"]["utilization"].get<double>());
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
            host_total, sim_seconds,
            out["host"]["simulated_rays_per_host_second"].get<double>() / 1e6);
        fmt::print("  stats    {}\n", stats_path);
    }
    return 0;
}

}  // namespace rtsim

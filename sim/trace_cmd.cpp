#include "sim/trace_cmd.h"

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <chrono>
#include <memory>

#include "sim/interrupt.h"
#include "sim/run_report.h"
#include "workloads/error.h"
#include "workloads/mesh_cache.h"
#include "workloads/output_file.h"
#include "workloads/packet.h"
#include "workloads/parallel.h"
#include "workloads/ray_file.h"
#include "workloads/scene_file.h"
#include "workloads/tile_queue.h"
#include "workloads/trace_file.h"
#include "workloads/tracer.h"

namespace rtsim {

void add_trace_options(CLI::App* cmd, TraceOptions& t) {
    cmd->add_option("--config", t.config_path,
                    "Architecture config JSON (its bvh section is used)");
    cmd->add_option("--set", t.sets, "Override a config field, KEY=VALUE; repeatable");
    add_workload_options(cmd, t.workload);
    cmd->add_option("--rays-file", t.rays_file,
                    "Trace these rays instead of generated ones: little-endian float32 records "
                    "ox oy oz tmin dx dy dz tmax");
    cmd->add_flag("--any-hit", t.any_hit, "With --rays-file: occlusion queries (first hit found)");
    cmd->add_option("--hits", t.hits_csv,
                    "Write hits as CSV: ray,t,prim,u,v (miss: t=inf, prim=-1)");
    cmd->add_option(
        "--hits-bin", t.hits_bin,
        "Write hits as binary records: uint32 ray, float t, int32 prim, float u, float v");
    cmd->add_option("--write-rays", t.write_rays, "Write the traced rays in the ray-file format");
    cmd->add_option(
        "-o,--out", t.trace_out,
        "Record a trace file (.rtt) of every ray's steps and hit, for rtsim run --trace");
    cmd->add_option("--chunk-rays", t.trace_chunk_rays, "Rays per compressed trace chunk")
        ->capture_default_str();
    cmd->add_option("--threads,-j", t.threads, "Host threads (0: all)")->capture_default_str();
    add_bvh_cache_option(cmd, t.bvh_cache);
    cmd->add_option(
           "--packet", t.packet,
           "Trace consecutive rays of one kind in packets of this many (1..64); 0: single rays")
        ->capture_default_str();
    cmd->add_option(
           "--packet-switch", t.packet_switch,
           "With --packet: finish a subtree ray by ray once fewer than this fraction of lanes "
           "are active (0: never)")
        ->capture_default_str();
    cmd->add_flag("--quiet,-q", t.quiet, "No summary");
}

namespace {

using SteadyClock = std::chrono::steady_clock;

double seconds_since(SteadyClock::time_point t) {
    return std::chrono::duration<double>(SteadyClock::now() - t).count();
}

void check_trace_options(const TraceOptions& opt) {
    if (opt.threads < 0)
        throw InputError(fmt::format("--threads: expected 0 or more, got {}", opt.threads));
    if (opt.trace_chunk_rays < 1 || opt.trace_chunk_rays > (1u << 24))
        throw InputError(
            fmt::format("--chunk-rays: expected 1..16777216, got {}", opt.trace_chunk_rays));
    if (opt.packet != 0 && (opt.packet < 1 || opt.packet > kMaxPacketSize))
        throw InputError(
            fmt::format("--packet: expected 0 or 1..{}, got {}", kMaxPacketSize, opt.packet));
    if (!(opt.packet_switch >= 0.0f && opt.packet_switch <= 1.0f))
        throw InputError(fmt::format("--packet-switch: expected a fraction from 0 to 1, got {}",
                                     opt.packet_switch));
    if (!opt.trace_out.empty() && opt.packet > 0)
        throw InputError("--packet: a trace records single-ray traversal; drop --packet with -o");
}

// One batch of rays to trace: from a ray file or the generator.
struct Batch {
    std::vector<Ray> rays;
    std::vector<HitQuery> queries;
    std::vector<uint32_t> ids;
    std::vector<RayKind> kinds;
    void clear() {
        rays.clear();
        queries.clear();
        ids.clear();
        kinds.clear();
    }
    void add(const Ray& r, HitQuery q, uint32_t id, RayKind k) {
        rays.push_back(r);
        queries.push_back(q);
        ids.push_back(id);
        kinds.push_back(k);
    }
};

// `rtsim trace` as a job: inputs checked and loaded, outputs opened (they appear only when
// complete), then batch after batch traced on all threads and written out.
class TraceJob {
  public:
    explicit TraceJob(const TraceOptions& opt)
        : opt_(opt),
          cfg_(load_config(opt.config_path, opt.sets)),
          reader_(opt.rays_file.empty() ? nullptr : std::make_unique<RayFileReader>(opt.rays_file)),
          scene_file_(is_scene_file(opt.workload.scene)),
          scene_(scene_file_
                     ? Scene()
                     : load_scene_cached(opt.workload.scene, resolve_bvh_cache_dir(opt.bvh_cache),
                                         &mesh_status_, opt.workload.flatten ? nullptr : &iscene_)),
          instanced_(scene_file_ || !iscene_.instances.empty()),
          bvh_(instanced_
                   ? Bvh()
                   : build_bvh_from_config(cfg_, scene_, resolve_bvh_cache_dir(opt.bvh_cache))),
          threads_(resolve_threads(opt.threads)) {
        if (instanced_) load_instanced();
        if (!reader_) {
            gen_ = instanced_ ? std::make_unique<RayGenerator>(iscene_, two_, opt.workload.gen)
                              : std::make_unique<RayGenerator>(scene_, bvh_, opt.workload.gen);
            tiles_ = std::make_unique<TileQueue>(*gen_, threads_);  // tiles generated in parallel
        } else {
            // As the generator does.
            check_scene_range(instanced_ ? iscene_.name : scene_.name,
                              instanced_ ? two_.bounds() : bvh_.bounds());
        }
        open_outputs();
    }

    void run() {
        const auto t0 = SteadyClock::now();
        while (gather()) {
            check_interrupt();  // SIGINT/SIGTERM: the outputs' temporary files go with the stack
            trace_batch();
            write_batch();
        }
        for (auto* f : {csv_.get(), bin_.get(), rays_out_.get()})
            if (f) f->commit();
        if (trace_out_) {
            const auto tw = SteadyClock::now();
            trace_out_->finish();
            write_seconds_ += seconds_since(tw);
        }
        if (!opt_.quiet) print_summary(seconds_since(t0));
    }

  private:
    // A scene of instances (a JSON scene file, workloads/scene_file.h, or a mesh file whose
    // nodes share meshes): its meshes' BLASes and the TLAS over its instances, with the config's
    // BVH settings. What the two-level tracer does not record yet is refused before anything is
    // written.
    void load_instanced() {
        const std::string& file = opt_.workload.scene;
        const char* or_flatten = scene_file_ ? "" : kOrFlatten;
        if (opt_.packet > 0)
            throw InputError(fmt::format(
                "--packet: {} is an instanced scene; packets trace one level{}", file, or_flatten));
        if (!opt_.hits_bin.empty())
            throw InputError(fmt::format(
                "--hits-bin: {} is an instanced scene; its hits carry an instance, written by "
                "--hits (CSV){}",
                file, or_flatten));
        const auto t0 = SteadyClock::now();
        const std::string cache_dir = resolve_bvh_cache_dir(opt_.bvh_cache);
        if (scene_file_) iscene_ = load_scene_file(file, cache_dir);  // (else read with the mesh)
        const auto t1 = SteadyClock::now();
        two_ = build_two_level_from_config(cfg_, iscene_, cache_dir);
        load_seconds_ = std::chrono::duration<double>(t1 - t0).count() +
                        (scene_file_ ? 0.0 : mesh_status_.seconds);
        build_seconds_ = seconds_since(t1);
    }

    void open_outputs() {
        if (!opt_.hits_csv.empty()) {
            csv_ = std::make_unique<AtomicOutputFile>(opt_.hits_csv);
            csv_->write(instanced_ ? kInstancedHitCsvHeader : kHitCsvHeader);
        }
        if (!opt_.hits_bin.empty()) bin_ = std::make_unique<AtomicOutputFile>(opt_.hits_bin);
        if (!opt_.write_rays.empty())
            rays_out_ = std::make_unique<AtomicOutputFile>(opt_.write_rays);
        if (opt_.trace_out.empty()) return;
        nlohmann::json meta = {
            {"rtsim_version", RTSIM_VERSION},
            {"scene", instanced_ ? scene_summary(iscene_) : scene_summary(scene_)},
            {"bvh", instanced_ ? bvh_summary(two_, true) : bvh_summary(bvh_, true)}};
        if (reader_)
            meta["workload"] = {{"rays_file", opt_.rays_file},
                                {"query", opt_.any_hit ? "any" : "closest"}};
        else
            meta["workload"] = workload_summary(opt_.workload.gen, gen_->ao_length());
        trace_out_ = std::make_unique<TraceWriter>(opt_.trace_out, meta.dump(),
                                                   opt_.trace_chunk_rays, 3, instanced_);
    }

    // The next batch of rays; false when there are none left.
    bool gather() {
        constexpr size_t kBatchRays = 1 << 16;
        batch_.clear();
        if (reader_) {
            if (!reader_->read(file_rays_, kBatchRays)) return false;
            const HitQuery q = opt_.any_hit ? HitQuery::Any : HitQuery::Closest;
            const RayKind k = opt_.any_hit ? RayKind::Shadow : RayKind::Primary;
            for (size_t i = 0; i < file_rays_.size(); ++i)
                batch_.add(file_rays_[i], q, uint32_t(total_ + i), k);
            return true;
        }
        generated_.clear();
        while (generated_.size() < kBatchRays && tiles_->next(generated_)) {
        }
        for (const GeneratedRay& g : generated_) batch_.add(g.ray, g.query, g.id, g.kind);
        return !generated_.empty();
    }

    // Traces the batch in parallel (each ray's result has its own slot) and counts its work.
    void trace_batch() {
        const size_t n = batch_.rays.size();
        results_.assign(n, Hit());
        counters_.assign(n, TraceCounters());
        const auto ts = SteadyClock::now();
        if (opt_.packet > 0) {
            trace_packets();
        } else {
            if (trace_out_) records_.resize(n);
            parallel_blocks(n, 256, threads_, [&](size_t b, size_t e) {
                for (size_t i = b; i < e; ++i) {
                    std::vector<Step>* steps = trace_out_ ? &records_[i].steps : nullptr;
                    if (steps) steps->clear();
                    if (!instanced_)
                        results_[i] = trace_ray(bvh_, batch_.rays[i], batch_.queries[i], steps,
                                                &counters_[i]);
                    else if (steps)
                        results_[i] = trace_ray_recorded(two_, batch_.rays[i], batch_.queries[i],
                                                         *steps, 0xff, &counters_[i]);
                    else
                        results_[i] =
                            trace_ray(two_, batch_.rays[i], batch_.queries[i], 0xff, &counters_[i]);
                }
            });
        }
        trace_seconds_ += seconds_since(ts);
        for (size_t i = 0; i < n; ++i) {
            hits_ += results_[i].valid();
            nodes_ += counters_[i].nodes;
            boxes_ += counters_[i].box_tests;
            tris_ += counters_[i].tri_tests;
            by_kind_[int(batch_.kinds[i])]++;
        }
        total_ += n;
    }

    void trace_packets() {
        const auto packets =
            packet_runs(batch_.rays.size(), opt_.packet, [&](size_t i) { return batch_.kinds[i]; });
        std::vector<PacketStats> stats(packets.size());
        PacketOptions po;
        po.size = opt_.packet;
        po.switch_threshold = opt_.packet_switch;
        parallel_blocks(packets.size(), 16, threads_, [&](size_t b, size_t e) {
            for (size_t p = b; p < e; ++p) {
                const auto [first, last] = packets[p];
                trace_packet(bvh_, &batch_.rays[first], int(last - first), batch_.queries[first],
                             &results_[first], po, stats[p]);
            }
        });
        for (size_t p = 0; p < packets.size(); ++p) {
            packet_by_kind_[int(batch_.kinds[packets[p].first])].add(stats[p]);
            nodes_ += stats[p].node_visits + stats[p].single_ray_nodes;
            boxes_ += stats[p].box_tests;
            tris_ += stats[p].tri_tests;
        }
    }

    void write_batch() {
        const size_t n = batch_.rays.size();
        if (trace_out_) {
            const auto tw = SteadyClock::now();
            for (size_t i = 0; i < n; ++i) {
                TraceRecord& r = records_[i];
                r.ray_id = batch_.ids[i];
                r.kind = batch_.kinds[i];
                r.prim = results_[i].prim;
                r.t = results_[i].t;
                r.instance = results_[i].instance;
                trace_out_->add(r);
            }
            write_seconds_ += seconds_since(tw);
        }
        if (csv_) {
            text_.clear();
            for (size_t i = 0; i < n; ++i)
                append_hit_csv(batch_.ids[i], results_[i], text_, instanced_);
            csv_->write(text_);
        }
        if (bin_) {
            text_.clear();
            for (size_t i = 0; i < n; ++i) append_hit_binary(batch_.ids[i], results_[i], text_);
            bin_->write(text_);
        }
        if (rays_out_) {
            text_.clear();
            append_ray_records(batch_.rays, text_);
            rays_out_->write(text_);
        }
    }

    void print_summary(double wall) const {
        std::string kinds;
        for (int k = 0; k < kRayKindCount; ++k)
            if (by_kind_[k])
                kinds += fmt::format("{}{} {}", kinds.empty() ? "" : ", ",
                                     ray_kind_name(RayKind(k)), by_kind_[k]);
        if (instanced_)
            fmt::print(
                "rtsim trace  scene {} ({} mesh{}, {} triangles; {} instances, {} instanced "
                "triangles), read in {:.3f} s; {} BVH{} over two levels, built in {:.3f} s\n",
                iscene_.name, iscene_.meshes.size(), iscene_.meshes.size() == 1 ? "" : "es",
                iscene_.unique_triangle_count(), iscene_.instances.size(),
                iscene_.instanced_triangle_count(), load_seconds_,
                bvh_builder_name(two_.options.builder), two_.options.width, build_seconds_);
        else
            fmt::print(
                "rtsim trace  scene {} ({} triangles), {} BVH{}, SAH cost {:.2f}, built in {:.3f} "
                "s\n",
                scene_.name, scene_.triangle_count(), bvh_builder_name(bvh_.options.builder),
                bvh_.width(), bvh_.quality.sah_cost, bvh_.quality.build_seconds);
        fmt::print("  rays     {} ({}) from {}\n", total_, kinds.empty() ? "none" : kinds,
                   reader_ ? opt_.rays_file : "the generator");
        fmt::print("  hits     {} ({:.1f}%)\n", hits_, total_ ? 100.0 * hits_ / total_ : 0.0);
        for (int k = 0; k < kRayKindCount && opt_.packet > 0; ++k) {
            const PacketStats& p = packet_by_kind_[k];
            if (!p.packets) continue;
            fmt::print(
                "  packets  {:10} {} packets of up to {}: lane utilisation {:.1f}%, {} packet "
                "node visits, {} switches to single rays ({} single-ray node visits)\n",
                ray_kind_name(RayKind(k)), p.packets, opt_.packet, 100 * p.utilization(),
                p.node_visits, p.switches, p.single_ray_nodes);
        }
        const double per_ray = total_ ? 1.0 / double(total_) : 0.0;
        fmt::print("  work     {:.3f} nodes, {:.3f} box tests, {:.3f} triangle tests per ray\n",
                   nodes_ * per_ray, boxes_ * per_ray, tris_ * per_ray);
        fmt::print("  speed    {:.2f} Mrays/s tracing on {} thread{} ({:.3f} s; {:.3f} s in all)\n",
                   trace_seconds_ > 0 ? total_ / trace_seconds_ / 1e6 : 0.0, threads_,
                   threads_ == 1 ? "" : "s", trace_seconds_, wall);
        for (auto* f : {csv_.get(), bin_.get(), rays_out_.get()})
            if (f) fmt::print("  wrote    {}\n", f->path());
        if (trace_out_) print_trace_summary();
        fmt::print("  memory   peak RSS {:.0f} MiB\n", peak_rss_mib());
    }

    void print_trace_summary() const {
        const TraceWriter& t = *trace_out_;
        const double mb = t.file_bytes() / 1e6;
        fmt::print(
            "  trace    {}: {} rays, {} steps, {:.2f} MB ({:.2f} bytes/ray, {:.3f} bytes/step; "
            "{:.1f}x smaller than raw), encoded at {:.1f} MB/s\n",
            opt_.trace_out, t.rays(), t.steps(), mb,
            t.rays() ? double(t.file_bytes()) / t.rays() : 0.0,
            t.steps() ? double(t.file_bytes()) / t.steps() : 0.0,
            t.file_bytes() ? double(t.raw_bytes()) / t.file_bytes() : 0.0,
            write_seconds_ > 0 ? mb / write_seconds_ : 0.0);
    }

    const TraceOptions& opt_;
    const Config cfg_;
    std::unique_ptr<RayFileReader> reader_;
    const bool scene_file_;
    MeshCacheStatus mesh_status_;
    // A scene of instances (a scene file, or a mesh file whose nodes share meshes).
    InstancedScene iscene_;
    const Scene scene_;
    const bool instanced_;  // iscene_ and two_ instead of scene_ and bvh_
    const Bvh bvh_;
    TwoLevelBvh two_;
    double load_seconds_ = 0, build_seconds_ = 0;
    const int threads_;
    std::unique_ptr<RayGenerator> gen_;
    std::unique_ptr<AtomicOutputFile> csv_, bin_, rays_out_;
    std::unique_ptr<TraceWriter> trace_out_;

    Batch batch_;
    std::vector<Ray> file_rays_;
    std::unique_ptr<TileQueue> tiles_;
    std::vector<GeneratedRay> generated_;
    std::vector<Hit> results_;
    std::vector<TraceCounters> counters_;
    std::vector<TraceRecord> records_;
    std::string text_;
    double trace_seconds_ = 0, write_seconds_ = 0;
    uint64_t total_ = 0, hits_ = 0, nodes_ = 0, boxes_ = 0, tris_ = 0;
    std::array<uint64_t, kRayKindCount> by_kind_{};
    std::array<PacketStats, kRayKindCount> packet_by_kind_;
};

}  // namespace

int trace_command(const TraceOptions& opt) {
    check_trace_options(opt);
    TraceJob(opt).run();
    return 0;
}

}  // namespace rtsim

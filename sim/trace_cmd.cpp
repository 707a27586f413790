#include "sim/trace_cmd.h"

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <chrono>
#include <memory>

#include "sim/run_report.h"
#include "workloads/error.h"
#include "workloads/output_file.h"
#include "workloads/packet.h"
#include "workloads/parallel.h"
#include "workloads/ray_file.h"
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
};

}  // namespace

int trace_command(const TraceOptions& opt) {
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
    const Config cfg = load_config(opt.config_path, opt.sets);
    std::unique_ptr<RayFileReader> reader;
    if (!opt.rays_file.empty()) reader = std::make_unique<RayFileReader>(opt.rays_file);
    const Scene scene = load_scene(opt.workload.scene);
    const Bvh bvh = build_bvh_from_config(cfg, scene);

    // Outputs are opened only once all inputs have been checked; they appear when complete.
    std::unique_ptr<AtomicOutputFile> csv, bin, rays_out;
    if (!opt.hits_csv.empty()) {
        csv = std::make_unique<AtomicOutputFile>(opt.hits_csv);
        csv->write(kHitCsvHeader);
    }
    if (!opt.hits_bin.empty()) bin = std::make_unique<AtomicOutputFile>(opt.hits_bin);
    if (!opt.write_rays.empty()) rays_out = std::make_unique<AtomicOutputFile>(opt.write_rays);

    std::unique_ptr<RayGenerator> gen;
    if (!reader) gen = std::make_unique<RayGenerator>(scene, bvh, opt.workload.gen);
    std::unique_ptr<TraceWriter> trace_out;
    if (!opt.trace_out.empty()) {
        if (opt.packet > 0)
            throw InputError(
                "--packet: a trace records single-ray traversal; drop --packet with -o");
        nlohmann::json meta = {{"rtsim_version", RTSIM_VERSION},
                               {"scene", scene_summary(scene)},
                               {"bvh", bvh_summary(bvh, true)}};
        if (reader)
            meta["workload"] = {{"rays_file", opt.rays_file},
                                {"query", opt.any_hit ? "any" : "closest"}};
        else
            meta["workload"] = workload_summary(opt.workload.gen, gen->ao_length());
        trace_out = std::make_unique<TraceWriter>(opt.trace_out, meta.dump(), opt.trace_chunk_rays);
    }
    const int threads = resolve_threads(opt.threads);
    const auto t0 = std::chrono::steady_clock::now();
    double trace_seconds = 0, write_seconds = 0;
    std::vector<TraceRecord> records;
    uint64_t total = 0, hits = 0, nodes = 0, tris = 0;
    std::array<uint64_t, kRayKindCount> by_kind{};

    Batch batch;
    std::vector<Ray> file_rays;
    std::vector<GeneratedRay> generated;
    std::vector<Hit> results;
    std::vector<TraceCounters> counters;
    std::vector<std::pair<size_t, size_t>> packets;
    std::vector<PacketStats> packet_stats;
    std::array<PacketStats, kRayKindCount> packet_by_kind;
    std::string text;
    constexpr size_t kBatchRays = 1 << 16;
    for (;;) {
        // Gather one batch of rays.
        batch.clear();
        if (reader) {
            if (!reader->read(file_rays, kBatchRays)) break;
            for (size_t i = 0; i < file_rays.size(); ++i) {
                batch.rays.push_back(file_rays[i]);
                batch.queries.push_back(opt.any_hit ? HitQuery::Any : HitQuery::Closest);
                batch.ids.push_back(uint32_t(total + i));
                batch.kinds.push_back(opt.any_hit ? RayKind::Shadow : RayKind::Primary);
            }
        } else {
            generated.clear();
            while (generated.size() < kBatchRays && gen->next_tile(generated)) {
            }
            if (generated.empty()) break;
            for (const GeneratedRay& g : generated) {
                batch.rays.push_back(g.ray);
                batch.queries.push_back(g.query);
                batch.ids.push_back(g.id);
                batch.kinds.push_back(g.kind);
            }
        }
        // Trace it in parallel; each ray's result has its own slot.
        const size_t n = batch.rays.size();
        results.assign(n, Hit());
        counters.assign(n, TraceCounters());
        const auto ts = std::chrono::steady_clock::now();
        if (opt.packet > 0) {
            packets = packet_runs(n, opt.packet, [&](size_t i) { return batch.kinds[i]; });
            packet_stats.assign(packets.size(), PacketStats());
            PacketOptions po;
            po.size = opt.packet;
            po.switch_threshold = opt.packet_switch;
            parallel_blocks(packets.size(), 16, threads, [&](size_t b, size_t e) {
                for (size_t p = b; p < e; ++p) {
                    const auto [first, last] = packets[p];
                    trace_packet(bvh, &batch.rays[first], int(last - first), batch.queries[first],
                                 &results[first], po, packet_stats[p]);
                }
            });
            for (size_t p = 0; p < packets.size(); ++p) {
                packet_by_kind[int(batch.kinds[packets[p].first])].add(packet_stats[p]);
                nodes += packet_stats[p].node_visits + packet_stats[p].single_ray_nodes;
                tris += packet_stats[p].tri_tests;
            }
        } else if (trace_out) {
            records.resize(n);
            parallel_blocks(n, 256, threads, [&](size_t b, size_t e) {
                for (size_t i = b; i < e; ++i) {
                    records[i].steps.clear();
                    results[i] = trace_ray(bvh, batch.rays[i], batch.queries[i], &records[i].steps,
                                           &counters[i]);
                }
            });
        } else {
            parallel_blocks(n, 256, threads, [&](size_t b, size_t e) {
                for (size_t i = b; i < e; ++i)
                    results[i] =
                        trace_ray(bvh, batch.rays[i], batch.queries[i], nullptr, &counters[i]);
            });
        }
        trace_seconds +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - ts).count();
        for (size_t i = 0; i < n; ++i) {
            hits += results[i].valid();
            nodes += counters[i].nodes;
            tris += counters[i].tri_tests;
            by_kind[int(batch.kinds[i])]++;
        }
        total += n;
        if (trace_out) {
            const auto tw = std::chrono::steady_clock::now();
            for (size_t i = 0; i < n; ++i) {
                TraceRecord& r = records[i];
                r.ray_id = batch.ids[i];
                r.kind = batch.kinds[i];
                r.prim = results[i].prim;
                r.t = results[i].t;
                trace_out->add(r);
            }
            write_seconds +=
                std::chrono::duration<double>(std::chrono::steady_clock::now() - tw).count();
        }
        if (csv) {
            text.clear();
            for (size_t i = 0; i < n; ++i) append_hit_csv(batch.ids[i], results[i], text);
            csv->write(text);
        }
        if (bin) {
            text.clear();
            for (size_t i = 0; i < n; ++i) append_hit_binary(batch.ids[i], results[i], text);
            bin->write(text);
        }
        if (rays_out) {
            text.clear();
            append_ray_records(batch.rays, text);
            rays_out->write(text);
        }
    }
    for (auto* f : {csv.get(), bin.get(), rays_out.get()})
        if (f) f->commit();
    if (trace_out) {
        const auto tw = std::chrono::steady_clock::now();
        trace_out->finish();
        write_seconds +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - tw).count();
    }

    if (!opt.quiet) {
        const double wall =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::string kinds;
        for (int k = 0; k < kRayKindCount; ++k)
            if (by_kind[k])
                kinds += fmt::format("{}{} {}", kinds.empty() ? "" : ", ",
                                     ray_kind_name(RayKind(k)), by_kind[k]);
        fmt::print(
            "rtsim trace  scene {} ({} triangles), {} BVH{}, SAH cost {:.2f}, built in {:.3f} s\n",
            scene.name, scene.triangle_count(), bvh_builder_name(bvh.options.builder), bvh.width(),
            bvh.quality.sah_cost, bvh.quality.build_seconds);
        fmt::print("  rays     {} ({}) from {}\n", total, kinds.empty() ? "none" : kinds,
                   reader ? opt.rays_file : "the generator");
        fmt::print("  hits     {} ({:.1f}%)\n", hits, total ? 100.0 * hits / total : 0.0);
        if (opt.packet > 0)
            for (int k = 0; k < kRayKindCount; ++k) {
                const PacketStats& p = packet_by_kind[k];
                if (!p.packets) continue;
                fmt::print(
                    "  packets  {:10} {} packets of up to {}: lane utilisation {:.1f}%, {} packet "
                    "node visits, "
                    "{} switches to single rays ({} single-ray node visits)\n",
                    ray_kind_name(RayKind(k)), p.packets, opt.packet, 100 * p.utilization(),
                    p.node_visits, p.switches, p.single_ray_nodes);
            }
        fmt::print("  work     {:.2f} nodes, {:.2f} triangle tests per ray\n",
                   total ? double(nodes) / total : 0.0, total ? double(tris) / total : 0.0);
        fmt::print("  speed    {:.2f} Mrays/s tracing on {} thread{} ({:.3f} s; {:.3f} s in all)\n",
                   trace_seconds > 0 ? total / trace_seconds / 1e6 : 0.0, threads,
                   threads == 1 ? "" : "s", trace_seconds, wall);
        for (auto* f : {csv.get(), bin.get(), rays_out.get()})
            if (f) fmt::print("  wrote    {}\n", f->path());
        if (trace_out) {
            const double mb = trace_out->file_bytes() / 1e6;
            fmt::print(
                "  trace    {}: {} rays, {} steps, {:.2f} MB ({:.2f} bytes/ray, {:.3f} bytes/step; "
                "{:.1f}x smaller than raw), encoded at {:.1f} MB/s\n",
                opt.trace_out, trace_out->rays(), trace_out->steps(), mb,
                trace_out->rays() ? double(trace_out->file_bytes()) / trace_out->rays() : 0.0,
                trace_out->steps() ? double(trace_out->file_bytes()) / trace_out->steps() : 0.0,
                trace_out->file_bytes() ? double(trace_out->raw_bytes()) / trace_out->file_bytes()
                                        : 0.0,
                write_seconds > 0 ? mb / write_seconds : 0.0);
        }
        fmt::print("  memory   peak RSS {:.0f} MiB\n", peak_rss_mib());
    }
    return 0;
}

}  // namespace rtsim

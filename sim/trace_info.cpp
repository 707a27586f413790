#include "sim/trace_info.h"

#include <fmt/format.h>
#include <array>
#include <nlohmann/json.hpp>

#include "sim/run.h"
#include "workloads/error.h"
#include "workloads/trace_file.h"

namespace rtsim {

using nlohmann::json;

namespace {

// Power-of-two buckets: 0, 1, 2-3, 4-7, ...
constexpr int kBuckets = 16;
int bucket(uint64_t n) {
    int b = 0;
    while (n && b < kBuckets - 1) {
        n >>= 1;
        ++b;
    }
    return b;
}
std::string bucket_label(int b) {
    if (b == 0) return "0";
    if (b == 1) return "1";
    if (b == kBuckets - 1) return fmt::format("{}+", 1u << (b - 1));
    return fmt::format("{}-{}", 1u << (b - 1), (1u << b) - 1);
}

struct KindStats {
    uint64_t rays = 0, hits = 0, nodes = 0, tris = 0, transforms = 0, any_hits = 0;
    uint64_t crossings = 0;  // steps into another treelet than the step before
    std::array<uint64_t, kBuckets> node_hist{}, tri_hist{};
};

}  // namespace

int trace_info_command(const std::string& path, bool as_json) {
    TraceReader reader(path);
    const json meta = open_trace_metadata(reader, path);

    std::array<KindStats, kRayKindCount> kinds;
    std::vector<TraceRecord> chunk;
    for (size_t k = 0; k < reader.chunk_count(); ++k) {
        reader.read_chunk(k, chunk);
        for (const TraceRecord& r : chunk) {
            KindStats& s = kinds[int(r.kind)];
            uint64_t nodes = 0, tris = 0;
            for (size_t i = 0; i < r.steps.size(); ++i) {
                const StepKind kind = r.steps[i].kind;
                if (kind == StepKind::Transform)
                    s.transforms++;
                else if (kind == StepKind::AnyHit)
                    s.any_hits++;
                else
                    (kind == StepKind::Node ? nodes : tris)++;
                if (i > 0 && r.steps[i].treelet != r.steps[i - 1].treelet) s.crossings++;
            }
            s.rays++;
            s.hits += r.prim != kInvalidPrim;
            s.nodes += nodes;
            s.tris += tris;
            s.node_hist[bucket(nodes)]++;
            s.tri_hist[bucket(tris)]++;
        }
    }

    json out = {
        {"file", path},
        {"format_version", reader.version()},
        {"bytes", reader.file_bytes()},
        {"chunks", reader.chunk_count()},
        {"rays", reader.rays()},
        {"steps", reader.steps()},
        {"bytes_per_ray", reader.rays() ? double(reader.file_bytes()) / reader.rays() : 0.0},
        {"bytes_per_step", reader.steps() ? double(reader.file_bytes()) / reader.steps() : 0.0},
        {"metadata", meta}};
    json by_kind = json::object();
    for (int k = 0; k < kRayKindCount; ++k) {
        const KindStats& s = kinds[k];
        if (!s.rays) continue;
        // Histograms as [bucket, rays] pairs in bucket order (JSON objects would sort the labels).
        json nh = json::array(), th = json::array();
        for (int b = 0; b < kBuckets; ++b) {
            if (s.node_hist[b]) nh.push_back({bucket_label(b), s.node_hist[b]});
            if (s.tri_hist[b]) th.push_back({bucket_label(b), s.tri_hist[b]});
        }
        by_kind[ray_kind_name(RayKind(k))] = {{"rays", s.rays},
                                              {"hits", s.hits},
                                              {"node_steps", s.nodes},
                                              {"triangle_steps", s.tris},
                                              {"treelet_crossings", s.crossings},
                                              {"nodes_per_ray_histogram", nh},
                                              {"triangles_per_ray_histogram", th}};
        // Two-level scenes only: the instance records entered.
        if (s.transforms) by_kind[ray_kind_name(RayKind(k))]["transform_steps"] = s.transforms;
        // ...and of them, scenes with non-opaque instances: the any-hit shader calls.
        if (s.any_hits) by_kind[ray_kind_name(RayKind(k))]["any_hit_steps"] = s.any_hits;
    }
    out["by_kind"] = by_kind;
    if (as_json) {
        fmt::print("{}\n", out.dump(2));
        return 0;
    }
    const json& sc = meta.value("scene", json::object());
    const json& bv = meta["bvh"];
    fmt::print("{}: RTSim trace, format version {}, {} bytes in {} chunks\n", path,
               reader.version(), reader.file_bytes(), reader.chunk_count());
    fmt::print("  scene     {} ({} triangles, hash {})\n", sc.value("name", std::string("?")),
               sc.value("triangles", 0), sc.value("hash", std::string("?")));
    if (sc.contains("instances"))
        fmt::print(
            "  instances {} of {} meshes, {} instanced triangles; {} instance records of {} "
            "bytes\n",
            sc.value("instances", 0), sc.value("meshes", 0),
            sc.value("instanced_triangles", uint64_t(0)), bv["layout"].value("instance_count", 0),
            bv["layout"].value("instance_size_bytes", 0));
    fmt::print("  bvh       {} BVH{} {}, {} node records of {} bytes, triangles of {} bytes\n",
               bv.value("builder", std::string("?")), bv.value("width", 0),
               bv.value("node_format", std::string("?")), bv["layout"].value("inner_node_count", 0),
               bv["layout"].value("node_size_bytes", 0),
               bv["layout"].value("triangle_size_bytes", 0));
    const uint32_t treelets = bv["layout"].value("treelets", 0u);
    if (treelets)
        fmt::print("  treelets  {} of at most {} bytes\n", treelets,
                   bv["layout"].value("treelet_bytes", 0u));
    fmt::print("  workload  {}\n", meta.value("workload", json::object()).dump());
    fmt::print("  rays      {}, steps {}: {:.2f} bytes per ray, {:.3f} bytes per step\n",
               reader.rays(), reader.steps(), out["bytes_per_ray"].get<double>(),
               out["bytes_per_step"].get<double>());
    for (auto& [name, s] : by_kind.items()) {
        const double rays = s["rays"].get<double>();
        fmt::print("  {:10} {} rays, {} hits, {:.2f} nodes and {:.2f} triangles per ray", name,
                   s["rays"].get<uint64_t>(), s["hits"].get<uint64_t>(),
                   s["node_steps"].get<double>() / rays, s["triangle_steps"].get<double>() / rays);
        if (s.contains("transform_steps"))
            fmt::print(", {:.2f} instances entered", s["transform_steps"].get<double>() / rays);
        if (s.contains("any_hit_steps"))
            fmt::print(", {:.2f} any-hit calls", s["any_hit_steps"].get<double>() / rays);
        if (treelets)
            fmt::print(", {:.2f} treelet crossings", s["treelet_crossings"].get<double>() / rays);
        fmt::print("\n");
        for (const char* h : {"nodes_per_ray_histogram", "triangles_per_ray_histogram"}) {
            std::string row;
            for (const json& b : s[h])
                row += fmt::format("  {}:{}", b[0].get<std::string>(), b[1].get<uint64_t>());
            fmt::print("    {:10}{}\n", h[0] == 'n' ? "nodes" : "triangles", row);
        }
    }
    return 0;
}

}  // namespace rtsim

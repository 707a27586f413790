// Functional tracer benchmark: our tracer against Embree on the same meshes and rays, and the
// table of claims about BVH width and builders reproduced from our own measurements.
// A benchmark, not a test: it prints figures and ratios measured within one run.
//
//   build/bench_tracer [--threads N] [--res WxH] [--reps N] [--leaf N] [--kinds primary,ao,...]
//   [mesh ...]
// With no mesh, uses the glmark2 bunny and the largest libcgal-demo meshes in .cache/meshes/cgal.

#include <fmt/format.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "support/embree_scene.h"
#include "workloads/bvh.h"
#include "workloads/packet.h"
#include "workloads/parallel.h"
#include "workloads/raygen.h"
#include "workloads/scene.h"
#include "workloads/tile_queue.h"
#include "workloads/tracer.h"

using namespace rtsim;
using rtsim::test::EmbreeScene;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

struct RaySet {
    std::string kind;
    std::vector<Ray> rays;
    HitQuery query;
};

// Rays of one kind from the generator (secondaries found with a SAH BVH8).
RaySet make_rays(const Scene& s, const Bvh& bvh, const char* kind, int w, int h) {
    RayGenOptions o;
    o.width = w;
    o.height = h;
    o.kinds = parse_ray_kinds(kind, "bench");
    o.ao_samples = 4;
    o.diffuse_depth = 2;
    RayGenerator gen(s, bvh, o);
    std::vector<GeneratedRay> g;
    TileQueue tiles(gen, 1);
    while (tiles.next(g)) {
    }
    RaySet set{kind, {}, g.empty() ? HitQuery::Closest : g[0].query};
    for (const GeneratedRay& r : g) set.rays.push_back(r.ray);
    return set;
}

// Best of `reps` timings of tracing every ray, in Mrays/s.
template <class F>
double mrays(size_t n, int reps, F trace_all) {
    double best = 1e30;
    for (int r = 0; r < reps; ++r) {
        const auto t0 = Clock::now();
        trace_all();
        best = std::min(best, seconds_since(t0));
    }
    return n / best / 1e6;
}

double ours(const Bvh& bvh, const RaySet& rs, int threads, int reps, uint64_t* checksum) {
    std::vector<uint32_t> prims(rs.rays.size());
    const double r = mrays(rs.rays.size(), reps, [&] {
        parallel_blocks(rs.rays.size(), 512, threads, [&](size_t b, size_t e) {
            for (size_t i = b; i < e; ++i) prims[i] = trace_ray(bvh, rs.rays[i], rs.query).prim;
        });
    });
    *checksum = 0;
    for (uint32_t p : prims) *checksum += p != kInvalidPrim;
    return r;
}

double embree(const EmbreeScene& es, const RaySet& rs, int threads, int reps, uint64_t* checksum) {
    std::vector<uint8_t> hit(rs.rays.size());
    const double r = mrays(rs.rays.size(), reps, [&] {
        parallel_blocks(rs.rays.size(), 512, threads, [&](size_t b, size_t e) {
            for (size_t i = b; i < e; ++i)
                hit[i] = rs.query == HitQuery::Any ? es.occluded(rs.rays[i])
                                                   : es.intersect(rs.rays[i]).valid();
        });
    });
    *checksum = 0;
    for (uint8_t h : hit) *checksum += h;
    return r;
}

}  // namespace

int main(int argc, char** argv) {
    int threads = resolve_threads(0), reps = 3, w = 384, h = 384, leaf = 4;
    std::string kinds = "primary,ao,diffuse";
    std::vector<std::string> meshes;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--threads" && i + 1 < argc)
            threads = std::atoi(argv[++i]);
        else if (a == "--reps" && i + 1 < argc)
            reps = std::atoi(argv[++i]);
        else if (a == "--kinds" && i + 1 < argc)
            kinds = argv[++i];
        else if (a == "--leaf" && i + 1 < argc)
            leaf = std::atoi(argv[++i]);
        else if (a == "--res" && i + 1 < argc)
            std::sscanf(argv[++i], "%dx%d", &w, &h);
        else
            meshes.push_back(a);
    }
    if (meshes.empty()) {
        meshes.push_back("builtin:cornell");
        meshes.push_back("/usr/share/glmark2/models/bunny.obj");
        for (const char* m : {"refined_elephant.off", "bunny00.off", "armadillo.off"})
            meshes.push_back(std::string(RTSIM_SOURCE_DIR) + "/.cache/meshes/cgal/" + m);
    }
    fmt::print(
        "Functional tracer vs Embree {}.{}.{}, {}x{} pixels, best of {}; threads: 1 and {}\n",
        RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH, w, h, reps, threads);
    fmt::print("Ours: the fastest path (counters unused, no step recording).\n\n");

    std::vector<std::string> claims;
    for (const std::string& path : meshes) {
        if (path.rfind("builtin:", 0) != 0 && !std::filesystem::exists(path)) {
            fmt::print("skipping {}: not found (run scripts/setup.sh)\n", path);
            continue;
        }
        const Scene s = load_scene(path);
        fmt::print("== {} ({} triangles)\n", s.name, s.triangle_count());
        EmbreeScene es1(s, 1);
        struct Built {
            std::string name;
            Bvh bvh;
        };
        std::vector<Built> bvhs;
        struct Build {
            BvhBuilder builder;
            int restructure_passes;
            NodeFormat format = NodeFormat::Full;
        };
        for (Build b :
             {Build{BvhBuilder::Sah, 0}, Build{BvhBuilder::Lbvh, 0}, Build{BvhBuilder::Lbvh, 3},
              Build{BvhBuilder::Sah, 0, NodeFormat::Compressed}})
            for (int wd : {2, 4, 8}) {
                BvhBuildOptions o;
                o.builder = b.builder;
                o.restructure_passes = b.restructure_passes;
                o.node_format = b.format;
                o.width = wd;
                o.max_leaf_size = leaf;
                bvhs.push_back({fmt::format("{}{}{} BVH{}", bvh_builder_name(b.builder),
                                            b.restructure_passes ? "+tr" : "",
                                            b.format == NodeFormat::Compressed ? "-q" : "", wd),
                                build_bvh(s, o)});
            }
        fmt::print("build (1 thread): Embree {:.3f} s", es1.build_seconds);
        for (const Built& b : bvhs)
            fmt::print("; {} {:.3f} s ({:.2f}x Embree)", b.name, b.bvh.quality.build_seconds,
                       b.bvh.quality.build_seconds / es1.build_seconds);
        fmt::print("\n");
        EmbreeScene esn(s, threads);
        const Bvh& ref = bvhs[2].bvh;  // SAH BVH8 generates the secondary rays
        fmt::print("{:10} {:>8} | {:>9} {:>9} | {:>13} {:>13} {:>13} | {:>9} {:>9}\n", "rays",
                   "count", "embree 1t", fmt::format("embree {}t", threads), "best ours 1t",
                   "ratio 1t", "bvh", fmt::format("ours {}t", threads),
                   fmt::format("ratio {}t", threads));
        std::stringstream kind_list(kinds);
        for (std::string kind; std::getline(kind_list, kind, ',');) {
            const RaySet rs = make_rays(s, ref, kind.c_str(), w, h);
            uint64_t ce = 0, co = 0;
            const double e1 = embree(es1, rs, 1, reps, &ce);
            const double en = embree(esn, rs, threads, reps, &ce);
            double best = 0;
            std::string best_name;
            const Bvh* best_bvh = nullptr;
            for (const Built& b : bvhs) {
                const double m = ours(b.bvh, rs, 1, reps, &co);
                if (co != ce)
                    fmt::print("  warning: {} {} finds {} hits, Embree {}\n", b.name, kind, co, ce);
                if (m > best) {
                    best = m;
                    best_name = b.name;
                    best_bvh = &b.bvh;
                }
            }
            const double on = ours(*best_bvh, rs, threads, reps, &co);
            fmt::print(
                "{:10} {:8} | {:9.2f} {:9.2f} | {:13.2f} {:12.2f}x {:>13} | {:9.2f} {:8.2f}x\n",
                kind, rs.rays.size(), e1, en, best, best / e1, best_name, on, on / en);
        }

        // Claims, measured: work per ray by width, SAH cost and build time by builder.
        const RaySet diffuse = make_rays(s, ref, "diffuse", w / 2, h / 2);
        const RaySet primary = make_rays(s, ref, "primary", w / 2, h / 2);
        claims.push_back(fmt::format("{} ({} tris)", s.name, s.triangle_count()));
        for (const Built& b : bvhs) {
            uint64_t nodes = 0, boxes = 0, tris = 0;
            for (const RaySet* rs : {&primary, &diffuse})
                for (const Ray& r : rs->rays) {
                    TraceCounters c;
                    trace_ray(b.bvh, r, rs->query, nullptr, &c);
                    nodes += c.nodes;
                    boxes += c.box_tests;
                    tris += c.tri_tests;
                }
            const double n = double(primary.rays.size() + diffuse.rays.size());
            claims.push_back(fmt::format(
                "  {:13} SAH cost {:6.2f}  build {:6.4f} s  nodes/ray {:5.2f}  box tests/ray "
                "{:5.2f}  "
                "tri tests/ray {:4.2f}  children/node {:4.2f}  node bytes {:8}",
                b.name, b.bvh.quality.sah_cost, b.bvh.quality.build_seconds, nodes / n, boxes / n,
                tris / n, b.bvh.quality.mean_children, b.bvh.layout.node_bytes_total()));
        }
        // Packets: lane utilisation of consecutive-ray packets (8x2-pixel strips for 16 primary
        // rays, a whole 8x8 tile for 64), on coherent primary and incoherent diffuse rays, at the
        // full resolution. Rays that miss the scene count as idle lanes.
        const RaySet primary_full = make_rays(s, ref, "primary", w, h);
        const RaySet diffuse_full = make_rays(s, ref, "diffuse", w, h);
        for (const Built& b : bvhs) {
            if (b.name.rfind("sah BVH", 0) != 0) continue;
            std::string row = fmt::format("  {:13} packet lane utilisation:", b.name);
            for (int size : {16, 64})
                for (const RaySet* rs : {&primary_full, &diffuse_full}) {
                    PacketOptions po;
                    po.size = size;
                    PacketStats st;
                    std::vector<Hit> hits(size);
                    for (size_t i = 0; i < rs->rays.size(); i += size)
                        trace_packet(b.bvh, &rs->rays[i],
                                     int(std::min<size_t>(size, rs->rays.size() - i)), rs->query,
                                     hits.data(), po, st);
                    row += fmt::format("  {} x{} {:5.1f}%", rs->kind, size, 100 * st.utilization());
                }
            claims.push_back(row);
        }
        fmt::print("\n");
    }
    fmt::print(
        "Claims, measured (primary + diffuse rays, {}x{}; SAH costs with C_trav = C_isect = 1;\n"
        "+tr: 3 passes of treelet restructuring; -q: compressed nodes, 8-bit quantised child "
        "boxes):\n",
        w / 2, h / 2);
    for (const std::string& c : claims) fmt::print("{}\n", c);
    return 0;
}

// BVH builds against Embree's, side by side at the same thread counts: for each mesh, the time
// to parse it (apart), Embree's build (its default binned-SAH quality) and ours (binned SAH,
// BVH2 and BVH8, full node format, collapsed and laid out as a run uses them), with 1 thread and
// with every host thread; ours is checked to be the same tree at both counts.
//
//     build/bench_build [--threads N] [mesh ...]     (default: the bunny and refined_elephant)
#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <sys/resource.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "support/embree_scene.h"
#include "workloads/bvh.h"
#include "workloads/parallel.h"
#include "workloads/scene.h"

using namespace rtsim;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The same tree: node records, triangle order and leaf blocks byte for byte.
bool same_tree(const Bvh& a, const Bvh& b) {
    if (a.prim_order != b.prim_order || a.leaf_block != b.leaf_block) return false;
    auto same = [](const auto& x, const auto& y) {
        return x.size() == y.size() &&
               std::memcmp(x.data(), y.data(), x.size() * sizeof(x.data()[0])) == 0;
    };
    return same(a.nodes2, b.nodes2) && same(a.nodes4, b.nodes4) && same(a.nodes8, b.nodes8);
}

}  // namespace

int main(int argc, char** argv) {
    int threads = resolve_threads(0);
    std::vector<std::string> meshes;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--threads" && i + 1 < argc)
            threads = std::atoi(argv[++i]);
        else
            meshes.push_back(a);
    }
    if (meshes.empty()) {
        meshes.push_back("/usr/share/glmark2/models/bunny.obj");
        meshes.push_back(std::string(RTSIM_SOURCE_DIR) +
                         "/.cache/meshes/cgal/refined_elephant.off");
    }
    fmt::print(
        "BVH builds: ours (binned SAH) against Embree {}.{}.{} (default build quality), "
        "1 and {} threads; seconds, best of 2\n",
        RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH, threads);
    for (const std::string& path : meshes) {
        if (!std::filesystem::exists(path)) {
            fmt::print("skipping {}: not found (run scripts/setup.sh)\n", path);
            continue;
        }
        auto t0 = std::chrono::steady_clock::now();
        const Scene s = load_scene(path);
        const double parse_s = seconds_since(t0);
        fmt::print("== {} ({} triangles): parsed in {:.2f} s\n", s.name, s.triangle_count(),
                   parse_s);
        for (const int t : {1, threads}) {
            double embree_s = 1e30;
            for (int rep = 0; rep < 2; ++rep)
                embree_s = std::min(embree_s, test::EmbreeScene(s, t).build_seconds);
            fmt::print("  {} thread{}: Embree {:.3f} s", t, t == 1 ? "" : "s", embree_s);
            for (const int width : {2, 8}) {
                BvhBuildOptions o;
                o.width = width;
                o.build_threads = t;
                double ours_s = 1e30;
                Bvh bvh;
                for (int rep = 0; rep < 2; ++rep) {
                    t0 = std::chrono::steady_clock::now();
                    bvh = build_bvh(s, o);
                    ours_s = std::min(ours_s, seconds_since(t0));
                }
                BvhBuildOptions one = o;
                one.build_threads = 1;
                const bool same = t == 1 || same_tree(bvh, build_bvh(s, one));
                fmt::print("; ours BVH{} {:.3f} s ({:.2f}x Embree, SAH cost {:.2f}{})", width,
                           ours_s, ours_s / embree_s, bvh.quality.sah_cost,
                           same ? "" : ", NOT the 1-thread tree");
            }
            fmt::print("\n");
        }
    }
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    fmt::print("peak RSS {:.0f} MiB\n", double(ru.ru_maxrss) / 1024.0);
    return 0;
}

// The numerical stress suite at full size: watertightness on closed Debian meshes on
// every BVH variant, meshes scaled and moved against a double-precision reference, axis-parallel
// and in-plane rays on flat geometry with degenerate triangles, and secondary rays from hit
// points. Prints one line per case with its counts; bench/results/stress_numerics.txt is the last
// recorded output. The same cases at small sizes run in the test command
// (tests/workloads/test_numerics.cpp).
//
//     build/stress_numerics [--rays N] [--meshes a.off,b.off] [--seed S]
#include <fmt/format.h>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "support/numerics_stress.h"
#include "workloads/bvh.h"
#include "workloads/raygen.h"
#include "workloads/scene.h"

using namespace rtsim;
using namespace rtsim::test;

namespace {

const char* const kClosedMeshes[] = {
    "armadillo.off", "bear.off", "bull.off",    "bunny00.off",    "camel.off",
    "cheese.off",    "cow.off",  "dino.off",    "elephant.off",   "fandisk_large.off",
    "homer.off",     "man.off",  "turbine.off", "triceratops.off"};

std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    size_t start = 0;
    while (start <= s.size()) {
        const size_t comma = s.find(',', start);
        out.push_back(s.substr(start, comma - start));
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    return out;
}

void print(const char* category, const std::string& what, const StressTally& t) {
    std::printf("%-12s %-44s %10llu %10llu %7llu %7llu %7llu %7llu\n", category, what.c_str(),
                (unsigned long long)t.rays, (unsigned long long)t.must_hit,
                (unsigned long long)t.misses, (unsigned long long)t.wrong,
                (unsigned long long)t.self_hits, (unsigned long long)t.escapes);
    std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
    uint64_t rays = 20000, seed = 1;
    std::vector<std::string> meshes(std::begin(kClosedMeshes), std::end(kClosedMeshes));
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--rays" && i + 1 < argc) {
            rays = std::strtoull(argv[++i], nullptr, 10);
        } else if (a == "--seed" && i + 1 < argc) {
            seed = std::strtoull(argv[++i], nullptr, 10);
        } else if (a == "--meshes" && i + 1 < argc) {
            meshes = split(argv[++i]);
        } else {
            std::fprintf(stderr, "stress_numerics: unknown argument %s (see the file's header)\n",
                         a.c_str());
            return 2;
        }
    }
    const auto start = std::chrono::steady_clock::now();
    std::printf("# build/stress_numerics --rays %llu --seed %llu\n", (unsigned long long)rays,
                (unsigned long long)seed);
    std::printf("%-12s %-44s %10s %10s %7s %7s %7s %7s\n", "category", "case", "rays", "must-hit",
                "leaks", "wrong", "selfhit", "escape");
    StressTally all;
    for (const std::string& name : meshes) {
        const Scene s = load_scene(std::string(RTSIM_CGAL_MESH_DIR) + "/" + name);
        if (!is_closed(s)) {
            std::fprintf(stderr, "stress_numerics: %s is not a closed mesh\n", name.c_str());
            return 2;
        }
        // Watertightness on every BVH variant.
        StressTally w;
        for (const BvhBuildOptions& o : bvh_variants())
            w.add(watertight(s, build_bvh(s, o), rays / bvh_variants().size() + 1, seed));
        print("watertight", name + fmt::format(" x {} BVH variants", bvh_variants().size()), w);
        all.add(w);
        // Secondary rays at three scales.
        StressTally sec;
        for (double scale : {1e-6, 1.0, 1e6}) {
            const Scene t = transformed(s, scale, 0.0);
            sec.add(secondary(t, build_bvh(t, BvhBuildOptions()), rays / 3 + 1, seed + 1));
        }
        print("secondary", name + " at 1e-6, 1, 1e6", sec);
        all.add(sec);
    }
    // Scales and offsets, inside and outside the documented range, on cow.off (5,804 triangles:
    // the double-precision reference is a brute force over all of them per ray).
    const Scene base = load_scene(std::string(RTSIM_CGAL_MESH_DIR) + "/cow.off");
    const AABB bb = base.bounds();
    const double size = double(length(bb.hi - bb.lo));
    for (double scale : {1e-12, 1e-9, 1e-6, 1e-3, 1.0, 1e3, 1e6, 1e9, 1e12, 1e13, 1e15})
        for (double offset : {0.0, 1e2, 1e3, 1e4, 1e6}) {
            const Scene t = transformed(base, scale / size, offset * scale);
            const Bvh bvh = build_bvh(t, BvhBuildOptions());
            StressTally st = against_double(t, bvh, rays / 100 + 1, seed + 2);
            st.add(watertight(t, bvh, rays / 10 + 1, seed + 3));
            char what[96];
            std::snprintf(what, sizeof what, "cow extent %g, offset %g x extent", scale, offset);
            print("scaled", what, st);
            const bool in_range = scale >= kMinSceneExtent && scale <= kMaxSceneExtent &&
                                  offset <= kMaxOffsetOverExtent;
            if (in_range) all.add(st);
        }
    // Flat axis-aligned geometry, with and without degenerate triangles.
    StressTally flat;
    for (const BvhBuildOptions& o : bvh_variants()) {
        flat.add(axis_aligned(build_bvh(axis_aligned_grid_box(8), o), 8, seed + 4));
        const Scene messy = grid_box_with_degenerates(8);
        flat.add(
            degenerates(messy, build_bvh(messy, o), rays / bvh_variants().size() + 1, seed + 5));
    }
    print("flat", fmt::format("grid box 8x8, degenerates, {} BVH variants", bvh_variants().size()),
          flat);
    all.add(flat);
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    print("total", "in the documented range", all);
    std::printf("# %.1f s; in range: scene extents %g to %g, offsets up to %g x the extent\n", secs,
                double(kMinSceneExtent), double(kMaxSceneExtent), double(kMaxOffsetOverExtent));
    return all.clean() ? 0 : 1;
}

// The numerical stress suite at a size the test command runs in seconds (bench/stress_numerics
// runs it with millions of rays): every case on every BVH variant must have no leak, no answer a
// double-precision check calls wrong, no self-hit and no escape.
#include <gtest/gtest.h>

#include <string>

#include "support/numerics_stress.h"
#include "workloads/bvh.h"
#include "workloads/error.h"
#include "workloads/instances.h"
#include "workloads/raygen.h"
#include "workloads/scene.h"

using namespace rtsim;
using namespace rtsim::test;

namespace {
std::string cgal(const char* name) {
    return std::string(RTSIM_CGAL_MESH_DIR) + "/" + name;
}

void expect_clean(const StressTally& t, const std::string& what) {
    EXPECT_GT(t.rays, 0u) << what;
    EXPECT_EQ(t.misses, 0u) << what << ": leaks of " << t.must_hit << " must-hit rays";
    EXPECT_EQ(t.wrong, 0u) << what << ": answers off the double-precision reference";
    EXPECT_EQ(t.self_hits, 0u) << what;
    EXPECT_EQ(t.escapes, 0u) << what;
}
}  // namespace

TEST(Numerics, ClosedMeshesAreWatertightOnEveryBvhVariant) {
    for (const char* mesh : {"cow.off", "fandisk.off", "cube-meshed.off"}) {
        const Scene s = load_scene(cgal(mesh));
        ASSERT_TRUE(is_closed(s)) << mesh << " is not closed: the test would prove nothing";
        for (const BvhBuildOptions& o : bvh_variants()) {
            const Bvh bvh = build_bvh(s, o);
            expect_clean(watertight(s, bvh, 400, 1), std::string(mesh) + " " + variant_name(o));
        }
    }
}

// The same rays through instances of each mesh in one two-level scene (rotated and non-uniformly
// scaled; mirrored; moved only), each ray carried to world space by its instance's transform:
// no leak across the instance boundary on any BVH variant.
TEST(Numerics, InstancedClosedMeshesAreWatertight) {
    for (const char* mesh : {"cow.off", "fandisk.off", "cube-meshed.off"}) {
        InstancedScene scene;
        scene.name = mesh;
        scene.meshes.push_back(load_scene(cgal(mesh)));
        const Scene& s = scene.meshes[0];
        const float size = length(s.bounds().extent());
        const float c = std::cos(0.7f), sn = std::sin(0.7f);
        Instance turned, mirrored, moved;
        turned.object_to_world.m = {c * 1.5f, 0, sn * 0.4f,  0, 0,        0.8f,
                                    0,        0, -sn * 1.5f, 0, c * 0.4f, 0};
        mirrored.object_to_world.m = {-1, 0, 0, 3 * size, 0, 1, 0, 0, 0, 0, 1, 0};
        moved.object_to_world.m = {1, 0, 0, -3 * size, 0, 1, 0, size, 0, 0, 1, 0};
        scene.instances = {turned, mirrored, moved};
        const Bvh object_bvh = build_bvh(s, BvhBuildOptions());  // finds an interior point
        for (const BvhBuildOptions& o : bvh_variants()) {
            const TwoLevelBvh two = build_two_level(scene, o);
            for (uint32_t k = 0; k < 3; ++k) {
                const Affine3x4& to_world = scene.instances[k].object_to_world;
                const HitTest hits = [&](const Ray& r, HitQuery q) {
                    Ray w = r;
                    w.org = to_world.point(r.org);
                    w.dir = to_world.vector(r.dir);
                    return trace_ray(two, w, q).valid();
                };
                expect_clean(
                    watertight(s, object_bvh, 200, 1 + k, hits),
                    std::string(mesh) + " instance " + std::to_string(k) + " " + variant_name(o));
            }
        }
    }
}

// The documented range (workloads/raygen.h): extents 1e-9 to 1e12, coordinates up to 100
// extents from the origin. (Beyond it, bench/results/stress_numerics.txt shows what goes wrong.)
TEST(Numerics, ScaledAndOffsetMeshesMatchDoublePrecision) {
    const Scene cow = load_scene(cgal("cow.off"));
    const AABB b = cow.bounds();
    const double size = double(length(b.hi - b.lo));
    for (double extent : {double(kMinSceneExtent), 1e-3, 1.0, 1e3, 1e9, double(kMaxSceneExtent)})
        for (double offset : {0.0, 10.0, double(kMaxOffsetOverExtent)}) {
            const Scene s = transformed(cow, extent / size, offset * extent);
            const Bvh bvh = build_bvh(s, BvhBuildOptions());
            const std::string what =
                "extent " + std::to_string(extent) + " offset " + std::to_string(offset) + " x";
            expect_clean(against_double(s, bvh, 150, 2), what);
            expect_clean(watertight(s, bvh, 150, 3), what);
        }
}

TEST(Numerics, AxisParallelAndInPlaneRaysOnFlatGeometry) {
    const Scene box = axis_aligned_grid_box(4);
    ASSERT_TRUE(is_closed(box));
    const Scene messy = grid_box_with_degenerates(4);
    for (const BvhBuildOptions& o : bvh_variants()) {
        expect_clean(axis_aligned(build_bvh(box, o), 4, 4), "grid box " + variant_name(o));
        const Bvh bvh = build_bvh(messy, o);
        expect_clean(degenerates(messy, bvh, 200, 5), "degenerates " + variant_name(o));
    }
}

TEST(Numerics, SecondaryRaysNeitherSelfHitNorEscape) {
    for (const char* mesh : {"cow.off", "fandisk.off"}) {
        const Scene s = load_scene(cgal(mesh));
        for (double scale : {1e-6, 1.0, 1e6}) {
            const Scene t = transformed(s, scale, 0.0);
            const Bvh bvh = build_bvh(t, BvhBuildOptions());
            const StressTally tally = secondary(t, bvh, 500, 6);
            expect_clean(tally, std::string(mesh) + " scale " + std::to_string(scale));
            EXPECT_GT(tally.must_hit, 150u);
        }
    }
}

// Outside the documented range the ray generator says so instead of missing silently: an error
// where every ray would miss (the triangle test's products overflow), a warning where hits lose
// precision.
TEST(Numerics, ScenesOutsideTheRangeGetAnErrorOrAWarning) {
    const Scene cow = load_scene(cgal("cow.off"));
    const AABB b = cow.bounds();
    const double size = double(length(b.hi - b.lo));
    RayGenOptions opt;
    opt.width = opt.height = 4;
    auto generator_messages = [&](double extent, double offset, bool& threw) {
        const Scene s = transformed(cow, extent / size, offset * extent);
        const Bvh bvh = build_bvh(s, BvhBuildOptions());
        testing::internal::CaptureStderr();
        threw = false;
        try {
            RayGenerator gen(s, bvh, opt);
        } catch (const InputError& e) {
            threw = std::string(e.what()).find("above") != std::string::npos;
        }
        return testing::internal::GetCapturedStderr();
    };
    bool threw = false;
    EXPECT_EQ(generator_messages(1.0, 0.0, threw), "");
    EXPECT_FALSE(threw);
    EXPECT_EQ(generator_messages(1e-3, 10.0, threw), "");
    generator_messages(1e13, 0.0, threw);
    EXPECT_TRUE(threw);
    EXPECT_NE(generator_messages(1e-11, 0.0, threw).find("warning: cow.off: scene extent"),
              std::string::npos);
    EXPECT_NE(generator_messages(1.0, 1e5, threw).find("times the scene's extent"),
              std::string::npos);
}

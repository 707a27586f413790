// JSON scene files (workloads/scene_file.h): placements, grids and scatters as hand-computed
// matrices and positions; every bad file one line naming the file and the field.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "support/input_error.h"
#include "support/scratch_dir.h"
#include "workloads/memory_limit.h"
#include "workloads/scene_file.h"

namespace fs = std::filesystem;
using namespace rtsim;

namespace {

std::string write_scene(const std::string& name, const std::string& text) {
    const fs::path p = test::scratch_dir() / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
}

// A one-triangle OFF mesh beside the scene files.
std::string one_triangle() {
    return write_scene("tri.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
}

void expect_near(const Affine3x4& a, const std::array<float, 12>& m) {
    for (size_t i = 0; i < 12; ++i) EXPECT_NEAR(a.m[i], m[i], 1e-6f) << "element " << i;
}

}  // namespace

TEST(SceneFile, PlacementIsTranslateRotateScale) {
    one_triangle();
    const std::string path = write_scene("place.json",
                                         R"({"meshes": {"t": "tri.off"},
            "instances": [{"mesh": "t", "scale": [2, 3, 4], "rotate": [0, 0, 1, 90],
                           "translate": [10, 20, 30], "mask": 5, "opaque": false},
                          {"mesh": "t", "transform": [1, 0, 0, 7, 0, 1, 0, 8, 0, 0, -1, 9]}]})");
    const InstancedScene s = load_scene_file(path);
    ASSERT_EQ(s.meshes.size(), 1u);
    ASSERT_EQ(s.instances.size(), 2u);
    // R(z, 90) = [[0,-1,0],[1,0,0],[0,0,1]]; times diag(2,3,4); then + (10,20,30).
    expect_near(s.instances[0].object_to_world, {0, -3, 0, 10, 2, 0, 0, 20, 0, 0, 4, 30});
    EXPECT_EQ(s.instances[0].mask, 5);
    EXPECT_FALSE(s.instances[0].opaque);
    expect_near(s.instances[1].object_to_world, {1, 0, 0, 7, 0, 1, 0, 8, 0, 0, -1, 9});
    EXPECT_TRUE(s.instances[1].opaque);
    EXPECT_EQ(s.instances[1].mask, 0xff);
    // The vertex (1, 0, 0) of the first instance: (0*1 + 10, 2*1 + 20, 30).
    const Vec3 p = s.instances[0].object_to_world.point(Vec3(1, 0, 0));
    EXPECT_NEAR(p.x, 10, 1e-5);
    EXPECT_NEAR(p.y, 22, 1e-5);
    EXPECT_NEAR(p.z, 30, 1e-5);
    EXPECT_EQ(s.unique_triangle_count(), 1u);
    EXPECT_EQ(s.instanced_triangle_count(), 2u);
}

TEST(SceneFile, GridCopiesAreOffsetAfterThePlacement) {
    one_triangle();
    const InstancedScene s =
        load_scene_file(write_scene("grid.json", R"({"meshes": {"t": "tri.off"},
                         "instances": [{"mesh": "t", "scale": 2,
                                        "grid": {"count": [3, 1, 2], "spacing": [5, 0, 7]}}]})"));
    ASSERT_EQ(s.instances.size(), 6u);
    // x fastest: copy 4 is x = 1, z = 1.
    expect_near(s.instances[4].object_to_world, {2, 0, 0, 5, 0, 2, 0, 0, 0, 0, 2, 7});
    expect_near(s.instances[5].object_to_world, {2, 0, 0, 10, 0, 2, 0, 0, 0, 0, 2, 7});
}

TEST(SceneFile, ScatterIsSeededAndStaysInItsRegion) {
    one_triangle();
    const std::string text = R"({"meshes": {"t": "tri.off"},
        "instances": [{"mesh": "t", "scatter": {"count": 500, "seed": SEED, "min": [-1, 2, -3],
                       "max": [1, 2, 3], "scale": [0.5, 2], "rotate_y": true}}]})";
    auto with_seed = [&](int seed) {
        std::string t = text;
        t.replace(t.find("SEED"), 4, std::to_string(seed));
        return load_scene_file(write_scene("scatter" + std::to_string(seed) + ".json", t));
    };
    const InstancedScene a = with_seed(4), b = with_seed(4), c = with_seed(5);
    ASSERT_EQ(a.instances.size(), 500u);
    bool differs = false;
    for (size_t k = 0; k < 500; ++k) {
        EXPECT_EQ(a.instances[k].object_to_world.m, b.instances[k].object_to_world.m);
        differs |= a.instances[k].object_to_world.m != c.instances[k].object_to_world.m;
        const Affine3x4& m = a.instances[k].object_to_world;
        // The origin lands at the copy's position, inside the region.
        EXPECT_GE(m.at(0, 3), -1.0f);
        EXPECT_LE(m.at(0, 3), 1.0f);
        EXPECT_EQ(m.at(1, 3), 2.0f);
        EXPECT_GE(m.at(2, 3), -3.0f);
        EXPECT_LE(m.at(2, 3), 3.0f);
        // A yaw and a uniform scale: y stays y, and the scale is the column's length.
        const float scale = std::hypot(m.at(0, 0), m.at(2, 0));
        EXPECT_NEAR(m.at(1, 1), scale, 1e-5f);
        EXPECT_GE(scale, 0.5f - 1e-5f);
        EXPECT_LE(scale, 2.0f + 1e-5f);
        EXPECT_NEAR(m.determinant(), double(scale) * scale * scale, 1e-4);
    }
    EXPECT_TRUE(differs);
}

TEST(SceneFile, BadFilesGiveOneLineNamingTheField) {
    one_triangle();
    const std::pair<std::string, std::string> cases[] = {
        {R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "t", "rotatee": [0,1,0,3]}]})",
         "instances[0]: unknown field 'rotatee'"},
        {R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "u"}]})",
         "instances[0].mesh: no mesh named 'u'"},
        {R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "t", "scale": 0}]})",
         "instance 0 has a singular or non-finite transform"},
        {R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "t", "transform": [1, 2],
             "translate": [0, 0, 0]}]})",
         "'transform' and 'translate' both given"},
        {R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "t",
             "grid": {"count": [2, 0, 1], "spacing": [1, 1, 1]}}]})",
         "instances[0].grid.count: expected an integer from 1"},
        {R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "t",
             "scatter": {"count": 3, "min": [1, 0, 0], "max": [0, 0, 0]}}]})",
         "instances[0].scatter: 'min' exceeds 'max'"},
        {R"({"meshes": {"t": "missing.off"}, "instances": [{"mesh": "t"}]})",
         "missing.off: scene file not found"},
        {R"({"meshes": {}, "instances": [{"mesh": "t"}]})", "meshes: expected an object"},
        {R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "t"},)", "not valid JSON"},
        {R"({"meshes": {"t": {"file": "tri.off", "alpha": {"pattern": "stripes"}}},
             "instances": [{"mesh": "t"}]})",
         "meshes.t.alpha.pattern: expected \"triangles\" or \"checker\""},
        {R"({"meshes": {"t": {"file": "tri.off", "alpha": {"pattern": "triangles",
             "keep": 1.5}}}, "instances": [{"mesh": "t"}]})",
         "meshes.t.alpha.keep: expected a fraction from 0 to 1"},
        {R"({"meshes": {"t": {"file": "tri.off", "alpha": {"pattern": "triangles",
             "cells": 4}}}, "instances": [{"mesh": "t"}]})",
         "meshes.t.alpha: unknown field 'cells'"},
        {R"({"meshes": {"t": {"alpha": {"pattern": "checker"}}}, "instances": [{"mesh": "t"}]})",
         "meshes.t.file: expected a mesh file"},
    };
    int k = 0;
    for (const auto& [text, fragment] : cases) {
        const std::string path = write_scene("bad" + std::to_string(k++) + ".json", text);
        const std::string names = fragment.find("missing.off") == 0 ? "missing.off" : path;
        test::expect_input_error([&] { load_scene_file(path); }, names, fragment);
    }
}

TEST(SceneFile, SharedMeshesAreOneBlasWithManyInstances) {
    one_triangle();
    const InstancedScene s = load_scene_file(
        write_scene("shared.json", R"({"meshes": {"t": "tri.off", "c": "builtin:cornell"},
                           "instances": [{"mesh": "t", "grid": {"count": [10, 10, 1],
                                                                "spacing": [2, 2, 0]}},
                                         {"mesh": "c", "translate": [0, 0, -5]}]})"));
    const TwoLevelBvh two = build_two_level(s, BvhBuildOptions());
    ASSERT_EQ(two.blas.size(), 2u);
    EXPECT_EQ(two.blas[0].layout.triangle_count, 1u);
    EXPECT_EQ(two.instances.size(), 101u);
    // One address space: the TLAS's nodes, each BLAS's after it; instance records apart.
    EXPECT_EQ(two.blas_node_offset[0], two.tlas_node_count);
    EXPECT_EQ(two.blas[0].layout.node_base_addr,
              two.tlas.layout.node_base_addr +
                  uint64_t(two.tlas_node_count) * two.tlas.layout.node_size_bytes);
    EXPECT_GE(two.instance_base_addr,
              two.blas[1].layout.node_base_addr + two.blas[1].layout.node_bytes_total());
    EXPECT_GE(two.blas[0].layout.tri_base_addr, two.instance_base_addr + 101 * 64);
    // A ray down onto the triangle of copy (3, 4) hits it, in that instance, at t = 1.
    Ray r;
    r.org = Vec3(6.2f, 8.2f, 1.0f);
    r.dir = Vec3(0, 0, -1);
    const Hit h = trace_ray(two, r, HitQuery::Closest);
    ASSERT_TRUE(h.valid());
    EXPECT_EQ(h.instance, 4u * 10 + 3);
    EXPECT_EQ(h.prim, 0u);
    EXPECT_NEAR(h.t, 1.0f, 1e-6f);
    EXPECT_NEAR(h.u, 0.2f, 1e-5f);
    EXPECT_NEAR(h.v, 0.2f, 1e-5f);
}

TEST(SceneFile, ScenesThatWouldNotFitAreRefusedBeforeTheyAreMade) {
    one_triangle();
    const std::string path =
        write_scene("big.json", R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "t",
                        "grid": {"count": [100, 100, 10], "spacing": [1, 1, 1]}}]})");
    // 100,000 copies at 600 bytes each (60 MB) against a 16 MiB limit.
    ::setenv("RTSIM_MEMORY_LIMIT", "16M", 1);
    test::expect_input_error([&] { load_scene_file(path); }, path,
                             "100000 instances at 600 bytes), above the 0.0 GiB limit "
                             "(RTSIM_MEMORY_LIMIT)");
    EXPECT_EQ(memory_limit_bytes(), uint64_t(16) << 20);
    ::setenv("RTSIM_MEMORY_LIMIT", "2GiB", 1);
    EXPECT_EQ(memory_limit_bytes(), uint64_t(2) << 30);
    EXPECT_EQ(load_scene_file(path).instances.size(), 100000u);
    ::setenv("RTSIM_MEMORY_LIMIT", "12Q", 1);
    test::expect_input_error([&] { memory_limit_bytes(); }, "RTSIM_MEMORY_LIMIT", "got '12Q'");
    ::unsetenv("RTSIM_MEMORY_LIMIT");
}

// A mesh with an alpha mask makes its instances non-opaque unless they say otherwise; a mesh
// without one keeps them opaque unless they say otherwise.
TEST(SceneFile, AlphaMasksMakeTheirMeshesInstancesNonOpaque) {
    one_triangle();
    // The same scene with the leaf's checker of `cells` squares.
    auto scene = [](int cells) {
        return load_scene_file(write_scene(
            "alpha" + std::to_string(cells) + ".json",
            R"({"meshes": {"leaf": {"file": "tri.off", "alpha": {"pattern": "checker", "cells": )" +
                std::to_string(cells) + R"(}},
            "hole": {"file": "tri.off", "alpha": {"pattern": "triangles", "keep": 0.25,
                                                  "seed": 9}},
            "plain": "tri.off"},
        "instances": [{"mesh": "leaf"}, {"mesh": "leaf", "opaque": true}, {"mesh": "hole"},
                      {"mesh": "plain"}, {"mesh": "plain", "opaque": false}]})"));
    };
    const InstancedScene s = scene(8);
    ASSERT_EQ(s.alpha.size(), 3u);
    EXPECT_EQ(s.alpha[0].pattern, AlphaPattern::Checker);
    EXPECT_EQ(s.alpha[0].cells, 8u);
    EXPECT_EQ(s.alpha[1].pattern, AlphaPattern::Triangles);
    EXPECT_EQ(s.alpha[1].keep, 0.25);
    EXPECT_EQ(s.alpha[1].seed, 9u);
    EXPECT_EQ(s.alpha[2].pattern, AlphaPattern::None);
    const bool opaque[] = {false, true, false, true, false};
    for (size_t k = 0; k < 5; ++k) EXPECT_EQ(s.instances[k].opaque, opaque[k]) << k;
    // The masks are part of the scene's content (BVH caches, traces): another cell count is
    // another scene.
    EXPECT_NE(s.content_hash(), scene(4).content_hash());
}

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "workloads/bvh.h"
#include "workloads/scene.h"

using namespace rtsim;

namespace {

// Checks the structural invariants every BVH must hold, returns the number of leaves seen.
void check_invariants(const Scene& scene, const Bvh& bvh, const BvhBuildOptions& opt) {
    std::vector<int> seen(scene.triangle_count(), 0);
    std::vector<int> mem_seen(bvh.layout.inner_node_count, 0);
    struct Item {
        uint32_t node, depth;
    };
    std::vector<Item> stack = {{0, 0}};
    size_t visited = 0;
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        ASSERT_LT(it.node, bvh.nodes.size());
        ASSERT_LT(it.depth, kMaxBvhDepth);
        const BvhNode& n = bvh.nodes[it.node];
        ++visited;
        if (n.is_leaf()) {
            ASSERT_LE(n.prim_count, uint32_t(std::max(opt.max_leaf_size, 1)));
            for (uint32_t i = 0; i < n.prim_count; ++i) {
                const uint32_t prim = bvh.prim_order.at(n.a + i);
                ASSERT_LT(prim, scene.triangle_count());
                seen[prim]++;
                ASSERT_TRUE(n.box.contains(scene.triangle_bounds(prim)))
                    << "leaf box misses its triangle";
            }
        } else {
            ASSERT_LT(n.mem_index, bvh.layout.inner_node_count);
            mem_seen[n.mem_index]++;
            for (uint32_t c : {n.a, n.b}) {
                ASSERT_TRUE(n.box.contains(bvh.nodes[c].box)) << "child box outside parent";
                stack.push_back({c, it.depth + 1});
            }
        }
    }
    EXPECT_EQ(visited, bvh.nodes.size()) << "unreachable nodes";
    for (size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i], 1) << "primitive " << i;
    for (size_t i = 0; i < mem_seen.size(); ++i) ASSERT_EQ(mem_seen[i], 1) << "layout record " << i;
    // Layout: triangles start after the node records, page-aligned.
    EXPECT_GE(bvh.layout.tri_base_addr, bvh.layout.node_base_addr + bvh.layout.node_bytes_total());
    EXPECT_EQ(bvh.layout.tri_base_addr % 4096, 0u);
}

}  // namespace

TEST(Bvh, InvariantsOnBuiltinScenes) {
    for (const std::string& name : builtin_scene_names()) {
        Scene s = load_scene("builtin:" + name);
        for (int leaf : {1, 4, 8}) {
            BvhBuildOptions opt;
            opt.max_leaf_size = leaf;
            Bvh bvh = build_bvh_sah(s, opt, BvhLayout());
            SCOPED_TRACE(name + " leaf " + std::to_string(leaf));
            check_invariants(s, bvh, opt);
        }
    }
}

TEST(Bvh, InvariantsOnBunny) {
    ASSERT_TRUE(std::filesystem::exists(RTSIM_BUNNY_OBJ)) << "run scripts/setup.sh";
    Scene s = load_scene(RTSIM_BUNNY_OBJ);
    BvhBuildOptions opt;
    Bvh bvh = build_bvh_sah(s, opt, BvhLayout());
    check_invariants(s, bvh, opt);
    // SAH cost of a sane BVH over ~70k triangles is tens, not thousands.
    EXPECT_LT(bvh.quality.sah_cost, 100.0);
    EXPECT_GT(bvh.quality.sah_cost, 1.0);
}

TEST(Bvh, CoincidentTrianglesStillGiveBoundedLeaves) {
    Scene s;
    s.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (int i = 0; i < 1000; ++i) s.triangles.push_back({0, 1, 2});
    BvhBuildOptions opt;
    Bvh bvh = build_bvh_sah(s, opt, BvhLayout());
    check_invariants(s, bvh, opt);
}

TEST(Bvh, PathologicalSpacingStaysWithinDepthBound) {
    // Triangles at exponentially growing distances drive SAH towards a chain.
    Scene s;
    for (int i = 0; i < 2000; ++i) {
        const float x = std::ldexp(1.0f, i % 120 - 60) * (1 + i / 120);
        const auto b = static_cast<uint32_t>(s.vertices.size());
        s.vertices.insert(s.vertices.end(), {{x, 0, 0}, {x * 1.01f, 0, 0}, {x, x * 0.01f, 0}});
        s.triangles.push_back({b, b + 1, b + 2});
    }
    BvhBuildOptions opt;
    Bvh bvh = build_bvh_sah(s, opt, BvhLayout());
    check_invariants(s, bvh, opt);
    EXPECT_LT(bvh.quality.max_depth, kMaxBvhDepth);
}

TEST(Bvh, QualityReportIsConsistent) {
    Scene s = load_scene("builtin:sphere");
    Bvh bvh = build_bvh_sah(s, BvhBuildOptions(), BvhLayout());
    const BvhQuality& q = bvh.quality;
    EXPECT_EQ(q.node_count, bvh.nodes.size());
    EXPECT_EQ(q.inner_count + q.leaf_count, q.node_count);
    EXPECT_EQ(q.leaf_count, q.inner_count + 1);  // a full binary tree
    EXPECT_NEAR(q.mean_leaf_size * q.leaf_count, double(s.triangle_count()), 1e-6);
    EXPECT_EQ(q.bytes, uint64_t(q.inner_count) * 64 + uint64_t(s.triangle_count()) * 48);
}

TEST(Bvh, MoreBucketsNeverMuchWorse) {
    // Binned SAH with 32 buckets should find splits at least about as good as with 4.
    Scene s = load_scene("builtin:cornell");
    BvhBuildOptions few, many;
    few.sah_buckets = 4;
    many.sah_buckets = 32;
    const double c_few = build_bvh_sah(s, few, BvhLayout()).quality.sah_cost;
    const double c_many = build_bvh_sah(s, many, BvhLayout()).quality.sah_cost;
    EXPECT_LT(c_many, c_few * 1.02);
}

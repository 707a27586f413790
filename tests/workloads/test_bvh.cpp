#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "workloads/bvh.h"
#include "workloads/error.h"
#include "workloads/scene.h"

using namespace rtsim;

namespace {

// Every builder at every width, and compressed nodes.
struct Variant {
    BvhBuilder builder;
    int width;
    NodeFormat format = NodeFormat::Full;
};
const Variant kVariants[] = {{BvhBuilder::Sah, 2},
                             {BvhBuilder::Sah, 4},
                             {BvhBuilder::Sah, 8},
                             {BvhBuilder::Lbvh, 2},
                             {BvhBuilder::Lbvh, 4},
                             {BvhBuilder::Lbvh, 8},
                             {BvhBuilder::Sah, 2, NodeFormat::Compressed},
                             {BvhBuilder::Sah, 4, NodeFormat::Compressed},
                             {BvhBuilder::Sah, 8, NodeFormat::Compressed}};

BvhBuildOptions options(Variant v, int leaf = 4) {
    BvhBuildOptions o;
    o.builder = v.builder;
    o.width = v.width;
    o.node_format = v.format;
    o.max_leaf_size = leaf;
    return o;
}

// The structural invariants every BVH must hold. Returns the bounds of the geometry below
// `node`; every child box must contain the geometry below it. Full-precision boxes also nest
// (a child box inside its parent's); compressed boxes are rounded outwards on each node's own
// grid, so they need not.
template <int W>
AABB check_node(const Scene& scene, const Bvh& bvh, uint32_t node, uint32_t depth,
                const AABB& parent_box, std::vector<int>& seen, std::vector<int>& reached) {
    const auto& nodes = bvh.nodes<W>();
    AABB content;
    EXPECT_LT(node, nodes.size());
    EXPECT_LT(depth, kMaxBvhDepth);
    if (node >= nodes.size() || depth >= kMaxBvhDepth) return content;
    reached[node]++;
    const WideNode<W>& n = nodes[node];
    EXPECT_GE(n.num, node == 0 ? 1 : 2);
    EXPECT_LE(n.num, W);
    const bool full = bvh.options.node_format == NodeFormat::Full;
    for (int l = 0; l < n.num; ++l) {
        const AABB b = n.box(l);
        if (full) {
            EXPECT_TRUE(parent_box.contains(b)) << "child box outside parent, node " << node;
        }
        AABB below;
        if (n.count[l]) {
            EXPECT_LE(n.count[l], bvh.options.max_leaf_size);
            for (uint32_t i = 0; i < n.count[l]; ++i) {
                const uint32_t slot = n.child[l] + i;
                const uint32_t prim = bvh.prim_order.at(slot);
                EXPECT_LT(prim, scene.triangle_count());
                if (prim >= scene.triangle_count()) continue;
                seen[prim]++;
                below.grow(scene.triangle_bounds(prim));
                for (int c = 0; c < 3; ++c) EXPECT_EQ(bvh.tri_verts[slot][c].x, scene.v(prim, c).x);
            }
        } else {
            EXPECT_GT(n.child[l], node) << "records are in depth-first order";
            below = check_node<W>(scene, bvh, n.child[l], depth + 1, b, seen, reached);
        }
        EXPECT_TRUE(b.contains(below)) << "child box misses geometry below it, node " << node;
        content.grow(below);
    }
    return content;
}

template <int W>
void check_wide(const Scene& scene, const Bvh& bvh) {
    ASSERT_EQ(bvh.nodes<W>().size(), bvh.layout.inner_node_count);
    std::vector<int> seen(scene.triangle_count(), 0), reached(bvh.nodes<W>().size(), 0);
    const AABB content = check_node<W>(scene, bvh, 0, 0, bvh.bounds(), seen, reached);
    EXPECT_TRUE(bvh.bounds().contains(content));
    for (size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i], 1) << "primitive " << i;
    for (size_t i = 0; i < reached.size(); ++i) ASSERT_EQ(reached[i], 1) << "record " << i;
    // Layout: stated node size; triangles start after the node records, page-aligned.
    EXPECT_EQ(bvh.layout.node_size_bytes, bvh.options.node_format == NodeFormat::Full
                                              ? default_node_size_bytes(W)
                                              : compressed_node_size_bytes(W));
    EXPECT_GE(bvh.layout.tri_base_addr, bvh.layout.node_base_addr + bvh.layout.node_bytes_total());
    EXPECT_EQ(bvh.layout.tri_base_addr % 4096, 0u);
}

void check_invariants(const Scene& scene, const Bvh& bvh) {
    switch (bvh.width()) {
        case 2:
            return check_wide<2>(scene, bvh);
        case 4:
            return check_wide<4>(scene, bvh);
        default:
            return check_wide<8>(scene, bvh);
    }
}

std::string name(Variant v) {
    return std::string(bvh_builder_name(v.builder)) + " BVH" + std::to_string(v.width);
}

}  // namespace

TEST(Bvh, InvariantsOnBuiltinScenesForEveryBuilderAndWidth) {
    for (const std::string& scene_name : builtin_scene_names()) {
        Scene s = load_scene("builtin:" + scene_name);
        for (Variant v : kVariants)
            for (int leaf : {1, 4, 8}) {
                SCOPED_TRACE(scene_name + " " + name(v) + " leaf " + std::to_string(leaf));
                check_invariants(s, build_bvh(s, options(v, leaf)));
            }
    }
}

TEST(Bvh, InvariantsOnBunny) {
    ASSERT_TRUE(std::filesystem::exists(RTSIM_BUNNY_OBJ)) << "run scripts/setup.sh";
    Scene s = load_scene(RTSIM_BUNNY_OBJ);
    for (Variant v : kVariants) {
        SCOPED_TRACE(name(v));
        Bvh bvh = build_bvh(s, options(v));
        check_invariants(s, bvh);
        // SAH cost of a sane BVH over ~70k triangles is tens, not thousands.
        EXPECT_LT(bvh.quality.sah_cost, 100.0);
        EXPECT_GT(bvh.quality.sah_cost, 1.0);
    }
}

TEST(Bvh, CoincidentTrianglesStillGiveBoundedLeaves) {
    Scene s;
    s.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (int i = 0; i < 1000; ++i) s.triangles.push_back({0, 1, 2});
    for (Variant v : kVariants) {
        SCOPED_TRACE(name(v));
        check_invariants(s, build_bvh(s, options(v)));
    }
}

TEST(Bvh, SingleTriangleAndTinyScenes) {
    Scene s;
    s.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 2, 2}};
    s.triangles = {{0, 1, 2}};
    for (Variant v : kVariants) {
        Bvh one = build_bvh(s, options(v));
        check_invariants(s, one);
        EXPECT_EQ(one.layout.inner_node_count, 1u);  // a root record holding the single leaf
    }
    s.triangles.push_back({1, 2, 3});
    for (Variant v : kVariants) check_invariants(s, build_bvh(s, options(v, 1)));
    EXPECT_THROW(build_bvh(Scene(), BvhBuildOptions()), InputError);
    BvhBuildOptions bad;
    bad.width = 3;
    EXPECT_THROW(build_bvh(s, bad), InputError);
}

TEST(Bvh, PathologicalSpacingStaysWithinDepthBound) {
    // Triangles at exponentially growing distances drive SAH towards a chain.
    Scene s;
    for (int i = 0; i < 2000; ++i) {
        const float x = std::ldexp(1.0f, i % 120 - 60) * (1 + i / 120);
        const auto b = static_cast<uint32_t>(s.vertices.size());
        for (const Vec3& v : {Vec3(x, 0, 0), Vec3(x * 1.01f, 0, 0), Vec3(x, x * 0.01f, 0)})
            s.vertices.push_back(v);
        s.triangles.push_back({b, b + 1, b + 2});
    }
    for (Variant v : kVariants) {
        SCOPED_TRACE(name(v));
        Bvh bvh = build_bvh(s, options(v));
        check_invariants(s, bvh);
        EXPECT_LT(bvh.quality.max_depth, kMaxBvhDepth);
    }
}

TEST(Bvh, QualityReportIsConsistent) {
    Scene s = load_scene("builtin:sphere");
    for (Variant v : kVariants) {
        SCOPED_TRACE(name(v));
        Bvh bvh = build_bvh(s, options(v));
        const BvhQuality& q = bvh.quality;
        EXPECT_EQ(q.inner_count, bvh.layout.inner_node_count);
        EXPECT_EQ(q.inner_count + q.leaf_count, q.node_count);
        if (v.width == 2) {
            EXPECT_EQ(q.leaf_count, q.inner_count + 1);  // a full binary tree
        }
        EXPECT_NEAR(q.mean_leaf_size * q.leaf_count, double(s.triangle_count()), 1e-6);
        EXPECT_EQ(q.bytes, uint64_t(q.inner_count) * bvh.layout.node_size_bytes +
                               uint64_t(s.triangle_count()) * 48);
        EXPECT_GT(q.build_seconds, 0.0);
    }
}

TEST(Bvh, WiderTreesHaveFewerNodesAndLowerTraversalCost) {
    Scene s = load_scene("builtin:cornell");
    const Bvh b2 = build_bvh(s, options({BvhBuilder::Sah, 2}));
    const Bvh b4 = build_bvh(s, options({BvhBuilder::Sah, 4}));
    const Bvh b8 = build_bvh(s, options({BvhBuilder::Sah, 8}));
    // Collapsing keeps the leaves and removes inner nodes. Greedy collapsing cannot open leaves,
    // so a binary node over two leaves stays a 2-child node and BVH8 nodes are not all full.
    EXPECT_EQ(b2.quality.leaf_count, b4.quality.leaf_count);
    EXPECT_EQ(b2.quality.leaf_count, b8.quality.leaf_count);
    EXPECT_LT(b4.quality.inner_count * 2, b2.quality.inner_count);
    EXPECT_LT(b8.quality.inner_count, b4.quality.inner_count);
    EXPECT_DOUBLE_EQ(b2.quality.mean_children, 2.0);
    EXPECT_GT(b4.quality.mean_children, 3.0);
    EXPECT_GT(b8.quality.mean_children, b4.quality.mean_children);
    EXPECT_LT(b4.quality.sah_cost, b2.quality.sah_cost);
    EXPECT_LT(b8.quality.sah_cost, b4.quality.sah_cost);
    EXPECT_LT(b8.quality.max_depth, b2.quality.max_depth);
}

TEST(Bvh, MortonBuildIsWorseThanSah) {
    Scene s = load_scene("builtin:cornell");
    const Bvh sah = build_bvh(s, options({BvhBuilder::Sah, 2}));
    const Bvh lbvh = build_bvh(s, options({BvhBuilder::Lbvh, 2}));
    EXPECT_GT(lbvh.quality.sah_cost, sah.quality.sah_cost * 1.05);
}

TEST(Bvh, MoreBucketsNeverMuchWorse) {
    // Binned SAH with 32 buckets should find splits at least about as good as with 4.
    Scene s = load_scene("builtin:cornell");
    BvhBuildOptions few, many;
    few.sah_buckets = 4;
    many.sah_buckets = 32;
    EXPECT_LT(build_bvh(s, many).quality.sah_cost, build_bvh(s, few).quality.sah_cost * 1.02);
}

TEST(Bvh, BinarySahCostMatchesCollapsedBvh2) {
    Scene s = load_scene("builtin:cornell");
    BvhBuildOptions o;
    EXPECT_NEAR(binary_sah_cost(build_binary_sah(s, o), o), build_bvh(s, o).quality.sah_cost, 1e-6);
}

TEST(Bvh, BuilderNames) {
    EXPECT_EQ(parse_bvh_builder("lbvh", "x"), BvhBuilder::Lbvh);
    EXPECT_THROW(parse_bvh_builder("median", "x"), InputError);
}

TEST(Bvh, TreeletRestructuringLowersSahCostAndKeepsInvariants) {
    Scene s = load_scene("builtin:cornell");
    for (BvhBuilder b : {BvhBuilder::Sah, BvhBuilder::Lbvh}) {
        BvhBuildOptions o;
        o.builder = b;
        BinaryBvh bin = b == BvhBuilder::Sah ? build_binary_sah(s, o) : build_binary_lbvh(s, o);
        const double before = binary_sah_cost(bin, o);
        const int rebuilt = restructure_treelets(bin, o, 2);
        const double after = binary_sah_cost(bin, o);
        EXPECT_GT(rebuilt, 0) << bvh_builder_name(b);
        EXPECT_LT(after, before) << bvh_builder_name(b);
        for (int w : {2, 4, 8}) {
            o.width = w;
            o.restructure_passes = 2;
            SCOPED_TRACE(std::string(bvh_builder_name(b)) + " BVH" + std::to_string(w));
            const Bvh bvh = build_bvh(s, o);
            check_invariants(s, bvh);
            if (w == 2) {
                EXPECT_NEAR(bvh.quality.sah_cost, after, 1e-3 * after);
            }
        }
    }
}

TEST(Bvh, RestructuringClosesMostOfTheMortonGap) {
    ASSERT_TRUE(std::filesystem::exists(RTSIM_BUNNY_OBJ));
    Scene s = load_scene(RTSIM_BUNNY_OBJ);
    BvhBuildOptions o;
    const double sah = build_bvh(s, o).quality.sah_cost;
    o.builder = BvhBuilder::Lbvh;
    const double lbvh = build_bvh(s, o).quality.sah_cost;
    o.restructure_passes = 3;
    const double fixed = build_bvh(s, o).quality.sah_cost;
    std::printf("SAH %.2f, LBVH %.2f, LBVH + 3 restructuring passes %.2f\n", sah, lbvh, fixed);
    EXPECT_GT(lbvh, sah);
    EXPECT_LT(fixed - sah, 0.5 * (lbvh - sah));  // at least half of the gap closed
}

TEST(Bvh, CompressedNodesAreSmallerAndConservative) {
    EXPECT_EQ(compressed_node_size_bytes(8), 80u);  // Ylitie et al.'s 80-byte BVH8 node
    EXPECT_EQ(compressed_node_size_bytes(4), 64u);
    EXPECT_EQ(default_node_size_bytes(8), 256u);
    Scene s = load_scene("builtin:cornell");
    BvhBuildOptions full, comp;
    full.width = comp.width = 8;
    comp.node_format = NodeFormat::Compressed;
    const Bvh a = build_bvh(s, full), b = build_bvh(s, comp);
    EXPECT_EQ(a.quality.inner_count, b.quality.inner_count);  // same topology
    EXPECT_LT(b.layout.node_bytes_total() * 3, a.layout.node_bytes_total());
    // Quantised boxes only grow, so the SAH cost can only rise, and not by much.
    EXPECT_GE(b.quality.sah_cost, a.quality.sah_cost);
    EXPECT_LT(b.quality.sah_cost, a.quality.sah_cost * 1.15);
}

// The SAH build hands large subtrees to threads and splices them back in the serial numbering:
// the tree is the same, node for node and triangle for triangle, at any thread count. Four
// copies of the bunny (279k triangles) make every split near the root large enough to go to a
// thread.
TEST(Bvh, SahBuildIsTheSameTreeAtAnyThreadCount) {
    const Scene bunny = load_scene(RTSIM_BUNNY_OBJ);
    Scene s;
    // Eight bunnies: 557k triangles, enough for the root's binning to run on every thread.
    s.name = "eight bunnies";
    for (int k = 0; k < 8; ++k) {
        const auto base = uint32_t(s.vertices.size());
        for (const Vec3& v : bunny.vertices) s.vertices.push_back(v + Vec3(0.3f * float(k), 0, 0));
        for (const auto& t : bunny.triangles)
            s.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
    }
    for (const int width : {2, 8}) {
        BvhBuildOptions o;
        o.width = width;
        o.build_threads = 1;
        const Bvh one = build_bvh(s, o);
        for (const int threads : {2, 3, 8}) {
            o.build_threads = threads;
            const Bvh many = build_bvh(s, o);
            EXPECT_EQ(many.prim_order, one.prim_order) << threads;
            auto same = [&](const auto& a, const auto& b) {
                ASSERT_EQ(a.size(), b.size()) << threads;
                EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(a.data()[0])), 0)
                    << threads;
            };
            if (width == 2)
                same(one.nodes2, many.nodes2);
            else
                same(one.nodes8, many.nodes8);
        }
    }
}

// The on-disk BVH cache: a hit gives the very tree a build gives (every array compared), and an
// entry that is damaged, truncated, of another build or of another scene is rebuilt, never used.
#include <gtest/gtest.h>
#include <xxhash.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "support/input_error.h"
#include "support/scratch_dir.h"
#include "workloads/bvh_cache.h"
#include "workloads/tracer.h"

using namespace rtsim;
namespace fs = std::filesystem;

namespace {

template <class A>
bool same_bytes(const A& a, const A& b) {
    return a.size() == b.size() &&
           (a.empty() ||
            std::memcmp(a.data(), b.data(), a.size() * sizeof(typename A::value_type)) == 0);
}

void expect_same_tree(const Bvh& a, const Bvh& b) {
    EXPECT_TRUE(same_bytes(a.nodes2, b.nodes2));
    EXPECT_TRUE(same_bytes(a.nodes4, b.nodes4));
    EXPECT_TRUE(same_bytes(a.nodes8, b.nodes8));
    EXPECT_TRUE(same_bytes(a.prim_order, b.prim_order));
    EXPECT_TRUE(same_bytes(a.tri_verts, b.tri_verts));
    EXPECT_TRUE(same_bytes(a.tri4, b.tri4));
    EXPECT_TRUE(same_bytes(a.leaf_block, b.leaf_block));
    EXPECT_EQ(a.layout.node_base_addr, b.layout.node_base_addr);
    EXPECT_EQ(a.layout.node_size_bytes, b.layout.node_size_bytes);
    EXPECT_EQ(a.layout.tri_base_addr, b.layout.tri_base_addr);
    EXPECT_EQ(a.layout.inner_node_count, b.layout.inner_node_count);
    EXPECT_EQ(a.layout.treelet_node_start, b.layout.treelet_node_start);
    EXPECT_EQ(a.layout.treelet_tri_start, b.layout.treelet_tri_start);
    EXPECT_EQ(a.quality.sah_cost, b.quality.sah_cost);
    for (uint32_t n = 0; n < a.layout.inner_node_count; ++n)
        ASSERT_EQ(a.layout.node_treelet(n), b.layout.node_treelet(n));
    // And it traces the same.
    Ray r;
    r.org = Vec3(0.1f, 1.0f, 5.0f);
    r.dir = normalize(Vec3(-0.05f, -0.1f, -1.0f));
    TraceCounters ca, cb;
    const Hit ha = trace_ray(a, r, HitQuery::Closest, nullptr, &ca);
    const Hit hb = trace_ray(b, r, HitQuery::Closest, nullptr, &cb);
    EXPECT_EQ(ha.t, hb.t);
    EXPECT_EQ(ha.prim, hb.prim);
    EXPECT_EQ(ca.nodes, cb.nodes);
}

fs::path fresh_dir(const char* name) {
    const fs::path d = test::scratch_dir() / name;
    fs::remove_all(d);
    return d;
}

}  // namespace

TEST(BvhCache, AHitIsTheTreeABuildGives) {
    const Scene s = make_builtin_scene("cornell");
    const std::string dir = fresh_dir("bvh_cache_hit").string();
    for (int width : {2, 4, 8})
        for (uint32_t treelet_bytes : {0u, 8192u}) {
            BvhBuildOptions o;
            o.width = width;
            o.treelet_bytes = treelet_bytes;
            o.node_format = width == 8 ? NodeFormat::Compressed : NodeFormat::Full;
            const Bvh built = build_bvh(s, o);
            BvhCacheStatus first, second;
            const Bvh a = build_bvh_cached(s, o, BvhLayout(), dir, &first);
            const Bvh b = build_bvh_cached(s, o, BvhLayout(), dir, &second);
            EXPECT_EQ(first.outcome, BvhCacheOutcome::Built);
            EXPECT_EQ(second.outcome, BvhCacheOutcome::Hit) << second.why;
            EXPECT_EQ(first.path, second.path);
            expect_same_tree(built, a);
            expect_same_tree(built, b);
            // A hit maps the entry's arrays rather than copying them, aligned for their records.
            EXPECT_FALSE(a.tri4.is_view());
            EXPECT_TRUE(b.tri4.is_view());
            EXPECT_TRUE(b.prim_order.is_view());
            EXPECT_EQ(reinterpret_cast<uintptr_t>(b.tri4.data()) % alignof(Tri4), 0u);
        }
    // The box datapath is not part of the tree: the same entry serves it, with its own options.
    BvhBuildOptions o;
    o.box_mantissa_bits = 10;
    BvhCacheStatus st;
    const Bvh r = build_bvh_cached(s, o, BvhLayout(), dir, &st);
    EXPECT_EQ(st.outcome, BvhCacheOutcome::Hit);
    EXPECT_EQ(r.options.box_mantissa_bits, 10);
    // A content hash known beforehand (the mesh cache's) finds the same entry.
    BvhCacheStatus given;
    build_bvh_cached(s, o, BvhLayout(), dir, &given, s.content_hash());
    EXPECT_EQ(given.outcome, BvhCacheOutcome::Hit);
    EXPECT_EQ(given.path, st.path);
    EXPECT_EQ(given.scene_hash, st.scene_hash);
}

TEST(BvhCache, KeysSeparateScenesSettingsAndLayouts) {
    const Scene s = make_builtin_scene("cornell");
    Scene moved = s;
    moved.vertices.mutable_at(0).x += 1e-3f;
    BvhBuildOptions o;
    const uint64_t k = bvh_cache_key(s, o, BvhLayout());
    EXPECT_EQ(k, bvh_cache_key(s, o, BvhLayout()));
    EXPECT_NE(k, bvh_cache_key(moved, o, BvhLayout()));
    BvhBuildOptions lbvh = o;
    lbvh.builder = BvhBuilder::Lbvh;
    EXPECT_NE(k, bvh_cache_key(s, lbvh, BvhLayout()));
    BvhBuildOptions leaf = o;
    leaf.max_leaf_size = 2;
    EXPECT_NE(k, bvh_cache_key(s, leaf, BvhLayout()));
    BvhLayout big;
    big.node_size_bytes = 256;
    EXPECT_NE(k, bvh_cache_key(s, o, big));
    BvhBuildOptions datapath = o;
    datapath.box_mantissa_bits = 7;
    EXPECT_EQ(k, bvh_cache_key(s, datapath, BvhLayout()));
}

TEST(BvhCache, DamagedOrForeignEntriesAreRebuiltNeverUsed) {
    const Scene s = make_builtin_scene("sphere");
    BvhBuildOptions o;
    o.width = 4;
    const Bvh built = build_bvh(s, o);
    const std::string dir = fresh_dir("bvh_cache_damage").string();
    BvhCacheStatus st;
    build_bvh_cached(s, o, BvhLayout(), dir, &st);
    ASSERT_EQ(st.outcome, BvhCacheOutcome::Built);
    const std::string path = st.path;
    std::string good;
    {
        std::ifstream in(path, std::ios::binary);
        good.assign(std::istreambuf_iterator<char>(in), {});
    }
    ASSERT_GT(good.size(), 1000u);
    auto write = [&](const std::string& bytes) {
        std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    };
    struct Case {
        const char* what;
        std::string bytes;
        const char* why;
    };
    std::string flipped = good;
    flipped[good.size() / 2] ^= 0x10;
    std::string other_version = good;
    other_version[8] ^= 1;  // the format version follows the 8-byte magic
    // The same, with its checksum made right again: a sound entry of another format version.
    std::string older = other_version;
    const uint64_t sum = XXH3_64bits(older.data(), older.size() - 8);
    std::memcpy(&older[older.size() - 8], &sum, 8);
    // An entry of another build under this key's name (a copied or renamed file).
    BvhBuildOptions o8 = o;
    o8.width = 8;
    const std::string other_dir = fresh_dir("bvh_cache_other").string();
    BvhCacheStatus ost;
    build_bvh_cached(s, o8, BvhLayout(), other_dir, &ost);
    std::string foreign;
    {
        std::ifstream in(ost.path, std::ios::binary);
        foreign.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::vector<Case> cases = {
        {"bit flip", flipped, "checksum"},
        {"truncated", good.substr(0, good.size() / 3), "checksum"},
        {"empty", "", "not a BVH cache entry"},
        {"text", "hello", "not a BVH cache entry"},
        {"damaged version", other_version, "checksum"},
        {"older format", older, "older entry format"},
        {"another build's entry", foreign, "key"},
    };
    for (const Case& c : cases) {
        write(c.bytes);
        BvhCacheStatus r;
        const Bvh b = build_bvh_cached(s, o, BvhLayout(), dir, &r);
        EXPECT_EQ(r.outcome, BvhCacheOutcome::Rebuilt) << c.what;
        EXPECT_NE(r.why.find(c.why), std::string::npos) << c.what << ": " << r.why;
        expect_same_tree(built, b);
        // The rebuilt entry replaced the bad one.
        BvhCacheStatus again;
        build_bvh_cached(s, o, BvhLayout(), dir, &again);
        EXPECT_EQ(again.outcome, BvhCacheOutcome::Hit) << c.what;
    }
}

TEST(BvhCache, NoFolderMeansNoCache) {
    BvhCacheStatus st;
    build_bvh_cached(make_builtin_scene("sphere"), BvhBuildOptions(), BvhLayout(), "", &st);
    EXPECT_EQ(st.outcome, BvhCacheOutcome::Off);
    EXPECT_TRUE(st.path.empty());
}

// A build is what needs memory: a scene that would not fit is refused before it is built,
// whether the cache is off or misses; a hit needs no build and is served.
TEST(BvhCache, BuildsThatWouldNotFitAreRefusedWithOrWithoutTheCache) {
    const Scene s = make_builtin_scene("cornell");  // ~26k triangles at 300 bytes: ~8 MB
    const fs::path dir = fresh_dir("memory-limit");
    ::setenv("RTSIM_MEMORY_LIMIT", "1M", 1);
    for (const std::string& folder : {std::string(), dir.string()})
        test::expect_input_error(
            [&] { build_bvh_cached(s, BvhBuildOptions(), BvhLayout(), folder); },
            s.source.empty() ? s.name : s.source, "above the 0.0 GiB limit");
    ::unsetenv("RTSIM_MEMORY_LIMIT");
    build_bvh_cached(s, BvhBuildOptions(), BvhLayout(), dir.string());  // stored
    ::setenv("RTSIM_MEMORY_LIMIT", "1M", 1);
    BvhCacheStatus st;
    build_bvh_cached(s, BvhBuildOptions(), BvhLayout(), dir.string(), &st);
    EXPECT_EQ(st.outcome, BvhCacheOutcome::Hit);
    ::unsetenv("RTSIM_MEMORY_LIMIT");
}

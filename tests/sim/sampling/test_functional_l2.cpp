// The frame's L2 misses counted functionally over its profile (sim/sampling/functional_l2.h): by
// hand on tiny caches, and against the cache model itself on random streams.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <set>

#include "../../models/fixed_memory.h"
#include "models/cache.h"
#include "sim/sampling/functional_l2.h"
#include "support/cache_damage.h"
#include "support/file_bytes.h"

using namespace rtsim;
namespace fs = std::filesystem;

namespace {

// A profile of the given tiles' lines (each tile's distinct lines in order), one tile a unit
// unless said, lines of 64 bytes from `base`.
FrameProfile profile_of(const std::vector<std::vector<uint32_t>>& tiles, uint64_t unit_tiles = 1,
                        uint64_t base = 0) {
    FrameProfile p;
    p.unit_tiles = unit_tiles;
    p.line_bytes = 64;
    p.line_base = base;
    p.units.assign((tiles.size() + unit_tiles - 1) / unit_tiles, AuxFigures{});
    p.tile_line_start.push_back(0);
    for (const auto& t : tiles) {
        for (uint32_t line : t) {
            p.tile_lines.push_back(line);
            p.tile_line_info.push_back(1);
        }
        p.tile_line_start.push_back(uint32_t(p.tile_lines.size()));
    }
    return p;
}

}  // namespace

// Two sets of one way (line k in set k mod 2), worked out by hand:
//   tile 0: 0, 2  both set 0, both first fetches: 2 misses, no capacity miss (set 0 holds 2)
//   tile 1: 0     evicted by 2: a capacity miss (set 0 holds 0)
//   tile 2: 1, 3  set 1, first fetches (set 1 holds 3)
//   tile 3: 2, 1  2 was evicted by 0 and 1 by 3: two capacity misses
TEST(FunctionalL2, DirectMappedByHand) {
    const FunctionalL2 f = functional_l2_misses(profile_of({{0, 2}, {0}, {1, 3}, {2, 1}}), 2, 1);
    EXPECT_EQ(f.unit_capacity_misses, (std::vector<uint32_t>{0, 1, 0, 2}));
    EXPECT_EQ(f.misses, 7u);
    EXPECT_EQ(f.capacity_misses, 3u);
}

// One set of two ways. Tile 1 touches A again, so C (tile 2) evicts B, the least recently used;
// B then misses (tile 4) and A hits (tile 3). FIFO would have evicted A instead.
TEST(FunctionalL2, LeastRecentlyUsedIsEvicted) {
    const uint32_t A = 0, B = 1, C = 2;
    const FunctionalL2 f = functional_l2_misses(profile_of({{A, B}, {A}, {C}, {A}, {B}}), 1, 2);
    EXPECT_EQ(f.unit_capacity_misses, (std::vector<uint32_t>{0, 0, 0, 0, 1}));
    EXPECT_EQ(f.misses, 4u);
}

// Units of several tiles sum their tiles' misses (the profile's base moves every line by the
// same number of sets, and changes nothing).
TEST(FunctionalL2, UnitsSumTheirTiles) {
    for (uint64_t base : {0, 64}) {
        const FunctionalL2 f =
            functional_l2_misses(profile_of({{0, 2}, {0}, {1}, {2}}, 2, base), 2, 1);
        EXPECT_EQ(f.unit_capacity_misses, (std::vector<uint32_t>{1, 1})) << base;
        EXPECT_EQ(f.capacity_misses, 2u);
    }
    EXPECT_THROW(functional_l2_misses(profile_of({{0}}), 3, 1), std::invalid_argument);
}

// Random tile streams through the cache model (LRU, counted tag checks) and through the
// functional count: the same misses in every unit, for set layouts the cache compiles for (4 and
// 16 ways), one it reads at run time (12) and more ways than the functional count's mask (80).
TEST(FunctionalL2, AgreesWithTheCacheModel) {
    for (int ways : {1, 4, 12, 16, 80}) {
        const uint64_t sets = 8;
        CacheParams params;
        params.ways = ways;
        params.line_bytes = 64;
        params.size_bytes = sets * uint64_t(ways) * 64;
        params.replacement = "lru";
        test::fresh_kernel();
        test::FixedLatencyMemory mem(10);
        Cache cache(sc_core::sc_gen_unique_name("l2"), params, &mem.up);
        test::elaborate();
        std::mt19937_64 rng{uint64_t(ways)};
        // Lines drawn from a pool about twice what the cache holds: hits, compulsory and
        // capacity misses all occur.
        const uint32_t pool = uint32_t(2 * sets * uint64_t(ways) + 5);
        std::vector<std::vector<uint32_t>> tiles(400);
        for (auto& t : tiles) {
            std::set<uint32_t> distinct;
            const size_t n = 1 + rng() % 12;
            while (distinct.size() < n) distinct.insert(uint32_t(rng() % pool));
            t.assign(distinct.begin(), distinct.end());
            std::shuffle(t.begin(), t.end(), rng);
        }
        const uint64_t unit_tiles = 3, base = 64 * 5;
        const FrameProfile p = profile_of(tiles, unit_tiles, base);
        std::vector<uint32_t> want(p.units.size(), 0);
        std::set<uint32_t> fetched;
        uint64_t misses = 0;
        Cycle at = 0;
        for (size_t t = 0; t < tiles.size(); ++t)
            for (uint32_t line : tiles[t]) {
                if (cache.check_tag(base / 64 + line, ++at)) continue;
                ++misses;
                if (!fetched.insert(line).second) ++want[t / unit_tiles];
            }
        ASSERT_EQ(cache.misses, misses) << ways;
        const FunctionalL2 f = functional_l2_misses(p, sets, uint32_t(ways));
        EXPECT_EQ(f.unit_capacity_misses, want) << ways << " ways";
        EXPECT_EQ(f.misses, misses) << ways << " ways";
        EXPECT_GT(f.capacity_misses, 0u) << ways << " ways";
    }
}

// The count's cache: stored, then served; an entry damaged, truncated, of another key or not
// fitting the profile is counted again and stored over, never used.
TEST(FunctionalL2, CacheServesValidEntriesAndRefusesDamagedOnes) {
    FrameProfile p = profile_of({{0, 2}, {0}, {1, 3}, {2, 1}, {0, 3}, {2}});
    p.key = "frame a";
    const fs::path dir = fs::path(::testing::TempDir()) / "rtsim_l2misses_cache";
    fs::remove_all(dir);
    fs::create_directories(dir);
    EXPECT_EQ(functional_l2_misses_cached(p, 2, 1, "").cache, "off");
    const FunctionalL2 want = functional_l2_misses(p, 2, 1);
    auto get = [&](const FrameProfile& q, uint32_t ways = 1) {
        return functional_l2_misses_cached(q, 2, ways, dir.string());
    };
    auto same = [&](const FunctionalL2& f) {
        return f.unit_capacity_misses == want.unit_capacity_misses && f.misses == want.misses &&
               f.capacity_misses == want.capacity_misses;
    };
    const FunctionalL2 built = get(p);
    EXPECT_EQ(built.cache, "built");
    EXPECT_TRUE(same(built));
    const FunctionalL2 hit = get(p);
    EXPECT_EQ(hit.cache, "hit");
    EXPECT_TRUE(same(hit));
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir)) files.push_back(e.path());
    ASSERT_EQ(files.size(), 1u);
    const fs::path entry = files[0];
    auto bytes = [](const fs::path& f) { return test::read_file_bytes(f); };
    auto put = [](const fs::path& f, const std::string& s) { test::write_file_bytes(f, s); };
    test::expect_damaged_entry_rebuilt(entry, [&] {
        const FunctionalL2 again = get(p);
        EXPECT_TRUE(same(again));  // recounted
        return again.cache;
    });
    // Another geometry is another entry; another key's entry under this one's name is refused.
    EXPECT_EQ(get(p, 2).cache, "built");
    FrameProfile other = p;
    other.key = "frame b";
    get(other);
    std::string foreign;
    for (const auto& e : fs::directory_iterator(dir))
        if (bytes(e.path()).find("frame b") != std::string::npos) foreign = bytes(e.path());
    ASSERT_FALSE(foreign.empty());
    put(entry, foreign);
    EXPECT_EQ(get(p).cache, "rebuilt: key mismatch");
    EXPECT_EQ(get(p).cache, "hit");
    // The same key over a profile of other units (a stale key): the entry does not fit it.
    FrameProfile fewer = profile_of({{0, 2}, {0}, {1, 3}});
    fewer.key = p.key;
    const FunctionalL2 refit = get(fewer);
    EXPECT_EQ(refit.cache, "rebuilt: inconsistent contents");
    EXPECT_EQ(refit.unit_capacity_misses, functional_l2_misses(fewer, 2, 1).unit_capacity_misses);
    fs::remove_all(dir);
}

namespace {

// profile_of with each line's rays and kind given: {line, rays, triangle}.
struct TileLine {
    uint32_t line, rays;
    bool triangle;
};
FrameProfile profile_with_rays(const std::vector<std::vector<TileLine>>& tiles) {
    FrameProfile p = profile_of(std::vector<std::vector<uint32_t>>(tiles.size()));
    p.tile_line_start = std::vector<uint32_t>{0};
    std::vector<uint32_t> start{0}, lines;
    std::vector<uint8_t> info;
    for (const auto& t : tiles) {
        for (const TileLine& l : t) {
            lines.push_back(l.line);
            info.push_back(uint8_t(l.rays | (l.triangle ? kTileLineTriangle : 0)));
        }
        start.push_back(uint32_t(lines.size()));
    }
    p.tile_line_start = std::move(start);
    p.tile_lines = std::move(lines);
    p.tile_line_info = std::move(info);
    return p;
}

}  // namespace

// One core: each line of a tile is one access to its L1, whatever its rays, so the count is an
// LRU cache's misses, compulsory ones included. The tiles of DirectMappedByHand above, through
// two sets of one way: tile 0 misses 0 and 2; tile 1 misses 0 (2 evicted it); tile 2 misses 1
// and 3; tile 3 misses 2 (0 evicted it) and 1 (3 evicted it).
TEST(FunctionalL1, OneCoreIsAnLruCacheByHand) {
    const FrameProfile p = profile_with_rays({{{0, 5, false}, {2, 1, false}},
                                              {{0, 9, false}},
                                              {{1, 1, false}, {3, 2, false}},
                                              {{2, 1, false}, {1, 127, false}}});
    const FunctionalL1 f = functional_l1_misses(p, 1, 2, 1, false);
    EXPECT_EQ(f.unit_misses, (std::vector<uint32_t>{2, 1, 2, 2}));
    EXPECT_EQ(f.misses, 7u);
}

// A line that 127 rays fetch reaches every one of 4 cores (4 (1 - 0.75^127) of them), each
// with an L1 of its own: four times the one core's misses. A line one ray fetches reaches one
// core: tile after tile of line 0 alone misses once in each core it lands on, 4 misses in all
// (a core missed by 100 draws has odds 4 * 0.75^100, about 1e-12).
TEST(FunctionalL1, RaysSpreadALineOverTheCores) {
    const FrameProfile every = profile_with_rays({{{0, 127, false}, {2, 127, false}},
                                                  {{0, 127, false}},
                                                  {{1, 127, false}, {3, 127, false}},
                                                  {{2, 127, false}, {1, 127, false}}});
    EXPECT_EQ(functional_l1_misses(every, 4, 2, 1, false).unit_misses,
              (std::vector<uint32_t>{8, 4, 8, 8}));
    const FrameProfile one(
        profile_with_rays(std::vector<std::vector<TileLine>>(100, {{0, 1, false}})));
    const FunctionalL1 f = functional_l1_misses(one, 4, 1, 1, false);
    EXPECT_EQ(f.misses, 4u);
    EXPECT_EQ(functional_l1_misses(one, 4, 1, 1, false).unit_misses, f.unit_misses);  // fixed
}

// A split L1 keeps triangles apart: a node line and a triangle line of one set of one way
// evict each other in a unified L1 (2 misses a tile), not in a split one (2 in all).
TEST(FunctionalL1, SplitL1KeepsTrianglesApart) {
    const FrameProfile p =
        profile_with_rays(std::vector<std::vector<TileLine>>(3, {{0, 1, false}, {1, 1, true}}));
    EXPECT_EQ(functional_l1_misses(p, 1, 1, 1, false).misses, 6u);
    EXPECT_EQ(functional_l1_misses(p, 1, 1, 1, true).unit_misses, (std::vector<uint32_t>{2, 0, 0}));
    EXPECT_THROW(functional_l1_misses(p, 0, 1, 1, false), std::invalid_argument);
    EXPECT_THROW(functional_l1_misses(p, 1, 3, 1, false), std::invalid_argument);
}

// Units are merged from tiles in frame order (the last may be short), and a unit size is the
// fewest tiles whose rays, at the mean of the tiles that have any, reach the slots asked for.
TEST(FrameProfileUnits, MergeAndSizeByHand) {
    FrameProfile p = profile_of({{0}, {1}, {2}, {3}, {4}});
    for (size_t u = 0; u < 5; ++u) {
        p.units[u][kAuxWork] = 10 * (u + 1);
        p.units[u][kAuxRays] = u;
    }
    p.unit_new_line_rays = {1, 2, 3, 4, 5};
    p.key = "k";
    merge_profile_units(p, 2);
    EXPECT_EQ(p.unit_tiles, 2u);
    ASSERT_EQ(p.units.size(), 3u);
    EXPECT_EQ(p.units[0][kAuxWork], 30u);
    EXPECT_EQ(p.units[1][kAuxWork], 70u);
    EXPECT_EQ(p.units[2][kAuxWork], 50u);
    EXPECT_EQ(p.units[2][kAuxRays], 4u);
    EXPECT_EQ(p.unit_new_line_rays, (std::vector<uint64_t>{3, 7, 5}));
    EXPECT_NE(p.key, "k");  // counts cached by the key are kept per unit size
    // Rays per tile 0, 100, 300, 0, 200: a mean of 200 over the three with rays.
    const MappableArray<uint32_t> rays(std::vector<uint32_t>{0, 100, 300, 0, 200});
    EXPECT_EQ(unit_tiles_for_slot_fills(rays, 1000), 5u);
    EXPECT_EQ(unit_tiles_for_slot_fills(rays, 1001), 6u);
    EXPECT_EQ(unit_tiles_for_slot_fills(rays, 200), 1u);
    EXPECT_EQ(unit_tiles_for_slot_fills(rays, 0), 1u);
    EXPECT_EQ(unit_tiles_for_slot_fills(MappableArray<uint32_t>(std::vector<uint32_t>{0, 0}), 64),
              1u);
}

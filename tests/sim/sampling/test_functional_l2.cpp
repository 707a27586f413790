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
        test::FixedLatencyMemory mem(10);
        Cache cache(sc_core::sc_gen_unique_name("l2"), params, &mem);
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

// Hardware prefetchers at a cache (models/prefetcher.h, models/prefetcher/): which lines each
// names, and the cache's handling of them (MSHRs, merging, counters), against values worked out
// by hand from the rules stated in models/prefetcher.h.
#include <gtest/gtest.h>

#include <vector>

#include "fixed_memory.h"
#include "models/cache.h"
#include "models/prefetcher.h"

using namespace rtsim;

namespace {

std::vector<uint64_t> named(Prefetcher& p, uint64_t line) {
    std::vector<uint64_t> out;
    p.on_miss(line, out);
    return out;
}

std::unique_ptr<Prefetcher> make(const char* name, int degree) {
    PrefetcherParams pp;
    pp.degree = degree;
    return PrefetcherRegistry::at(name).make(pp);
}

// 1 KiB, 4 ways, 64-byte lines (4 sets), hit latency 4, one bank, the next level 100 cycles.
CacheParams small_cache(const char* prefetcher, int mshrs, int degree = 1) {
    CacheParams p;
    p.size_bytes = 1024;
    p.ways = 4;
    p.line_bytes = 64;
    p.hit_latency_cycles = 4;
    p.mshrs = mshrs;
    p.banks = 1;
    p.prefetcher = prefetcher;
    p.prefetch_degree = degree;
    return p;
}

}  // namespace

TEST(Prefetcher, NoneMakesNothing) {
    EXPECT_EQ(PrefetcherRegistry::at("none").make, nullptr);
}

TEST(Prefetcher, NextLineNamesTheFollowingLines) {
    auto p = make("next_line", 3);
    EXPECT_EQ(named(*p, 10), (std::vector<uint64_t>{11, 12, 13}));
    EXPECT_EQ(named(*p, 0), (std::vector<uint64_t>{1, 2, 3}));
}

TEST(Prefetcher, StrideNeedsTwoEqualDistancesWithinItsReach) {
    auto p = make("stride", 2);
    EXPECT_TRUE(named(*p, 100).empty());                           // first miss: no distance
    EXPECT_TRUE(named(*p, 103).empty());                           // +3, not confirmed yet
    EXPECT_EQ(named(*p, 106), (std::vector<uint64_t>{109, 112}));  // +3 again
    EXPECT_TRUE(named(*p, 105).empty());                           // -1: re-trains
    EXPECT_EQ(named(*p, 104), (std::vector<uint64_t>{103, 102}));  // -1 twice, downwards
    EXPECT_TRUE(named(*p, 104).empty());                           // distance 0 is no stride
    EXPECT_TRUE(named(*p, 204).empty());                           // +100: beyond 64 lines
    EXPECT_TRUE(named(*p, 304).empty());                           // +100 twice: still too far
    EXPECT_TRUE(named(*p, 1).empty());                             // no line below 0 is named
    auto q = make("stride", 4);
    named(*q, 5);
    named(*q, 3);
    EXPECT_EQ(named(*q, 1), (std::vector<uint64_t>{}));  // -2: lines -1, -3, ... do not exist
}

// Line 0 misses at 0: looked up at 4, fetched until 104. Next-line names line 1: an MSHR is free
// at 4, so it is fetched at 4 too, until 104. A demand read of line 1 at 10 (looked up at 14)
// finds it filling and waits until 104; at 200 (looked up at 204) it hits.
TEST(Prefetcher, NextLineFetchesAtTheMissAndADemandWaitsForIt) {
    test::FixedLatencyMemory mem(100);
    Cache c(sc_core::sc_gen_unique_name("pf"), small_cache("next_line", 4), &mem.up);
    test::elaborate();
    EXPECT_EQ(c.access(0, 64, 0), 104u);
    ASSERT_EQ(mem.addrs, (std::vector<uint64_t>{0, 64}));
    EXPECT_EQ(mem.times, (std::vector<Cycle>{4, 4}));
    EXPECT_EQ(c.access(64, 64, 10), 104u);
    EXPECT_EQ(c.access(64, 64, 200), 204u);
    EXPECT_EQ(c.misses, 1u);
    EXPECT_EQ(c.hits, 2u);
    EXPECT_EQ(c.merged_misses, 1u);
    EXPECT_EQ(c.prefetches, 1u);
    EXPECT_EQ(c.prefetch_hits, 1u);  // the first demand lookup only
    EXPECT_EQ(c.prefetches_dropped, 0u);
    EXPECT_EQ(c.fill_bytes, 128u);
    EXPECT_EQ(mem.addrs.size(), 2u);
}

// One MSHR: the demand miss of line 0 holds it from 4 to 104, so line 1's prefetch at 4 finds
// none free and is dropped; line 1 is then a demand miss of its own (looked up at 14, waiting for
// the MSHR until 104, back at 204), whose prefetch of line 2 is dropped the same way.
TEST(Prefetcher, APrefetchWithNoFreeMshrIsDroppedAndDelaysNothing) {
    test::FixedLatencyMemory mem(100);
    Cache c(sc_core::sc_gen_unique_name("pf"), small_cache("next_line", 1), &mem.up);
    test::elaborate();
    EXPECT_EQ(c.access(0, 64, 0), 104u);
    EXPECT_EQ(c.access(64, 64, 10), 204u);
    EXPECT_EQ(mem.addrs, (std::vector<uint64_t>{0, 64}));
    EXPECT_EQ(mem.times, (std::vector<Cycle>{4, 104}));
    EXPECT_EQ(c.prefetches, 0u);
    EXPECT_EQ(c.prefetches_dropped, 2u);
    EXPECT_EQ(c.misses, 2u);
}

// A prefetch takes an MSHR until its line is back: with two MSHRs, line 0's miss and line 1's
// prefetch hold both from 4 to 104, so a demand miss of line 8 at 10 (looked up at 14) waits
// until 104 and is back at 204.
TEST(Prefetcher, APrefetchHoldsItsMshrUntilItsLineIsBack) {
    test::FixedLatencyMemory mem(100);
    Cache c(sc_core::sc_gen_unique_name("pf"), small_cache("next_line", 2), &mem.up);
    test::elaborate();
    EXPECT_EQ(c.access(0, 64, 0), 104u);
    EXPECT_EQ(c.access(8 * 64, 64, 10), 204u);
    EXPECT_EQ(c.mshr_wait_cycles, 104u - 14);
    // Line 8's prefetch of line 9 at 14: both MSHRs busy (until 104 and 204): dropped.
    EXPECT_EQ(c.prefetches, 1u);
    EXPECT_EQ(c.prefetches_dropped, 1u);
}

// A held line is not fetched again, and only a demand lookup's first find of a prefetched line
// counts as useful. Degree 2; 4 sets, so lines 0 .. 4 sit in sets 0, 1, 2, 3, 0.
TEST(Prefetcher, HeldLinesAreNotFetchedAgainAndOnlyDemandHitsCount) {
    test::FixedLatencyMemory mem(100);
    Cache c(sc_core::sc_gen_unique_name("pf"), small_cache("next_line", 8, 2), &mem.up);
    test::elaborate();
    c.access(2 * 64, 64, 0);    // miss 2; prefetch 3, 4
    c.access(0, 64, 300);       // miss 0; names 1, 2: 2 is held, 1 is fetched
    c.access(3 * 64, 64, 600);  // hit on prefetched 3: useful
    c.access(1 * 64, 64, 700);  // hit on prefetched 1: useful
    c.access(1 * 64, 64, 800);  // hit again: not a prefetch hit
    c.access(2 * 64, 64, 900);  // a demand-fetched line: not a prefetch hit
    EXPECT_EQ(c.misses, 2u);
    EXPECT_EQ(c.prefetches, 3u);
    EXPECT_EQ(c.prefetch_hits, 2u);
    EXPECT_EQ(mem.addrs, (std::vector<uint64_t>{2 * 64, 3 * 64, 4 * 64, 0, 64}));
}

// A cache without a prefetcher counts none and asks the next level for demand lines only.
TEST(Prefetcher, NoPrefetcherFetchesDemandLinesOnly) {
    test::FixedLatencyMemory mem(100);
    Cache c(sc_core::sc_gen_unique_name("pf"), small_cache("none", 4), &mem.up);
    test::elaborate();
    c.access(0, 64, 0);
    EXPECT_FALSE(c.prefetching());
    EXPECT_EQ(mem.addrs, (std::vector<uint64_t>{0}));
    EXPECT_EQ(c.prefetches + c.prefetches_dropped + c.prefetch_hits, 0u);
}

// Sampled runs with a prefetcher count as first fills the lines a ray first asks for, as the
// frame's profile does (LineFirstTouches): a prefetched line counts when a demand first finds
// it, warming marks lines asked for without counting them, and a line only a prefetch brought
// never counts.
TEST(Prefetcher, FirstFillsAreTheLinesDemandFirstAsksFor) {
    test::FixedLatencyMemory mem(100);
    Cache c(sc_core::sc_gen_unique_name("pf"), small_cache("next_line", 8), &mem.up);
    test::elaborate();
    LineFirstTouches touches(0, 64 * 64, 64);
    c.count_first_demands(&touches);
    c.access(0, 64, 0);  // line 0 asked for; line 1 prefetched
    EXPECT_EQ(touches.count, 1u);
    c.access(64, 64, 300);  // line 1's first demand
    EXPECT_EQ(touches.count, 2u);
    c.access(0, 64, 400);  // asked for before
    EXPECT_EQ(touches.count, 2u);
    c.warm(5 * 64, 64);  // warming asks for line 5 (uncounted) and prefetches line 6
    EXPECT_TRUE(c.contains(6 * 64));
    c.access(5 * 64, 64, 500);
    EXPECT_EQ(touches.count, 2u);
    c.access(6 * 64, 64, 600);  // brought by warming's prefetch, first asked for now
    EXPECT_EQ(touches.count, 3u);
    EXPECT_EQ(c.prefetches, 1u);  // line 1 (timed); warming's line 6 is not counted
}

#include <gtest/gtest.h>

#include <algorithm>
#include <list>
#include <random>
#include <set>

#include "fixed_memory.h"
#include "models/cache.h"
#include "models/crossbar.h"

using namespace rtsim;

namespace {

// Deliberately simple LRU reference: one list of line addresses per set, most recent first.
class ReferenceLru {
  public:
    // lru false: FIFO (a hit leaves the order as it is).
    ReferenceLru(uint64_t sets, int ways, uint32_t line, bool lru = true)
        : sets_(sets), ways_(ways), line_(line), lru_(lru), lists_(sets) {}
    bool access(uint64_t addr) {
        const uint64_t line = addr / line_;
        auto& l = lists_[line % sets_];
        for (auto it = l.begin(); it != l.end(); ++it)
            if (*it == line) {
                if (lru_) {
                    l.erase(it);
                    l.push_front(line);
                }
                return true;
            }
        l.push_front(line);
        if (l.size() > size_t(ways_)) l.pop_back();
        return false;
    }

  private:
    uint64_t sets_;
    int ways_;
    uint32_t line_;
    bool lru_;
    std::vector<std::list<uint64_t>> lists_;
};

}  // namespace

TEST(Cache, HitAndMissCountsEqualReferenceLru) {
    // Every set layout the hot paths are compiled for (4, 8, 16 ways), and ones read at run time.
    for (int ways : {1, 2, 4, 8, 12, 16, 32}) {
        CacheParams p;
        p.ways = ways;
        p.line_bytes = 64;
        p.size_bytes = uint64_t(ways) * 64 * (ways % 3 == 0 ? 8 : 8 * 16 / ways);  // 2^n sets
        test::fresh_kernel();
        test::FixedLatencyMemory mem(50);
        Cache c(sc_core::sc_gen_unique_name("c"), p, &mem.up);
        test::elaborate();
        ReferenceLru ref(p.sets(), ways, 64);
        TimeFloor floor;  // requests come in time order: the bank forgets what is behind
        c.follow(&floor);
        std::mt19937_64 rng(ways);
        // A mix of a hot region (hits) and a cold sweep (conflict and capacity misses).
        uint64_t ref_hits = 0, ref_misses = 0;
        Cycle t = 0;
        for (int i = 0; i < 200000; ++i) {
            const uint64_t addr = (rng() % 4 == 0) ? (rng() % (1 << 20)) : (rng() % (6 * 1024));
            const uint64_t aligned = addr & ~uint64_t(63);
            (ref.access(aligned) ? ref_hits : ref_misses)++;
            floor.cycle = t;
            c.access(aligned, 64, t);
            t += 1000;  // fills complete between accesses: pure hit/miss behaviour
        }
        EXPECT_EQ(c.hits, ref_hits) << ways << " ways";
        EXPECT_EQ(c.misses, ref_misses) << ways << " ways";
        EXPECT_EQ(c.accesses, 200000u);
        EXPECT_EQ(mem.addrs.size(), ref_misses);
        EXPECT_EQ(c.fill_bytes, ref_misses * 64);
    }
}

// First fills (count_first_fills) against a reference LRU and a set of the lines ever held: a
// counted miss on a line of the range never held before, by a miss or by warming (uncounted).
TEST(Cache, FirstFillsAreMissesOnLinesOfTheRangeNeverHeld) {
    CacheParams p;
    p.ways = 4;
    p.line_bytes = 64;
    p.size_bytes = 4 * 64 * 16;  // 16 sets: capacity misses aplenty
    test::FixedLatencyMemory mem(50);
    Cache c("first_fills", p, &mem.up);
    Cache plain("plain", p, &mem.up);
    test::elaborate();
    const uint64_t base = 64 * 100 + 8,
                   end = 64 * 900;  // lines 100 .. 899 (a part line at each end)
    c.count_first_fills(base, end);
    StatsRegistry reg;
    c.register_stats(reg);
    ReferenceLru ref(p.sets(), p.ways, 64);
    std::set<uint64_t> held;
    std::mt19937_64 rng(7);
    uint64_t want = 0, misses = 0;
    Cycle t = 0;
    for (int i = 0; i < 50000; ++i) {
        const uint64_t line = rng() % 1000, addr = line * 64;
        const bool in_range = line >= 100 && line < 900, warm = rng() % 5 == 0;
        const bool hit = ref.access(addr);
        if (!hit && in_range) want += !warm && held.insert(line).second;
        if (!hit && in_range && warm) held.insert(line);
        misses += !hit && !warm;
        if (warm) {
            c.warm(addr, 64);
        } else {
            c.access(addr, 64, t);
            t += 1000;
        }
    }
    EXPECT_EQ(c.misses, misses);
    EXPECT_EQ(c.first_fills(), want);
    EXPECT_LT(want, misses / 4);  // most misses are capacity misses here
    EXPECT_GT(want, 500u);
    // Registered only when counted.
    EXPECT_TRUE(reg.has("first_fills.first_fills"));
    plain.register_stats(reg);
    EXPECT_FALSE(reg.has("plain.first_fills"));
    EXPECT_TRUE(reg.has("plain.misses"));
}

// The cores' way in: a request of one, two or four lines (a triangle, a node) first tries
// access_local, which must find every line or change nothing, then access. Line by line, the
// hits and misses must be the reference's, for every set layout and both orderings, with the
// stamps' counter wrapping on the way.
TEST(Cache, LocalProbesOfManyLinesEqualReference) {
    for (int ways : {2, 4, 8, 12, 16})
        for (auto policy : {std::string("lru"), std::string("fifo")}) {
            CacheParams p;
            p.ways = ways;
            p.line_bytes = 64;
            p.size_bytes = uint64_t(ways) * 64 * 16;  // 16 sets
            p.replacement = policy;
            const bool lru = policy == std::string("lru");
            test::fresh_kernel();
            test::FixedLatencyMemory mem(50);
            Cache c(sc_core::sc_gen_unique_name("c"), p, &mem.up);
            test::elaborate();
            ReferenceLru ref(p.sets(), ways, 64, lru);
            TimeFloor floor;
            c.follow(&floor);
            std::mt19937_64 rng(uint64_t(ways) * 2 + lru);
            uint64_t ref_hits = 0, ref_misses = 0, local = 0;
            Cycle t = 0;
            for (int i = 0; i < 30000; ++i) {
                const uint64_t lines = uint64_t(1) << (rng() % 3);
                const uint64_t addr = (rng() % (3 * p.size_bytes)) & ~(lines * 64 - 1);
                for (uint64_t k = 0; k < lines; ++k)
                    (ref.access(addr + 64 * k) ? ref_hits : ref_misses)++;
                floor.cycle = t;
                Cycle ready = 0;
                if (c.access_local(addr, uint32_t(lines * 64), t, ready))
                    ++local;
                else
                    c.access(addr, uint32_t(lines * 64), t);
                t += 1000;  // fills complete between requests: pure hit/miss behaviour
                if (i % 7000 == 6999) c.set_stamp_clock(~uint32_t(0) - 50);
            }
            const std::string what = std::to_string(ways) + (lru ? " ways, lru" : " ways, fifo");
            EXPECT_EQ(c.hits, ref_hits) << what;
            EXPECT_EQ(c.misses, ref_misses) << what;
            EXPECT_GT(local, 3000u) << what;  // both ways in were taken
            EXPECT_GT(c.misses, 3000u) << what;
        }
}

// Replacement stamps are 32 bits: when their counter wraps they are renumbered per set, and
// every decision stays the reference's.
TEST(Cache, ReplacementStampsSurviveTheirCounterWrapping) {
    for (auto policy : {std::string("lru"), std::string("fifo")}) {
        CacheParams p;
        p.size_bytes = 4 * 1024;
        p.ways = 4;
        p.replacement = policy;
        test::fresh_kernel();
        test::FixedLatencyMemory mem(50);
        Cache c(sc_core::sc_gen_unique_name("c"), p, &mem.up);
        test::elaborate();
        c.set_stamp_clock(~uint32_t(0) - 5000);  // wraps after 5,000 stamps, several times over
        const bool lru = policy == std::string("lru");
        ReferenceLru ref(p.sets(), p.ways, 64, lru);
        TimeFloor floor;
        c.follow(&floor);
        std::mt19937_64 rng(3);
        uint64_t ref_hits = 0;
        Cycle t = 0;
        for (int i = 0; i < 40000; ++i) {
            const uint64_t addr = (rng() % (16 * 1024)) & ~uint64_t(63);
            ref_hits += ref.access(addr);
            floor.cycle = t;
            c.access(addr, 64, t);
            t += 1000;
            if (i % 9000 == 8999) c.set_stamp_clock(~uint32_t(0) - 100);
        }
        EXPECT_EQ(c.hits, ref_hits) << (lru ? "lru" : "fifo");
    }
}

TEST(Cache, LatenciesAndMissMerging) {
    CacheParams p;
    p.size_bytes = 1024;
    p.ways = 2;
    p.line_bytes = 64;
    p.hit_latency_cycles = 4;
    p.banks = 2;  // a request spanning two lines looks both up in the same cycle
    test::FixedLatencyMemory mem(100);
    Cache c("c", p, &mem.up);
    test::elaborate();
    EXPECT_EQ(c.access(0x1000, 48, 10), 10u + 4 + 100);  // miss: lookup, then the next level
    EXPECT_EQ(c.access(0x1010, 16, 20), 114u);           // same line, fill in flight: waits for it
    EXPECT_EQ(c.merged_misses, 1u);
    EXPECT_EQ(c.access(0x1000, 64, 500), 504u);  // plain hit
    EXPECT_EQ(mem.addrs.size(), 1u);             // one fill served all three
    // A request spanning two lines looks both up.
    EXPECT_EQ(c.access(0x2030, 32, 1000), 1000u + 4 + 100);
    EXPECT_EQ(mem.addrs.size(), 3u);
    EXPECT_EQ(c.accesses, 5u);
    // A request spanning two lines, one a plain hit and one still filling, waits for the fill:
    // 0x3040 is there from 1604; 0x3000's fill, asked at 2000, returns at 2000 + 4 + 100.
    EXPECT_EQ(c.access(0x3040, 64, 1500), 1500u + 4 + 100);
    EXPECT_EQ(c.access(0x3000, 64, 2000), 2104u);
    EXPECT_EQ(c.access(0x3020, 64, 2010), 2104u);
    EXPECT_EQ(c.merged_misses, 2u);
}

TEST(Cache, BreakdownChargesEachLevelItsCycles) {
    CacheParams p1, p2;
    p1.size_bytes = 1024;
    p1.ways = 2;
    p1.hit_latency_cycles = 4;
    p1.banks = 2;
    p2.size_bytes = 8192;
    p2.ways = 4;
    p2.hit_latency_cycles = 30;
    test::FixedLatencyMemory dram(200);  // charges its latency to the DRAM level
    Cache l2("l2", p2, &dram.up, kLevelL2);
    Cache l1("l1", p1, &l2.up, kLevelL1);
    test::elaborate();
    AccessBreakdown a;
    EXPECT_EQ(l1.access(0x4000, 64, 100, &a), 100u + 4 + 30 + 200);  // misses everywhere
    EXPECT_EQ(a.cycles[kLevelL1], 4u);
    EXPECT_EQ(a.cycles[kLevelL2], 30u);
    EXPECT_EQ(a.cycles[kLevelDram], 200u);
    AccessBreakdown b;
    EXPECT_EQ(l1.access(0x4000, 64, 110, &b), 334u);  // hit on a line still filling: waits below L1
    // The fill left the L1 at 104, was at the L2 until 134 and at DRAM until 334: the hit,
    // looked up by 114, waits 20 cycles on the L2 and 200 on DRAM (charged where it waits, not
    // all to the level below the L1).
    EXPECT_EQ(b.cycles[kLevelL1], 4u);
    EXPECT_EQ(b.cycles[kLevelL2], 134u - 114u);
    EXPECT_EQ(b.cycles[kLevelDram], 334u - 134u);
    AccessBreakdown c;
    EXPECT_EQ(l1.access(0x4000, 32, 1000, &c), 1004u);  // plain hit
    EXPECT_EQ(c.cycles[kLevelL1] + c.cycles[kLevelL2] + c.cycles[kLevelDram], 4u);
    // Two lines, one cached, one not: the slower line's breakdown is charged.
    AccessBreakdown d;
    EXPECT_EQ(l1.access(0x4000 + 32, 64, 2000, &d), 2000u + 4 + 30 + 200);
    EXPECT_EQ(d.cycles[kLevelL1], 4u);
    EXPECT_EQ(d.cycles[kLevelDram], 200u);
}

TEST(Cache, MshrsBoundBandwidthByLittlesLaw) {
    // N misses to distinct lines, all at once, through M MSHRs to a memory of latency L: M misses
    // are in flight at any time, so they finish in waves, L cycles apart, and the bandwidth is
    // M lines per L cycles (Little's law).
    const int M = 4;
    const Cycle L = 100, hit = 4;
    const int N = 100;
    CacheParams p;
    p.size_bytes = 64 * 1024;
    p.ways = 4;
    p.hit_latency_cycles = hit;
    p.mshrs = M;
    p.banks = 128;  // lookups never wait for a bank here: only MSHRs limit
    test::FixedLatencyMemory mem(L);
    Cache c("c", p, &mem.up);
    Cache d("d", p, &mem.up);
    test::elaborate();
    Cycle last = 0;
    for (int i = 0; i < N; ++i) last = std::max(last, c.access(uint64_t(i) * 64, 64, 0));
    EXPECT_EQ(last, hit + Cycle(N / M) * L);
    const double lines_per_cycle = double(N) / double(last - hit);
    EXPECT_NEAR(lines_per_cycle, double(M) / double(L), 1e-9);
    EXPECT_GT(c.mshr_wait_cycles, 0u);
    // Merged misses take no MSHR: a second access to a filling line does not wait for one.
    for (int i = 0; i < M; ++i) d.access(uint64_t(i) * 64, 64, 0);
    EXPECT_EQ(d.access(0, 64, 1), hit + L);  // joins the first fill
    EXPECT_EQ(d.mshr_wait_cycles, 0u);
}

// Misses whose data returns out of order (the latency varies by line): with M MSHRs each miss
// waits for the earliest to free, as a deliberately simple model of M free times says. Up to
// 16 MSHRs and more are kept differently (unordered keys, an ordered ring); both must agree.
TEST(Cache, MshrsFreeOutOfOrderAsASimpleModelSays) {
    struct VaryingMemory : test::TargetMemory {
        Cycle latency(uint64_t addr) const { return 50 + (addr / 64 % 7) * 30; }
        Cycle access(uint64_t addr, uint32_t, Cycle now, AccessBreakdown* bd) override {
            if (bd) bd->cycles[kLevelDram] += latency(addr);
            return now + latency(addr);
        }
    };
    for (int M : {1, 3, 16, 17, 40}) {
        CacheParams p;
        p.size_bytes = 64 * 1024;
        p.ways = 4;
        p.hit_latency_cycles = 4;
        p.mshrs = M;
        p.banks = 256;  // only MSHRs limit
        test::fresh_kernel();
        VaryingMemory mem;
        Cache c("c", p, &mem.up);
        test::elaborate();
        std::vector<Cycle> free_at(size_t(M), 0);
        for (int i = 0; i < 200; ++i) {
            const uint64_t addr = uint64_t(i) * 64;
            const Cycle now = Cycle(i) * 3;
            auto earliest = std::min_element(free_at.begin(), free_at.end());
            const Cycle done = std::max(now + 4, *earliest) + mem.latency(addr);
            *earliest = done;
            ASSERT_EQ(c.access(addr, 64, now), done) << M << " MSHRs, miss " << i;
        }
        EXPECT_GT(c.mshr_wait_cycles, 0u) << M;
    }
}

TEST(Cache, BankConflictsSerialiseLookups) {
    CacheParams p;
    p.size_bytes = 4096;
    p.ways = 2;
    p.hit_latency_cycles = 4;
    p.banks = 2;
    test::FixedLatencyMemory mem(50);
    Cache c("c", p, &mem.up);
    test::elaborate();
    for (int i = 0; i < 4; ++i) c.access(uint64_t(i) * 64, 64, 0);  // warm four lines
    // Lines 0 and 2 share bank 0: at the same cycle the second waits one cycle for it.
    EXPECT_EQ(c.access(0, 64, 1000), 1004u);
    EXPECT_EQ(c.access(128, 64, 1000), 1005u);
    EXPECT_EQ(c.access(64, 64, 1000), 1004u);                 // bank 1 is free
    EXPECT_EQ(c.bank_conflict_cycles, 1u + (0 + 1 + 0 + 1));  // warm-up: lines 2 and 3 waited too
}

// Functional warming (sampled simulation): warming a stream of addresses leaves every level with
// the contents timed accesses of the same stream leave, for every replacement policy, and counts
// nothing; a timed access to a warmed line is then a plain hit.
TEST(Cache, WarmingLeavesTheStateTimedAccessesLeave) {
    for (const char* policy : {"lru", "fifo", "random", "srrip", "tree_plru"}) {
        CacheParams p1, p2;
        p1.size_bytes = 4096;
        p1.ways = 4;
        p1.replacement = policy;
        p2.size_bytes = 32768;
        p2.ways = 8;
        p2.replacement = policy;
        test::fresh_kernel();
        test::FixedLatencyMemory mem_a(100), mem_b(100);
        Cache l2a(sc_core::sc_gen_unique_name("l2"), p2, &mem_a.up, kLevelL2);
        Cache l1a(sc_core::sc_gen_unique_name("l1"), p1, &l2a.up);
        Cache l2b(sc_core::sc_gen_unique_name("l2"), p2, &mem_b.up, kLevelL2);
        Cache l1b(sc_core::sc_gen_unique_name("l1"), p1, &l2b.up);
        test::elaborate();
        std::mt19937_64 rng(3);
        Cycle t = 0;
        for (int i = 0; i < 20000; ++i) {
            const uint64_t addr = (rng() % 3 == 0 ? rng() % (1 << 18) : rng() % 16384) & ~63ull;
            l1a.access(addr, 64, t += 1000);  // fills complete between accesses
            l1b.warm(addr, 64);
        }
        EXPECT_EQ(l1b.accesses + l1b.hits + l1b.misses + l1b.fill_bytes, 0u) << policy;
        EXPECT_EQ(l2b.accesses + l2b.hits + l2b.misses + l2b.fill_bytes, 0u) << policy;
        EXPECT_TRUE(mem_b.addrs.empty()) << policy;
        int present = 0;
        for (uint64_t line = 0; line < (1 << 18) / 64; ++line) {
            ASSERT_EQ(l1a.contains(line * 64), l1b.contains(line * 64)) << policy << " " << line;
            ASSERT_EQ(l2a.contains(line * 64), l2b.contains(line * 64)) << policy << " " << line;
            present += l1b.contains(line * 64);
        }
        EXPECT_EQ(present, 4096 / 64) << policy;  // the L1 is full
        // A warmed line: an L1 hit at the hit latency, no traffic below.
        uint64_t warmed = 0;
        while (!l1b.contains(warmed)) warmed += 64;
        const uint64_t below = mem_b.addrs.size();
        EXPECT_EQ(l1b.access(warmed, 64, t), t + p1.hit_latency_cycles) << policy;
        EXPECT_EQ(l1b.hits, 1u);
        EXPECT_EQ(mem_b.addrs.size(), below);
    }
}

// The sampler's replay (sim/sampling/sampler.cpp) warms an LRU L1 with only the last touch of each
// line of its window, in their order: the cache must end as the whole stream leaves it, its lines
// held before included, down to the recency order (which the next lines' evictions show).
TEST(Cache, LastTouchesLeaveAnLruCacheAsTheWholeStream) {
    CacheParams p;
    p.size_bytes = 4096;
    p.ways = 4;
    p.replacement = "lru";
    test::FixedLatencyMemory mem_a(100), mem_b(100);
    Cache a(sc_core::sc_gen_unique_name("l1"), p, &mem_a.up);
    Cache b(sc_core::sc_gen_unique_name("l1"), p, &mem_b.up);
    test::elaborate();
    std::mt19937_64 rng(8);
    auto line_addr = [](uint64_t line) { return line * 64; };
    for (uint64_t line = 1000; line < 1040; ++line) {  // lines held before the window
        a.warm(line_addr(line), 64);
        b.warm(line_addr(line), 64);
    }
    // Lines met again and again; set s (of 16) gets s % 6 + 1 distinct ones, so that some sets
    // keep lines from before the window below the window's own.
    std::vector<uint64_t> stream;
    for (int i = 0; i < 600; ++i) {
        const uint64_t set = rng() % 16;
        stream.push_back(set + 16 * (rng() % (set % 6 + 1)));
    }
    std::vector<uint64_t> last;
    std::set<uint64_t> seen;
    for (size_t i = stream.size(); i-- > 0;)
        if (seen.insert(stream[i]).second) last.push_back(stream[i]);
    ASSERT_LT(last.size(), stream.size() * 9 / 10);
    for (uint64_t line : stream) a.warm(line_addr(line), 64);
    for (size_t i = last.size(); i-- > 0;) b.warm(line_addr(last[i]), 64);
    auto same = [&]() {
        for (uint64_t line = 0; line < 2048; ++line)
            if (a.contains(line_addr(line)) != b.contains(line_addr(line))) return false;
        return true;
    };
    EXPECT_TRUE(same());
    int held_before = 0;
    for (uint64_t line = 1000; line < 1040; ++line) held_before += b.contains(line_addr(line));
    EXPECT_GT(held_before, 0);  // some sets kept lines from before the window
    for (uint64_t line = 1100; line < 1164; ++line) {  // fresh lines evict in recency order
        a.warm(line_addr(line), 64);
        b.warm(line_addr(line), 64);
        ASSERT_TRUE(same()) << "after line " << line;
    }
}

TEST(Cache, FifoAndRandomReplacement) {
    // One set of 2 ways: A, B, then A again, then C. LRU evicts B (A was used last), FIFO evicts A
    // (filled first). Random is deterministic: two caches see the same victims.
    auto run = [](const std::string& r) {
        CacheParams p;
        p.size_bytes = 128;
        p.ways = 2;
        p.replacement = r;
        test::fresh_kernel();
        test::FixedLatencyMemory mem(10);
        Cache c(sc_core::sc_gen_unique_name("c"), p, &mem.up);
        test::elaborate();
        Cycle t = 0;
        for (uint64_t line : {0, 1, 0, 2}) c.access(line * 64, 64, t += 100);
        const uint64_t before = c.hits;
        c.access(0, 64, t += 100);  // is A still there?
        return c.hits - before;
    };
    EXPECT_EQ(run(std::string("lru")), 1u);
    EXPECT_EQ(run(std::string("fifo")), 0u);
    EXPECT_EQ(run(std::string("random")), run(std::string("random")));
}

TEST(Crossbar, CapsBandwidthAndAddsTheCrossingTime) {
    test::FixedLatencyMemory l2(30);
    Crossbar x("xbar", 32.0, &l2.up);
    test::elaborate();
    const Cycle n = 50;
    Cycle last = 0;
    for (Cycle k = 0; k < n; ++k) last = std::max(last, x.access(k * 64, 64, 0));
    // 64-byte lines at 32 bytes per cycle: one every 2 cycles, each crossing in 2 after the L2.
    EXPECT_EQ(last, 2 * (n - 1) + 30 + 2);
    EXPECT_EQ(x.bytes, n * 64);
    EXPECT_EQ(x.queue_cycles, n * (n - 1));  // request k waited 2k cycles
    AccessBreakdown bd;
    EXPECT_EQ(x.access(0, 64, 1000, &bd), 1000u + 30 + 2);  // idle: latency plus crossing only
    EXPECT_EQ(bd.cycles[kLevelCrossbar], 2u);  // the crossing is the crossbar's, not the L2's
    EXPECT_EQ(bd.cycles[kLevelL2], 0u);
}

namespace {
// Lines at or above `slow_from` take `slow` cycles (a DRAM miss in the L2), others `fast`.
class TwoSpeedMemory : public test::TargetMemory {
  public:
    TwoSpeedMemory(uint64_t slow_from, Cycle fast, Cycle slow)
        : slow_from_(slow_from), fast_(fast), slow_(slow) {}
    Cycle access(uint64_t addr, uint32_t, Cycle now, AccessBreakdown* bd) override {
        const Cycle latency = addr >= slow_from_ ? slow_ : fast_;
        if (bd) bd->cycles[kLevelDram] += latency;
        return now + latency;
    }

  private:
    uint64_t slow_from_;
    Cycle fast_, slow_;
};
}  // namespace

// A line crosses when the L2 returns it: a line waiting for DRAM holds no bandwidth, and lines
// returned in another order than requested cross in the order they come back.
TEST(Crossbar, LinesCrossWhenTheL2ReturnsThem) {
    TwoSpeedMemory l2(0x10000, 30, 300);
    Crossbar x("xbar_returns", 16.0, &l2.up);  // a line crosses in 4 cycles
    test::elaborate();
    AccessBreakdown slow_bd, fast_bd;
    EXPECT_EQ(x.access(0x10000, 64, 0, &slow_bd), 304u);  // requested first, back last
    EXPECT_EQ(x.access(0x0, 64, 1, &fast_bd), 35u);       // not queued behind the DRAM miss
    EXPECT_EQ(x.access(0x40, 64, 2, nullptr), 36u + 3);   // back at 32: waits for the link
    EXPECT_EQ(x.queue_cycles, 3u);
    // The breakdown adds up to the latency: the level below's cycles, then the crossing, which
    // is the crossbar's.
    EXPECT_EQ(slow_bd.cycles[kLevelDram], 300u);
    EXPECT_EQ(slow_bd.cycles[kLevelCrossbar], 4u);
    EXPECT_EQ(fast_bd.cycles[kLevelCrossbar], 4u);
    EXPECT_EQ(fast_bd.cycles[kLevelL2], 0u);
}

// The fast model serves a cache's tag state and MSHRs in the order requests reach it; where that
// is not simulated-time order it counts it (a probe: with one MSHR, a miss at cycle
// 1000 handled before a miss at cycle 0).
TEST(Cache, RequestsOutOfTimeOrderAreCounted) {
    CacheParams p;
    p.mshrs = 1;
    test::FixedLatencyMemory mem(100);
    Cache c("ooo", p, &mem.up);
    test::elaborate();
    c.access(0 * 64, 64, 1000);
    EXPECT_EQ(c.lookup_out_of_order + c.mshr_out_of_order, 0u);
    c.access(1 * 64, 64, 0);  // earlier than the one before: both its lookup and its MSHR
    EXPECT_EQ(c.lookup_out_of_order, 1u);
    EXPECT_EQ(c.mshr_out_of_order, 1u);
    c.access(0 * 64, 64, 500);  // a hit, earlier than 1000: tag state only
    EXPECT_EQ(c.lookup_out_of_order, 2u);
    EXPECT_EQ(c.mshr_out_of_order, 1u);
    c.access(2 * 64, 64, 2000);  // in order again
    EXPECT_EQ(c.lookup_out_of_order, 2u);
    EXPECT_EQ(c.mshr_out_of_order, 1u);
}

namespace {
CacheParams one_bank_direct_mapped() {
    CacheParams p;
    p.size_bytes = 4 * 64;  // 4 sets of one 64-byte way
    p.ways = 1;
    p.line_bytes = 64;
    p.hit_latency_cycles = 4;
    p.mshrs = 0;
    return p;
}
}  // namespace

// Write-back, write-allocate without a fetch: a written line is there for a later read and costs
// the next level nothing until it is evicted, when exactly its line goes down as one write.
TEST(CacheWrites, WriteBackAllocatesWithoutFetchAndWritesBackOnEviction) {
    test::FixedLatencyMemory mem(50);
    Cache c(sc_core::sc_gen_unique_name("c"), one_bank_direct_mapped(), &mem.up, kLevelL2);
    test::elaborate();
    // A write looks its line up like a read: bank at 0, tag at 0 + 4.
    EXPECT_EQ(c.write(0x1008, 8, 0), 4u);
    EXPECT_TRUE(c.contains(0x1000));
    EXPECT_TRUE(mem.addrs.empty());  // no fetch
    EXPECT_EQ(c.write_misses, 1u);
    // A read of it at 10 hits: 10 + 4.
    EXPECT_EQ(c.access(0x1000, 64, 10), 14u);
    EXPECT_EQ(c.hits, 1u);
    // A second write to the line hits it.
    c.write(0x1010, 8, 20);
    EXPECT_EQ(c.write_hits, 1u);
    EXPECT_TRUE(mem.write_addrs.empty());
    // A read of another line of the same set (4 sets of 64 bytes: 0x1100 is set 0 too) evicts
    // the dirty line: it goes down at the read's lookup (30 + 4), before the fill.
    EXPECT_EQ(c.access(0x1100, 64, 30), 30u + 4u + 50u);
    ASSERT_EQ(mem.write_addrs.size(), 1u);
    EXPECT_EQ(mem.write_addrs[0], 0x1000u);
    EXPECT_EQ(mem.write_times[0], 34u);
    EXPECT_EQ(mem.write_bytes, 64u);
    EXPECT_EQ(c.writebacks, 1u);
    EXPECT_EQ(c.writeback_bytes, 64u);
    // The line read in is clean: evicting it by a write writes nothing back.
    c.write(0x1200, 8, 100);
    EXPECT_EQ(mem.write_addrs.size(), 1u);
    // ...and the written line, evicted by a read, does.
    c.access(0x1300, 64, 200);
    ASSERT_EQ(mem.write_addrs.size(), 2u);
    EXPECT_EQ(mem.write_addrs[1], 0x1200u);
}

TEST(CacheWrites, WriteThroughSendsEveryWriteOnAndAllocatesNothing) {
    test::FixedLatencyMemory mem(50);
    CacheParams p = one_bank_direct_mapped();
    p.write_back = false;
    Cache c(sc_core::sc_gen_unique_name("c"), p, &mem.up, kLevelL2);
    test::elaborate();
    EXPECT_EQ(c.write(0x2008, 16, 7), 11u);
    EXPECT_FALSE(c.contains(0x2000));
    ASSERT_EQ(mem.write_addrs.size(), 1u);
    EXPECT_EQ(mem.write_addrs[0], 0x2008u);  // the write itself, as it came
    EXPECT_EQ(mem.write_times[0], 11u);      // once looked up
    EXPECT_EQ(mem.write_bytes, 16u);
    EXPECT_EQ(c.writebacks, 0u);
}

// A write takes its bank's lookup slot: a read to the same bank in the same cycle waits one.
TEST(CacheWrites, WritesTakeBankSlots) {
    test::FixedLatencyMemory mem(50);
    Cache c(sc_core::sc_gen_unique_name("c"), one_bank_direct_mapped(), &mem.up, kLevelL2);
    test::elaborate();
    c.write(0x3000, 8, 0);
    // The line is there from the write's lookup (4); the read's lookup ends at 1 + 4.
    EXPECT_EQ(c.access(0x3000, 64, 0), 5u);
    EXPECT_EQ(c.bank_conflict_cycles, 1u);
}

// Writes cross the crossbar on a link of their own: a line coming back from the L2 does not
// wait for write data, and write data waits only for other writes.
TEST(CacheWrites, CrossbarCarriesWritesOnTheirOwnLink) {
    test::FixedLatencyMemory l2(30);
    Crossbar x(sc_core::sc_gen_unique_name("x"), 16.0, &l2.up);
    test::elaborate();
    // 64 bytes at 16 per cycle: 4 cycles; a second write right behind the first waits for it.
    x.write(0x100, 64, 0);
    x.write(0x200, 64, 0);
    ASSERT_EQ(l2.write_times.size(), 2u);
    EXPECT_EQ(l2.write_times[0], 4u);
    EXPECT_EQ(l2.write_times[1], 8u);
    // A read returning at 30 crosses at once (30..34): the writes are on the other link.
    EXPECT_EQ(x.access(0x300, 64, 0), 34u);
    EXPECT_EQ(x.write_bytes, 128u);
    EXPECT_EQ(x.bytes, 64u);
}

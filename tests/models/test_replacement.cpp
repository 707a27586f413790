// Replacement policies registered by name: each against a deliberately simple reference model of
// the published algorithm, hit for hit, and on small sequences worked out by hand.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "fixed_memory.h"
#include "models/cache.h"
#include "models/calendar.h"
#include "models/registry.h"
#include "models/replacement.h"

using namespace rtsim;

namespace {

// Tree pseudo-LRU as textbooks draw it: per set a binary tree of booleans (true: the victim lies
// in the right half), nodes numbered from 1 in heap order, ways filled while any is empty.
class ReferencePlru {
  public:
    ReferencePlru(uint64_t sets, int ways) : sets_(sets), ways_(ways), set_(sets) {
        for (auto& s : set_) {
            s.lines.assign(size_t(ways), -1);
            s.right.assign(size_t(ways), false);
        }
    }
    bool access(int64_t line) {
        Set& s = set_[uint64_t(line) % sets_];
        for (int w = 0; w < ways_; ++w)
            if (s.lines[size_t(w)] == line) {
                touch(s, w);
                return true;
            }
        int victim = -1;
        for (int w = 0; w < ways_ && victim < 0; ++w)
            if (s.lines[size_t(w)] < 0) victim = w;
        if (victim < 0) {
            int node = 1;
            while (node < ways_) node = 2 * node + (s.right[size_t(node)] ? 1 : 0);
            victim = node - ways_;
        }
        s.lines[size_t(victim)] = line;
        touch(s, victim);
        return false;
    }

  private:
    struct Set {
        std::vector<int64_t> lines;
        std::vector<bool> right;
    };
    void touch(Set& s, int way) {
        // Walk up from the leaf: each parent points to the other child.
        for (int node = ways_ + way; node > 1; node /= 2) s.right[size_t(node / 2)] = node % 2 == 0;
    }
    uint64_t sets_;
    int ways_;
    std::vector<Set> set_;
};

// SRRIP-HP exactly as Jaleel et al. (ISCA 2010) state it: hit -> RRPV 0; miss -> search from way
// 0 for RRPV 2^M - 1, and if none, increment every RRPV and search again; insert at 2^M - 2.
class ReferenceSrrip {
  public:
    ReferenceSrrip(uint64_t sets, int ways, int bits)
        : sets_(sets), ways_(ways), max_((1 << bits) - 1), set_(sets) {
        for (auto& s : set_) {
            s.lines.assign(size_t(ways), -1);
            s.rrpv.assign(size_t(ways), 0);
        }
    }
    bool access(int64_t line) {
        Set& s = set_[uint64_t(line) % sets_];
        for (int w = 0; w < ways_; ++w)
            if (s.lines[size_t(w)] == line) {
                s.rrpv[size_t(w)] = 0;
                return true;
            }
        int victim = -1;
        for (int w = 0; w < ways_ && victim < 0; ++w)
            if (s.lines[size_t(w)] < 0) victim = w;
        while (victim < 0) {
            for (int w = 0; w < ways_ && victim < 0; ++w)
                if (s.rrpv[size_t(w)] == max_) victim = w;
            if (victim < 0)
                for (int& r : s.rrpv) ++r;
        }
        s.lines[size_t(victim)] = line;
        s.rrpv[size_t(victim)] = max_ - 1;
        return false;
    }

  private:
    struct Set {
        std::vector<int64_t> lines;
        std::vector<int> rrpv;
    };
    uint64_t sets_;
    int ways_, max_;
    std::vector<Set> set_;
};

CacheParams params(const std::string& policy, int ways, uint64_t sets) {
    CacheParams p;
    p.replacement = policy;
    p.ways = ways;
    p.line_bytes = 64;
    p.size_bytes = uint64_t(ways) * 64 * sets;
    return p;
}

// Hits of `lines` (line numbers) accessed one by one, far apart in time.
std::vector<bool> hits_of(const CacheParams& p, const std::vector<int64_t>& lines) {
    test::fresh_kernel();
    test::FixedLatencyMemory mem(50);
    Cache c(sc_core::sc_gen_unique_name("c"), p, &mem.up);
    test::elaborate();
    TimeFloor floor;  // requests come in time order: the banks forget what is behind
    c.follow(&floor);
    std::vector<bool> out;
    Cycle t = 0;
    for (int64_t line : lines) {
        const uint64_t before = c.hits;
        floor.cycle = t += 1000;  // fills complete between accesses: pure hit/miss behaviour
        c.access(uint64_t(line) * 64, 64, t);
        out.push_back(c.hits > before);
    }
    return out;
}

// A stream with a hot region (hits), a cold sweep (capacity and conflict misses) and reuse at
// medium distance (where the policies disagree).
std::vector<int64_t> mixed_stream(uint64_t seed, int64_t hot, int64_t cold, size_t n) {
    std::mt19937_64 rng(seed);
    std::vector<int64_t> out;
    int64_t sweep = 0;
    for (size_t i = 0; i < n; ++i) {
        const auto r = rng() % 10;
        if (r < 5 || out.empty())
            out.push_back(int64_t(rng() % uint64_t(hot)));
        else if (r < 8)
            out.push_back(hot + (sweep++ % cold));
        else
            out.push_back(out[size_t(rng() % out.size())]);
    }
    return out;
}

}  // namespace

TEST(Replacement, TreePlruEqualsReferenceModel) {
    // Every set layout the hot paths compile (4, 8, 16 ways) and ones read at run time.
    for (int ways : {1, 2, 4, 8, 16, 32, 64})
        for (uint64_t sets : {1, 8}) {
            const auto p = params("tree_plru", ways, sets);
            const auto lines = mixed_stream(uint64_t(ways) * 31 + sets, int64_t(sets) * ways,
                                            int64_t(sets) * ways * 3, 20000);
            ReferencePlru ref(sets, ways);
            const auto got = hits_of(p, lines);
            size_t hits = 0;
            for (size_t i = 0; i < lines.size(); ++i) {
                ASSERT_EQ(got[i], ref.access(lines[i]))
                    << ways << " ways, " << sets << " sets, access " << i;
                hits += got[i];
            }
            EXPECT_GT(hits, 0u);
            EXPECT_LT(hits, lines.size());
        }
}

TEST(Replacement, SrripEqualsReferenceModel) {
    for (int bits : {1, 2, 3})
        for (int ways : {1, 2, 3, 4, 8, 12, 16}) {
            const uint64_t sets = 4;
            auto p = params("srrip", ways, sets);
            p.rrpv_bits = bits;
            const auto lines =
                mixed_stream(uint64_t(ways) * 7 + uint64_t(bits), 4 * ways, 12 * ways, 20000);
            ReferenceSrrip ref(sets, ways, bits);
            const auto got = hits_of(p, lines);
            for (size_t i = 0; i < lines.size(); ++i)
                ASSERT_EQ(got[i], ref.access(lines[i]))
                    << ways << " ways, " << bits << " bits, access " << i;
        }
}

// One set of four ways: A B C D fill it, A and B are hit, a scan E F G H of lines used once
// passes, then A and B come back. Worked by hand: LRU has evicted all four; SRRIP (2 bits)
// inserts the scan at RRPV 2, ages A and B (RRPV 0) only up to 2, and evicts C, D, E, F, so A
// and B both hit.
TEST(Replacement, SrripKeepsReusedLinesThroughAScanWhereLruDoesNot) {
    const std::vector<int64_t> seq = {0, 1, 2, 3, 0, 1, 4, 5, 6, 7, 0, 1};
    const auto srrip = hits_of(params("srrip", 4, 1), seq);
    const auto lru = hits_of(params("lru", 4, 1), seq);
    EXPECT_TRUE(srrip[10] && srrip[11]);
    EXPECT_FALSE(lru[10] || lru[11]);
}

// One set of four ways: A B C D, A hit, then E. Worked by hand: the tree's bits point to C's
// pair after A's hit (LRU would evict B, the least recently used); so B still hits, C misses.
TEST(Replacement, TreePlruEvictsByItsTreeNotByExactAge) {
    const auto plru_b = hits_of(params("tree_plru", 4, 1), {0, 1, 2, 3, 0, 4, 1});
    const auto plru_c = hits_of(params("tree_plru", 4, 1), {0, 1, 2, 3, 0, 4, 2});
    const auto lru_b = hits_of(params("lru", 4, 1), {0, 1, 2, 3, 0, 4, 1});
    EXPECT_TRUE(plru_b[6]);
    EXPECT_FALSE(plru_c[6]);
    EXPECT_FALSE(lru_b[6]);
}

TEST(Replacement, RegistryListsEveryPolicyAndRefusesUnknownOnes) {
    EXPECT_EQ(ComponentIndex::names("replacement"),
              (std::vector<std::string>{"fifo", "lru", "random", "srrip", "tree_plru"}));
    for (const auto& info : ComponentIndex::all().at("replacement")) {
        EXPECT_FALSE(info.description.empty()) << info.name;
        EXPECT_NE(ReplacementRegistry::find(info.name), nullptr);
    }
    EXPECT_THROW(ReplacementRegistry::at("belady"), std::invalid_argument);
    test::FixedLatencyMemory mem(50);
    EXPECT_THROW(Cache("bad_policy", params("mru", 4, 4), &mem.up), std::invalid_argument);
    EXPECT_THROW(Cache("plru_12_ways", params("tree_plru", 12, 4), &mem.up), std::invalid_argument);
}

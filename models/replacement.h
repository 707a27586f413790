// Cache replacement policies: one file each under models/replacement/, registered by name.
//
// A policy is a type with three static hooks, compiled into the cache's hot paths (a template
// instance per policy and set layout, resolved once when the cache is built: no virtual call per
// hit). Each way of a set has one 32-bit word of policy state (`words`, zero at start):
//
//     template <int G> static void hit(uint32_t* words, int way, ReplacementState& s);
//     template <int G> static void filled(uint32_t* words, int way, ReplacementState& s);
//     template <int G> static int victim(const uint32_t* tags, uint32_t* words,
//                                        ReplacementState& s);
//
// G is the set layout (G > 0: 4 * G ways known at compile time; 0: s.ways at run time; see
// ways_of). `victim` is asked only for a set about to be filled; `tags` holds kNoTag for an
// invalid way, which every policy fills first. A policy file ends with
//
//     RTSIM_REGISTER(ReplacementEntry, {"name", "description", {params}, &Cache::use_policy<P>})
#pragma once

#include <algorithm>
#include <cstdint>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include <string>
#include <vector>

#include "models/registry.h"

namespace rtsim {

class Cache;
struct CacheParams;

// Per cache: what its policy shares over all sets.
struct ReplacementState {
    static constexpr uint32_t kNoTag = ~uint32_t(0);
    int ways = 0;
    int rrpv_bits = 2;                     // SRRIP: bits of a re-reference prediction value
    uint32_t clock = 0;                    // LRU and FIFO: the last stamp given
    uint64_t rng = 0x9E3779B97F4A7C15ull;  // random: deterministic xorshift state
    // Where the sets' words are: set k's at words_base + k * stride_words.
    uint32_t* words_base = nullptr;
    uint64_t stride_words = 0;
    uint64_t sets = 0;

    // A stamp later than every stamp given before. Stamps only order the ways of a set:
    // before the 32-bit counter wraps they are replaced by their rank within the set, which
    // keeps every decision and frees the counter for another four billion uses.
    uint32_t next_stamp() {
        if (__builtin_expect(clock == ~uint32_t(0), 0)) renumber_stamps();
        return ++clock;
    }
    // Out of line: inlined, its sort made every lookup save and restore six registers.
    [[gnu::noinline, gnu::cold]] void renumber_stamps() {
        const auto n = size_t(ways);
        std::vector<size_t> order(n);
        for (uint64_t set = 0; set < sets; ++set) {
            uint32_t* st = words_base + set * stride_words;
            for (size_t w = 0; w < n; ++w) order[w] = w;
            std::sort(order.begin(), order.end(),
                      [&](size_t a, size_t b) { return st[a] < st[b]; });
            uint32_t rank = 0;
            for (size_t w : order) st[w] = st[w] == 0 ? 0 : ++rank;  // invalid ways keep 0
        }
        clock = uint32_t(ways);
    }
    uint64_t next_random() {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        return rng;
    }
};

// A set's associativity: 4 * G at compile time, or the configured one (G = 0).
template <int G>
[[gnu::always_inline]] inline int ways_of(const ReplacementState& s) {
    return G ? 4 * G : s.ways;
}

// The first invalid way of a set, or -1.
template <int G>
[[gnu::always_inline]] inline int first_invalid_way(const uint32_t* tags,
                                                    const ReplacementState& s) {
    for (int w = 0; w < ways_of<G>(s); ++w)
        if (tags[w] == ReplacementState::kNoTag) return w;
    return -1;
}

#ifdef __SSE2__
// The first way of the least stamp among the 4 * kGroups stamps at `age` (16-byte aligned).
template <int kGroups>
[[gnu::always_inline]] inline int least_stamp_in_groups(const uint32_t* age) {
    // SSE2 compares signed 32-bit lanes: flip the sign bit to order unsigned stamps.
    const __m128i bias = _mm_set1_epi32(int(0x80000000u));
    const auto load = [&](int g) {
        return _mm_xor_si128(_mm_load_si128(reinterpret_cast<const __m128i*>(age + 4 * g)), bias);
    };
    const auto min4 = [](__m128i a, __m128i b) {
        const __m128i a_greater = _mm_cmpgt_epi32(a, b);
        return _mm_or_si128(_mm_and_si128(a_greater, b), _mm_andnot_si128(a_greater, a));
    };
    __m128i least = load(0);
    for (int g = 1; g < kGroups; ++g) least = min4(least, load(g));
    least = min4(least, _mm_shuffle_epi32(least, 0x4E));  // swap halves
    least = min4(least, _mm_shuffle_epi32(least, 0xB1));  // swap neighbours
    uint32_t at = 0;
    for (int g = 0; g < kGroups; ++g)
        at |= uint32_t(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(load(g), least))))
              << (4 * g);
    return __builtin_ctz(at);
}
#endif

// The way with the least stamp (the first of equals): LRU's and FIFO's victim. Invalid ways
// have stamp 0 and valid ones a later stamp, so it is the first invalid way when there is one.
template <int G>
[[gnu::always_inline]] inline int least_stamp_way(const uint32_t* age, const ReplacementState& s) {
#ifdef __SSE2__
    if constexpr (G > 0) return least_stamp_in_groups<G>(age);
#endif
    // Branch-free: which way is oldest is unpredictable.
    int victim = 0;
    uint32_t oldest = age[0];
    for (int w = 1; w < ways_of<G>(s); ++w) {
        const bool older = age[w] < oldest;
        oldest = older ? age[w] : oldest;
        victim = older ? w : victim;
    }
    return victim;
}

// Ways ordered by stamps from the cache's clock, the least stamp leaving: the base of LRU (which
// stamps every use) and FIFO (which stamps fills only).
struct StampOrder {
    template <int G>
    static void filled(uint32_t* words, int way, ReplacementState& s) {
        words[way] = s.next_stamp();
    }
    template <int G>
    static int victim(const uint32_t*, uint32_t* words, ReplacementState& s) {
        return least_stamp_way<G>(words, s);
    }
};

// A replacement policy's registration: `bind` compiles the cache's hot paths for it; `check`
// (optional) says why a cache's geometry does not suit it (empty: it does).
struct ReplacementEntry {
    static constexpr const char* kKind = "replacement";
    std::string name, description;
    std::vector<std::string> params;
    void (*bind)(Cache&) = nullptr;
    std::string (*check)(int ways) = nullptr;
};
using ReplacementRegistry = Registry<ReplacementEntry>;

}  // namespace rtsim

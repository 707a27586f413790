// Tree pseudo-LRU: a binary tree of ways - 1 bits per set, each pointing to the half that was
// used less recently; a use turns every bit on its way's path to point away from it, the victim
// is found by following the bits from the root. One bit per way instead of a stamp per way, as
// in most hardware caches; it approximates LRU (the victim is never the most recently used way).
//
// Node n (1 .. ways - 1, heap order: children 2n and 2n + 1) keeps its bit in word n / 32, bit
// n % 32 of the set's words (ways words of 32 bits: room for any tree). Bit 0: the victim lies
// left. Leaf way w is node ways + w.
#include "models/cache_impl.h"

namespace rtsim {
namespace {

struct TreePlru {
    static bool bit(const uint32_t* words, int node) {
        return (words[node >> 5] >> (node & 31)) & 1;
    }
    static void set_bit(uint32_t* words, int node, bool v) {
        const uint32_t mask = uint32_t(1) << (node & 31);
        words[node >> 5] = v ? words[node >> 5] | mask : words[node >> 5] & ~mask;
    }
    // Every node on the path to `way` points away from it.
    template <int G>
    static void touch(uint32_t* words, int way, const ReplacementState& s) {
        for (int n = ways_of<G>(s) + way; n > 1; n >>= 1) set_bit(words, n >> 1, (n & 1) == 0);
    }
    template <int G>
    static void hit(uint32_t* words, int way, ReplacementState& s) {
        touch<G>(words, way, s);
    }
    template <int G>
    static void filled(uint32_t* words, int way, ReplacementState& s) {
        touch<G>(words, way, s);
    }
    template <int G>
    static int victim(const uint32_t* tags, uint32_t* words, ReplacementState& s) {
        const int invalid = first_invalid_way<G>(tags, s);
        if (invalid >= 0) return invalid;
        const int ways = ways_of<G>(s);
        int n = 1;
        while (n < ways) n = 2 * n + int(bit(words, n));
        return n - ways;
    }
};

std::string power_of_two_ways(int ways) {
    return ways > 0 && (ways & (ways - 1)) == 0
               ? std::string()
               : "needs a power-of-two number of ways (a full binary tree), got " +
                     std::to_string(ways);
}

}  // namespace

RTSIM_REGISTER(ReplacementEntry,
               {"tree_plru",
                "tree pseudo-LRU: ways - 1 bits per set point away from recent uses "
                "(power-of-two ways)",
                {},
                &Cache::use_policy<TreePlru>,
                &power_of_two_ways})

}  // namespace rtsim

// Least recently used: every use stamps its way with a rising clock; the oldest stamp leaves.
#include "models/cache_impl.h"

namespace rtsim {
namespace {

struct Lru {
    template <int G>
    static void hit(uint32_t* words, int way, ReplacementState& s) {
        words[way] = s.next_stamp();
    }
    template <int G>
    static void filled(uint32_t* words, int way, ReplacementState& s) {
        words[way] = s.next_stamp();
    }
    template <int G>
    static int victim(const uint32_t*, uint32_t* words, ReplacementState& s) {
        return least_stamp_way<G>(words, s);
    }
};

}  // namespace

RTSIM_REGISTER(ReplacementEntry, {"lru",
                                  "least recently used (exact, per-way use stamps)",
                                  {},
                                  &Cache::use_policy<Lru>})

}  // namespace rtsim

// Least recently used: every use stamps its way with a rising clock; the oldest stamp leaves.
#include "models/cache_impl.h"

namespace rtsim {
namespace {

struct Lru : StampOrder {
    template <int G>
    static void hit(uint32_t* words, int way, ReplacementState& s) {
        words[way] = s.next_stamp();
    }
};

}  // namespace

RTSIM_REGISTER(ReplacementEntry, {"lru",
                                  "least recently used (exact, per-way use stamps)",
                                  {},
                                  &Cache::use_policy<Lru>})

}  // namespace rtsim

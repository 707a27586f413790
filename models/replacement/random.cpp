// Pseudo-random: an invalid way if there is one, else a way drawn from a per-cache xorshift
// generator with a fixed seed, so runs are repeatable.
#include "models/cache_impl.h"

namespace rtsim {
namespace {

struct Random {
    template <int G>
    static void hit(uint32_t*, int, ReplacementState&) {}
    template <int G>
    static void filled(uint32_t*, int, ReplacementState&) {}
    template <int G>
    static int victim(const uint32_t* tags, uint32_t*, ReplacementState& s) {
        const int invalid = first_invalid_way<G>(tags, s);
        if (invalid >= 0) return invalid;
        return int(s.next_random() % uint64_t(ways_of<G>(s)));
    }
};

}  // namespace

RTSIM_REGISTER(ReplacementEntry, {"random",
                                  "pseudo-random victim (deterministic xorshift, fixed seed)",
                                  {},
                                  &Cache::use_policy<Random>})

}  // namespace rtsim

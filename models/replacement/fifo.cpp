// First in, first out: a way is stamped when it is filled; hits leave the order as it is.
#include "models/cache_impl.h"

namespace rtsim {
namespace {

struct Fifo {
    template <int G>
    static void hit(uint32_t*, int, ReplacementState&) {}
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

RTSIM_REGISTER(ReplacementEntry, {"fifo",
                                  "first in, first out (the line filled first leaves)",
                                  {},
                                  &Cache::use_policy<Fifo>})

}  // namespace rtsim

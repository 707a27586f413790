// First in, first out: a way is stamped when it is filled; hits leave the order as it is.
#include "models/cache_impl.h"

namespace rtsim {
namespace {

struct Fifo : StampOrder {
    template <int G>
    static void hit(uint32_t*, int, ReplacementState&) {}
};

}  // namespace

RTSIM_REGISTER(ReplacementEntry, {"fifo",
                                  "first in, first out (the line filled first leaves)",
                                  {},
                                  &Cache::use_policy<Fifo>})

}  // namespace rtsim

// l1.prefetcher / l2.prefetcher = none (the default): demand misses only.
#include "models/prefetcher.h"

namespace rtsim {

RTSIM_REGISTER(PrefetcherEntry,
               {"none", "no prefetcher: lines are fetched on demand only", {}, nullptr})

}  // namespace rtsim

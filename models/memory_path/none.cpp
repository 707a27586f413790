// memory_path.below_l1 / below_l2 = none (the default): the levels connect directly.
#include "models/memory_block.h"

namespace rtsim {

RTSIM_REGISTER(MemoryBlockEntry,
               {"none", "no block: the levels on either side connect directly", {}, nullptr})

}  // namespace rtsim

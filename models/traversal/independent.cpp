// The baseline: a core takes rays one by one from the work source and runs each to its end.
#include "models/traversal_mode.h"

namespace rtsim {

RTSIM_REGISTER(TraversalModeEntry,
               {"independent", "a core takes rays one by one and runs each to its end", {}})

}  // namespace rtsim

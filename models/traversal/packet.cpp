// Ray packets on SIMD lanes: consecutive rays of one kind traverse as one packet in lockstep; a
// node or triangle is fetched once for the packet and every operation occupies packet_size
// lanes, active or not. The packet tracer makes the steps, so it needs rays generated on the fly.
#include "models/traversal_mode.h"

namespace rtsim {

RTSIM_REGISTER(TraversalModeEntry,
               {"packet",
                "consecutive rays of one kind traverse in lockstep on packet_size SIMD lanes",
                {"packet_size"},
                /*ray_buffer=*/false,
                /*needs_treelets=*/false,
                /*packets=*/true,
                /*replays_traces=*/false})

}  // namespace rtsim

// Treelet queues (Aila & Karras 2010; Kopta et al. 2015, STRaTA): every ray in flight waits in
// the ray buffer, queued by the treelet it needs next; a core takes a batch of one treelet,
// optionally loads it whole, and runs the rays until each leaves it.
#include "models/traversal_mode.h"

namespace rtsim {

RTSIM_REGISTER(TraversalModeEntry,
               {"treelet",
                "rays queue per treelet in the ray buffer; cores take a treelet's rays in batches",
                {"treelet_scheduler", "treelet_max_wait_batches", "treelet_batch_rays",
                 "treelet_prefetch", "treelet_cache_kib", "treelet_cache_latency_cycles",
                 "ray_buffer.capacity_rays", "ray_buffer.ray_bytes", "ray_buffer.ports",
                 "ray_buffer.latency_cycles", "bvh.treelet_bytes"},
                /*ray_buffer=*/true,
                /*needs_treelets=*/true,
                /*packets=*/false,
                /*replays_traces=*/true,
                /*l1_in_order=*/false})

}  // namespace rtsim

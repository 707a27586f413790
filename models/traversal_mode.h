// Traversal modes, registered by name (traversal.mode; `rtsim list`): how rays go through the
// cores. A mode is described by what the chip must build and allow for it; the cores' behaviour
// in each mode is in models/core.cpp.
#pragma once

#include <string>
#include <vector>

#include "models/registry.h"

namespace rtsim {

struct TraversalModeEntry {
    static constexpr const char* kKind = "traversal_mode";
    std::string name, description;
    std::vector<std::string> params;  // traversal.* fields it reads
    bool ray_buffer = false;          // rays wait in the treelet ray buffer between batches
    bool needs_treelets = false;      // the BVH must be cut into treelets (bvh.treelet_bytes)
    bool packets = false;             // rays traverse in packets of traversal.packet_size
    bool replays_traces = true;       // a recorded trace can drive it (per-ray step streams)
    // A core's L1 lookups follow its one in-order issue port (false where a batch's treelet
    // load, at the batch's start, may come after a lookup issued just before it).
    bool l1_in_order = true;
};
using TraversalModeRegistry = Registry<TraversalModeEntry>;

}  // namespace rtsim

// A frame's L2 misses counted functionally, unit by unit, for the skip design's estimates
// (sim/sampling/sampler.h): the profile's tile lines (each tile's distinct lines, in the order its
// rays first fetched them, tile after tile in frame order) run through an LRU cache of the L2's
// geometry, counting each miss in the unit of the tile that made it. The units' L1 misses are
// estimated here too, over per-core L1s (FunctionalL1, below).
//
// Why: a frame whose lines outgrow the L2 (Cornell diffuse and 2-bounce path frames, 1080p)
// takes 70-85% of its DRAM traffic in capacity misses, which the sampled runs regressed on the
// rays' work and erred by 5-6% at 1 in 20. The functional count of a whole 1080p frame came
// within 0.14% of the detailed model's L2 misses on four such frames (Cornell diffuse 112,420
// against 112,314; bunny 2-bounce path 63,575 against 63,559), so the sampled run takes the
// capacity misses as known and estimates only their small difference from the detailed model's
// (sim/sampling/sampler.cpp, counter_estimates).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sim/sampling/frame_profile.h"

namespace rtsim {

struct FunctionalL2 {
    // Per unit of the profile: the misses of lines that some earlier tile of the frame had
    // already fetched (capacity and conflict misses; a line's first fetch in the frame is a
    // compulsory miss, which the profile's new lines count).
    std::vector<uint32_t> unit_capacity_misses;
    uint64_t misses = 0;           // the frame's, compulsory ones included
    uint64_t capacity_misses = 0;  // the frame's, the sum of the units'
    double seconds = 0;            // host time to count them (or load them)
    std::string cache;             // "off", "hit", "built", "rebuilt: why"
};

// The profile's line size must be the cache's (run.cpp profiles at the L2's line size); `sets`
// is a power of two, as the cache model's are (config validates), indexed by the line address's
// low bits as models/cache.h does.
FunctionalL2 functional_l2_misses(const FrameProfile& profile, uint64_t sets, uint32_t ways);

// functional_l2_misses through an on-disk cache in `dir` (empty, or a profile without a key:
// none), beside the profile it counts: keyed by the profile's key and the cache's sets and ways,
// checksummed, and an entry that is damaged or does not fit the profile is recounted and stored
// over, never used. A sweep over designs that share the L2 counts each frame once (45-75 ms for
// the 5.2 million tile lines of a 1080p Cornell 2-bounce path frame).
FunctionalL2 functional_l2_misses_cached(const FrameProfile& profile, uint64_t sets, uint32_t ways,
                                         const std::string& dir);

// A frame's L1 misses estimated functionally, unit by unit: where the chip's cycles follow its L1
// misses (a crossbar- or L2-bound chip), a unit's work says little of them. On a 1080p bunny
// frame (8 spp, 2-bounce diffuse) on 64 x 32 cores, whose crossbar was busy every cycle, a unit's
// cycles were within 4% of its L1 misses but 38% off their fit on its work.
//
// Which core runs which ray is decided by timing, so the count models it: of the R rays of a tile
// that fetch a line r times over the frame's C cores, about C (1 - (1 - 1/C)^r) cores fetch it
// (rays spread over the cores at random), here that many consecutive cores from one drawn per
// line and tile. Each core's L1 is an LRU cache of its geometry (sets, ways; a split L1's node
// and triangle caches each), fed the tile's lines in the order its rays first fetched them. What
// it leaves out (the order of fetches within a tile, the policy if not LRU, the cap of 127 rays
// per line) makes it a predictor of the units' misses, not a count of them: the sampler regresses
// on it (a unit's residual is what the interval covers) and never takes its total as known.
struct FunctionalL1 {
    std::vector<uint32_t> unit_misses;  // per unit of the profile (empty: over 2^32 accesses)
    uint64_t misses = 0;                // the frame's, the sum of the units'
    double seconds = 0;                 // host time to count them
};

// The profile's lines must be the L1's (the sampler counts only then); `sets` a power of two.
FunctionalL1 functional_l1_misses(const FrameProfile& profile, uint64_t cores, uint64_t sets,
                                  uint32_t ways, bool split);

}  // namespace rtsim

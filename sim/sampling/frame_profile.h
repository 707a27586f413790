// A frame's functional profile for sampled runs that skip tiles (sim.sample_fast_forward = skip,
// sim/sampling/sampler.h): per unit of tiles, what the functional tracer knows of its rays before
// timing (the regression's auxiliaries: work, first-touched lines, node steps, rays), and per tile
// the distinct lines its rays fetch, with how many of its rays fetched each. A skip run regresses
// on the units' auxiliaries as a run that traces every ray does, and loads the caches with the
// lines of each tile it skips, in tile order, without tracing it (sim/sampling/sampler.h): an LRU
// L2 then holds at each traced tile what it held in the full run, to the order of lines within a
// tile (the first fetches alone, without the reuses that keep a line recent, left bunny and Cornell
// diffuse frames' DRAM bytes 21-31% high). The profile
// depends on the frame and the BVH layout, not on the chip, so a sweep computes it once per frame
// (profile_frame_cached) and every design point reuses it.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "workloads/bvh.h"
#include "workloads/raygen.h"
#include "workloads/step.h"
#include "workloads/tile_queue.h"

namespace rtsim {

// Which lines of [base, end) rays have fetched, at line granularity: a ray's first touches of
// lines in the frame (compulsory misses, which DRAM traffic follows).
class LineTracker {
  public:
    LineTracker() = default;
    LineTracker(uint64_t base, uint64_t end, uint32_t line_bytes);
    // Calls f(k) for each line the step fetches that lies in the range (k: its index from the
    // range's start).
    template <class F>
    void for_each_line(const Step& s, F&& f) const {
        const uint64_t last = (s.addr + std::max<uint32_t>(s.size_bytes, 1) - 1) >> line_shift_;
        for (uint64_t line = s.addr >> line_shift_; line <= last; ++line) {
            const uint64_t k = line - first_line_;
            if (line >= first_line_ && k < lines_) f(k);
        }
    }
    // Marks the lines the step fetches; returns how many were not fetched before.
    uint64_t touch(const Step& s) {
        if (touched_.empty()) return 0;
        uint64_t fresh = 0;
        for_each_line(s, [&](uint64_t k) {
            const uint64_t bit = uint64_t(1) << (k % 64);
            fresh += (touched_[k / 64] & bit) == 0;
            touched_[k / 64] |= bit;
        });
        return fresh;
    }
    // The lines a step's fetch spans (as a cache of this line size counts its accesses).
    uint64_t lines_spanned(const Step& s) const {
        return ((s.addr + std::max<uint32_t>(s.size_bytes, 1) - 1) >> line_shift_) -
               (s.addr >> line_shift_) + 1;
    }
    uint32_t line_bytes() const { return uint32_t(1) << line_shift_; }
    // The byte address of line k of the range, and how many lines it has.
    uint64_t address(uint64_t k) const { return (first_line_ + k) << line_shift_; }
    uint64_t lines() const { return lines_; }

  private:
    uint64_t first_line_ = 0, line_shift_ = 6, lines_ = 0;
    std::vector<uint64_t> touched_;  // a bit per line of the range
};

// What a run knows of every ray before timing, summed over a unit: the sampled regression's
// auxiliaries, in the order they are fitted (sim/sampling/estimators.h).
enum AuxIndex { kAuxWork, kAuxNewLines, kAuxNodeSteps, kAuxRays, kAuxiliaries };
using AuxFigures = std::array<uint64_t, kAuxiliaries>;

// A ray's auxiliaries, marking its lines in `lines` (its new lines are the ones it fetched first).
inline AuxFigures ray_auxiliaries(const RayWork& work, LineTracker& lines) {
    AuxFigures a{};
    a[kAuxWork] = work.steps.size() + work.rays;
    a[kAuxRays] = work.rays;
    for (const Step& s : work.steps) {
        a[kAuxNodeSteps] += s.kind == StepKind::Node;
        a[kAuxNewLines] += lines.touch(s);
    }
    return a;
}

constexpr uint8_t kTileLineRays = 0x7f, kTileLineTriangle = 0x80;

struct FrameProfile {
    uint64_t unit_tiles = 0;
    uint32_t line_bytes = 0;
    uint64_t line_base = 0;         // byte address of line 0
    std::vector<AuxFigures> units;  // per unit of unit_tiles tiles
    // Per unit, over the lines new to the frame (fetched by no earlier tile), the tile's rays
    // that fetched each: how many rays wait on the unit's compulsory misses, which a count of
    // new lines does not say (one miss can stall a whole tile's rays). The sampler's regression
    // takes it in place of the new lines.
    std::vector<uint64_t> unit_new_line_rays;
    // (The per-tile arrays are views of the mapped entry on a cache hit.)
    MappableArray<uint32_t> tile_line_start;  // per tile and one more, where its lines start
    // Per tile, the line indices its rays fetch, each once, in the order they were first fetched,
    // and beside each, how many of the tile's rays fetched it (kTileLineRays, at most 127) and
    // whether it holds triangles (kTileLineTriangle).
    MappableArray<uint32_t> tile_lines;
    MappableArray<uint8_t> tile_line_info;
    MappableArray<uint32_t> tile_rays;  // per tile, its rays (those that fetch nothing too)
    // The frame's fetches: lines (at line_bytes) and bytes over every step of every ray, which
    // a core's L1 counts as its accesses and bytes requested.
    uint64_t fetch_lines = 0, fetch_bytes = 0;
    double seconds = 0;  // host time to compute (or load) it
    std::string cache;   // "off", "hit", "built", "rebuilt: why"
    std::string key;     // what its cache entry is keyed by (empty: not cached)
};

// Traces every tile of the frame (on `threads` threads, with `trace`: tracer_of a one-level BVH
// or of a scene of instances' two levels) and profiles it; lines of [base, end) at line_bytes.
FrameProfile profile_frame(const RayGenerator& gen, const TraceRays& trace, uint64_t unit_tiles,
                           uint64_t base, uint64_t end, uint32_t line_bytes, int threads);

// Sums the profile's units in runs of `merge` (its units become unit_tiles * merge tiles; the
// last may be short), and names the new size in its key, so that counts cached by the key (the
// functional L2's) are kept per unit size. A profile is computed per tile and merged to a run's
// units, which may depend on the chip (sim.sample_unit_slot_fills): one profile serves them all.
void merge_profile_units(FrameProfile& profile, uint64_t merge);

// The fewest tiles whose rays, at the mean over the tiles that have any (`tile_rays`: per tile),
// reach `rays` (at least 1). A unit's cycles run from the hand-out of its first ray to that of
// the next unit's, and while its rays go out the chip works on the rays in flight before it: a
// unit of about one fill of the chip's slots is timed by its predecessors' work. On 64 x 32
// cores (1080p bunny, 8 spp, 2-bounce diffuse) 4-tile units of about 2,000 rays left a residual
// of 32% of the mean unit's cycles on the units' own auxiliaries, 32-tile units 11%.
uint64_t unit_tiles_for_slot_fills(const MappableArray<uint32_t>& tile_rays, uint64_t rays);

// profile_frame through an on-disk cache in `dir` (empty: none), the BVH cache's folder. `key`
// names everything the profile depends on besides the unit and line sizes and the range (the
// scene's content, the BVH and its layout, the ray generator's settings); an entry whose
// checksum, key or structure is wrong is recomputed and stored over, never used.
FrameProfile profile_frame_cached(const RayGenerator& gen, const TraceRays& trace,
                                  uint64_t unit_tiles, uint64_t base, uint64_t end,
                                  uint32_t line_bytes, int threads, const std::string& key,
                                  const std::string& dir);

}  // namespace rtsim

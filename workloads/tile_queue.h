// Tiles of a frame generated several at a time on `threads` threads and handed on in frame order,
// their ray ids numbered through the frame (the tile's first ray follows the last tile's): the ray
// stream is the same for any thread count. A tile `want` refuses is never generated (a sampled run
// that skips most of the frame, sim/sampling/sampler.h).
#pragma once

#include <algorithm>
#include <functional>
#include <utility>
#include <vector>

#include "workloads/parallel.h"
#include "workloads/raygen.h"
#include "workloads/tracer.h"

namespace rtsim {

// Traces the rays of a tile the generator did not trace already (for their hits), so that every
// ray has its steps: the per_tile work of a TileQueue that feeds timing models.
// `Accel`: a Bvh, or a TwoLevelBvh.
template <class Accel>
void trace_untraced(const Accel& bvh, std::vector<GeneratedRay>& rays) {
    for (GeneratedRay& g : rays)
        if (!g.traced) {
            g.prim = trace_ray_recorded(bvh, g.ray, g.query, g.steps).prim;
            g.traced = true;
        }
}

// Work on a tile's rays, run on the thread that generated them.
using TraceRays = std::function<void(std::vector<GeneratedRay>&)>;
// trace_untraced through `bvh` (held by reference) as a TileQueue's per-tile work.
template <class Accel>
TraceRays tracer_of(const Accel& bvh) {
    return [&bvh](std::vector<GeneratedRay>& rays) { trace_untraced(bvh, rays); };
}

class TileQueue {
  public:
    // `per_tile` (optional) runs on the generating thread on each tile's rays, before they are
    // handed on (the run command traces them there).
    TileQueue(const RayGenerator& gen, int threads, TraceRays per_tile = {},
              std::function<bool(int)> want = {})
        : gen_(gen),
          threads_(std::max(1, threads)),
          per_tile_(std::move(per_tile)),
          want_(std::move(want)) {}

    // Appends the next tile's rays to `out`; false when every tile was handed on.
    bool next(std::vector<GeneratedRay>& out) {
        if (pos_ == ready_.size() && !generate()) return false;
        last_tile_ = indices_[pos_];
        std::vector<GeneratedRay>& tile = ready_[pos_++];
        for (GeneratedRay& g : tile) {
            g.id += next_id_;
            out.push_back(std::move(g));
        }
        next_id_ += uint32_t(tile.size());
        tile.clear();
        return true;
    }

    // Tiles handed on or skipped so far (progress).
    int tiles_handed_on() const { return last_tile_ + 1; }
    // The index of the tile next() handed on last.
    int last_tile() const { return last_tile_; }

  private:
    // The next threads_ x kTilesPerThread tiles (fewer at the end), a tile at a time to
    // whichever thread is free; on one thread, one tile (nothing to join: the first rays are
    // handed on as soon as their tile is traced).
    bool generate() {
        constexpr int kTilesPerThread = 8;  // a few ms of work between joins
        const int group = threads_ == 1 ? 1 : threads_ * kTilesPerThread;
        indices_.clear();
        for (; next_tile_ < gen_.tile_count() && int(indices_.size()) < group; ++next_tile_)
            if (!want_ || want_(next_tile_)) indices_.push_back(next_tile_);
        const size_t count = indices_.size();
        if (count == 0) return false;
        ready_.resize(count);
        pos_ = 0;
        parallel_blocks(count, 1, threads_, [&](size_t begin, size_t end) {
            for (size_t k = begin; k < end; ++k) {
                gen_.generate_tile(indices_[k], ready_[k]);
                if (per_tile_) per_tile_(ready_[k]);
            }
        });
        return true;
    }

    const RayGenerator& gen_;
    int threads_;
    TraceRays per_tile_;
    std::function<bool(int)> want_;
    int next_tile_ = 0;  // the first tile not generated (or skipped) yet
    int last_tile_ = -1;
    std::vector<int> indices_;                      // of the tiles in ready_
    uint32_t next_id_ = 0;                          // the id of the next ray handed on
    std::vector<std::vector<GeneratedRay>> ready_;  // generated; from pos_ on not handed on
    size_t pos_ = 0;
};

}  // namespace rtsim

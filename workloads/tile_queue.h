// Tiles of a frame generated several at a time on `threads` threads and handed on in frame order,
// their ray ids numbered through the frame (the tile's first ray follows the last tile's): the ray
// stream is the same for any thread count.
#pragma once

#include <algorithm>
#include <functional>
#include <utility>
#include <vector>

#include "workloads/parallel.h"
#include "workloads/raygen.h"

namespace rtsim {

class TileQueue {
  public:
    // `per_tile` (optional) runs on the generating thread on each tile's rays, before they are
    // handed on (the run command traces them there).
    TileQueue(const RayGenerator& gen, int threads,
              std::function<void(std::vector<GeneratedRay>&)> per_tile = {})
        : gen_(gen), threads_(std::max(1, threads)), per_tile_(std::move(per_tile)) {}

    // Appends the next tile's rays to `out`; false when every tile was handed on.
    bool next(std::vector<GeneratedRay>& out) {
        if (pos_ == ready_.size() && !generate()) return false;
        std::vector<GeneratedRay>& tile = ready_[pos_++];
        for (GeneratedRay& g : tile) {
            g.id += next_id_;
            out.push_back(std::move(g));
        }
        next_id_ += uint32_t(tile.size());
        tile.clear();
        return true;
    }

    int tiles_handed_on() const { return next_tile_ - int(ready_.size() - pos_); }

  private:
    // The next threads_ x kTilesPerThread tiles (fewer at the end), a tile at a time to
    // whichever thread is free.
    bool generate() {
        constexpr int kTilesPerThread = 8;  // a few ms of work between joins
        const int first = next_tile_,
                  count = std::min(threads_ * kTilesPerThread, gen_.tile_count() - next_tile_);
        if (count <= 0) return false;
        next_tile_ += count;
        ready_.resize(size_t(count));
        pos_ = 0;
        parallel_blocks(size_t(count), 1, threads_, [&](size_t begin, size_t end) {
            for (size_t k = begin; k < end; ++k) {
                gen_.generate_tile(first + int(k), ready_[k]);
                if (per_tile_) per_tile_(ready_[k]);
            }
        });
        return true;
    }

    const RayGenerator& gen_;
    int threads_;
    std::function<void(std::vector<GeneratedRay>&)> per_tile_;
    int next_tile_ = 0;                             // the first tile not generated yet
    uint32_t next_id_ = 0;                          // the id of the next ray handed on
    std::vector<std::vector<GeneratedRay>> ready_;  // generated; from pos_ on not handed on
    size_t pos_ = 0;
};

}  // namespace rtsim

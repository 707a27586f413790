// An on-disk cache of built BVHs. Sweeps run every point as its own process and architects rerun
// one scene under many configs; a large scene's SAH build then costs seconds per run for a tree
// that is the same each time. An entry is keyed by everything the build depends on: the scene's
// content (not its file name), the builder settings and the layout's record sizes and base
// address. A damaged, truncated, stale (older format) or mismatched entry is detected (checksum,
// key, structure) and rebuilt, never used.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "workloads/bvh.h"
#include "workloads/scene.h"

namespace rtsim {

// What the cache did for one build.
enum class BvhCacheOutcome : uint8_t {
    Off,      // no cache folder: built
    Hit,      // loaded a valid entry
    Built,    // no entry: built and stored
    Rebuilt,  // an entry was unusable (`why`): built and stored over it
};
const char* bvh_cache_outcome_name(BvhCacheOutcome o);

struct BvhCacheStatus {
    BvhCacheOutcome outcome = BvhCacheOutcome::Off;
    std::string path;  // the entry's file
    // With a cache folder: the entry's key, and the scene's content hash it was made from (a
    // run reuses both rather than hash a large scene's geometry again).
    uint64_t key = 0, scene_hash = 0;
    std::string why;     // for Rebuilt: what was wrong with the entry
    double seconds = 0;  // host time to load or build (and store)
};

// The cache folder runs use unless told otherwise: $RTSIM_BVH_CACHE if set ("off" disables it),
// else $XDG_CACHE_HOME/rtsim/bvh, else $HOME/.cache/rtsim/bvh; empty when none of these exists.
std::string default_bvh_cache_dir();

// The key of a build: a hash of the format version, the scene's content and counts, every
// BvhBuildOptions field the build reads, and the layout's sizes and base address.
uint64_t bvh_cache_key(const Scene& scene, const BvhBuildOptions& options,
                       const BvhLayout& layout_sizes);
// The same from the scene's content hash (Scene::content_hash) and counts.
uint64_t bvh_cache_key(uint64_t scene_hash, const Scene& scene, const BvhBuildOptions& options,
                       const BvhLayout& layout_sizes);

// build_bvh through the cache in `dir` (empty: no cache). The box datapath fields of `options`
// do not change the tree; they are taken from `options` whatever the entry holds. A folder that
// cannot be written only costs the store (a one-line warning), never the run. `scene_hash`:
// the scene's content hash if known (MeshCacheStatus), else it is computed.
Bvh build_bvh_cached(const Scene& scene, const BvhBuildOptions& options,
                     const BvhLayout& layout_sizes, const std::string& dir,
                     BvhCacheStatus* status = nullptr,
                     std::optional<uint64_t> scene_hash = std::nullopt);

}  // namespace rtsim

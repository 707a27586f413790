// Mesh files parsed once and cached beside the BVHs. A short run (a sampled frame, a sweep point)
// spends more reading its mesh than anything else before simulation: the 69,666-triangle bunny
// OBJ takes 55-73 ms through assimp against 25 ms to load its cached BVH. An entry is keyed by
// the file's bytes (a hash and the size), so an edited file misses rather than hitting a stale
// entry, and the same mesh under another name or folder hits. A damaged, truncated or
// mismatched entry is detected (checksum, key, indices in range) and the file parsed again and
// stored over it, never used.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "workloads/scene.h"

namespace rtsim {

struct MeshCacheStatus {
    std::string outcome = "off";  // off, hit, built, rebuilt: why, builtin
    double seconds = 0;           // host time to load the scene (parse or cache)
    // Scene::content_hash of the scene, when the cache knew it (stored with the entry: the BVH
    // cache's key needs it, and byte-wise FNV over a large mesh costs more than reading it).
    std::optional<uint64_t> scene_hash;
};

// load_scene through the cache in `dir` (empty: none; built-in scenes are never cached). A
// folder that cannot be written only costs the store (a one-line warning), never the run.
// With `instanced`, a file whose nodes share meshes keeps its instancing there (load_scene's
// overload; the Scene returned is then empty). Such files are never cached: an entry holds a
// flattened mesh, so a hit always means a file without shared meshes.
Scene load_scene_cached(const std::string& spec, const std::string& dir,
                        MeshCacheStatus* status = nullptr, InstancedScene* instanced = nullptr);

}  // namespace rtsim

// How much memory preparing a scene takes, and the refusal of one that would not fit: a clear
// error before the work starts, never the kernel's out-of-memory kill halfway through it.
#pragma once

#include <cstdint>
#include <string>

namespace rtsim {

// Peak bytes per unique triangle of loading a mesh and building its BVH (measured: a 1.42M
// triangle mesh peaked at 376 MB, 270 bytes per triangle, BVH2), and per instance of a scene
// file (a million instances of one small mesh peaked at 564 MB). Rounded up.
constexpr uint64_t kPrepareBytesPerTriangle = 300, kPrepareBytesPerInstance = 600;

// The bytes a run may use: RTSIM_MEMORY_LIMIT (bytes, or with a K, M, G or T suffix, powers of
// 1024) when set, else the memory the machine has available now (MemAvailable). `source`
// receives which ("RTSIM_MEMORY_LIMIT" or "available memory"). Throws InputError for a malformed
// RTSIM_MEMORY_LIMIT. 0: not known (no limit).
uint64_t memory_limit_bytes(std::string* source = nullptr);

// Throws InputError naming `what` when preparing `triangles` unique triangles and `instances`
// instances would need more than memory_limit_bytes(), giving the estimate and the limit.
void check_prepare_memory(const std::string& what, uint64_t triangles, uint64_t instances);

}  // namespace rtsim

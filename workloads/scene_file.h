// JSON scene files: meshes placed by instances, the way an application builds a DXR or Vulkan
// scene (docs/scenes.md). A file names its meshes (mesh files, or builtin scenes) and lists
// instances, each one placement, a grid of copies, or a seeded scatter of copies:
//
//   {"meshes": {"tree": "tree.off", "ground": "builtin:cornell"},
//    "instances": [
//      {"mesh": "ground", "scale": [10, 1, 10]},
//      {"mesh": "tree", "translate": [0, 1, 0], "rotate": [0, 1, 0, 30], "scale": 0.5,
//       "grid": {"count": [100, 1, 100], "spacing": [2, 0, 2]}},
//      {"mesh": "tree", "scatter": {"count": 10000, "seed": 7, "min": [-50, 0, -50],
//       "max": [50, 0, 50], "scale": [0.5, 1.5], "rotate_y": true}, "opaque": false}]}
//
// A placement is translate * rotate (axis, degrees) * scale, or a row-major 3x4 "transform";
// a grid or scatter copy adds its own offset (and a scatter its yaw and scale) after it.
// A mesh may carry an alpha mask (workloads/alpha.h), which makes its instances non-opaque
// unless they say "opaque": true:
//
//   "meshes": {"leaves": {"file": "leaves.off", "alpha": {"pattern": "checker", "cells": 4}}}
#pragma once

#include <string>

#include "workloads/instances.h"

namespace rtsim {

// The most instances a file may make (grids and scatters included): a bound on what a typo in
// a count can ask of memory before the memory estimate is made.
constexpr uint64_t kMaxSceneFileInstances = 100'000'000;

// Reads a scene file; mesh paths are relative to the file's folder, and meshes are read through
// the mesh cache in `cache_dir` (empty: none). Throws InputError naming the file and the field at
// fault (`instances[3].grid.count`).
InstancedScene load_scene_file(const std::string& path, const std::string& cache_dir = "");

// Whether `spec` (a --scene value) names a scene file rather than a mesh: a .json path.
bool is_scene_file(const std::string& spec);

}  // namespace rtsim

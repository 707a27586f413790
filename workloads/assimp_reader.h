// The entry point of the assimp reader module (workloads/assimp_reader.cpp), which
// read_with_assimp (workloads/scene.cpp) loads with dlopen and finds by this name.
#pragma once

#include <string>

namespace rtsim {
struct Scene;
struct InstancedScene;
}  // namespace rtsim

// Reads the mesh file at `path`; false with assimp's message in `error` if it cannot be read.
// `shared` says whether nodes of the file share a mesh (a mesh with triangles placed by more than
// one node, as a glTF's two wheel nodes share the wheel). If they do and `instanced` is given,
// the file's instancing is kept there: each such mesh once, in object space, and one instance
// per node that places it (its global transform); `scene` is left as it was. Otherwise the
// triangles of every node's meshes, moved by the node's transform, are appended to `scene`.
extern "C" bool rtsim_assimp_read(const char* path, rtsim::Scene* scene,
                                  rtsim::InstancedScene* instanced, bool* shared,
                                  std::string* error);
using RtsimAssimpRead = decltype(&rtsim_assimp_read);
constexpr const char* kRtsimAssimpModule = "librtsim_assimp.so";

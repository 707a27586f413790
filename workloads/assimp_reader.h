// The entry point of the assimp reader module (workloads/assimp_reader.cpp), which
// read_with_assimp (workloads/scene.cpp) loads with dlopen and finds by this name.
#pragma once

#include <string>

namespace rtsim {
struct Scene;
}

// Appends the triangles of the mesh file at `path` to `scene`; false with assimp's message in
// `error` if it cannot be read.
extern "C" bool rtsim_assimp_read(const char* path, rtsim::Scene* scene, std::string* error);
using RtsimAssimpRead = decltype(&rtsim_assimp_read);
constexpr const char* kRtsimAssimpModule = "librtsim_assimp.so";

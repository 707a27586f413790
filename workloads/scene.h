// Triangle scenes: loaded from mesh files through assimp or built procedurally.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "workloads/geometry.h"
#include "workloads/mappable_array.h"

namespace rtsim {

struct Scene {
    std::string name;    // e.g. "bunny.obj" or "builtin:cornell"
    std::string source;  // path, or "builtin"
    // (Arrays of their own when read or made, views of the mapped entry on a mesh cache hit.)
    MappableArray<Vec3> vertices;
    // Triangles in the file's own order (polygons split into fans in file order).
    MappableArray<std::array<uint32_t, 3>> triangles;

    size_t triangle_count() const { return triangles.size(); }
    AABB bounds() const;
    AABB triangle_bounds(uint32_t prim) const;
    // FNV-1a over positions and indices: identifies the geometry for stats and traces.
    uint64_t content_hash() const;
    // Light vertex lookup for tracers.
    const Vec3& v(uint32_t prim, int corner) const { return vertices[triangles[prim][corner]]; }
};

struct InstancedScene;

// Loads "builtin:NAME" or a mesh file (OBJ, PLY, OFF, STL, anything assimp reads), flattened into
// one triangle list (every node's meshes moved by its transform).
// Throws InputError naming the file and the problem.
Scene load_scene(const std::string& spec);
// The same, except that a file whose nodes share meshes (a glTF's wheels) keeps its instancing
// when `instanced` is given: then it is filled (one mesh per shared or placed mesh, one instance
// per node placement; validated) and the Scene returned is empty. `shared` (optional) says
// whether the file's nodes share meshes at all.
Scene load_scene(const std::string& spec, InstancedScene* instanced, bool* shared);

// Format readers behind load_scene. OFF has its own reader (assimp rejects inline comments);
// everything else goes through assimp. Both keep the file's face order.
Scene read_off(const std::string& path);
void read_with_assimp(const std::string& path, Scene& out, InstancedScene* instanced = nullptr,
                      bool* shared = nullptr);

// Procedural scenes that need no file. Throws InputError for an unknown name.
Scene make_builtin_scene(const std::string& name);
std::vector<std::string> builtin_scene_names();

}  // namespace rtsim

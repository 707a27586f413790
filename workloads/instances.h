// Scenes as applications build them: meshes, each with a bottom-level BVH (BLAS), placed by
// instances (an affine transform of one mesh), with a top-level BVH (TLAS) over the instances'
// world boxes. Traversal enters a mesh through its instance's world-to-object transform: the ray
// is moved into object space, unnormalised, so a hit's distance is the same in both spaces and
// one bound serves the whole two-level traversal (as DXR, Vulkan and Embree define it).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "workloads/alpha.h"
#include "workloads/bvh.h"
#include "workloads/geometry.h"
#include "workloads/scene.h"
#include "workloads/tracer.h"

namespace rtsim {

// An affine map as a row-major 3x4 matrix [L | t]: p' = L p + t.
struct Affine3x4 {
    std::array<float, 12> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};

    float at(int row, int col) const { return m[size_t(row * 4 + col)]; }
    Vec3 point(Vec3 p) const {
        return {at(0, 0) * p.x + at(0, 1) * p.y + at(0, 2) * p.z + at(0, 3),
                at(1, 0) * p.x + at(1, 1) * p.y + at(1, 2) * p.z + at(1, 3),
                at(2, 0) * p.x + at(2, 1) * p.y + at(2, 2) * p.z + at(2, 3)};
    }
    Vec3 vector(Vec3 v) const {
        return {at(0, 0) * v.x + at(0, 1) * v.y + at(0, 2) * v.z,
                at(1, 0) * v.x + at(1, 1) * v.y + at(1, 2) * v.z,
                at(2, 0) * v.x + at(2, 1) * v.y + at(2, 2) * v.z};
    }
    double determinant() const;
};

// a * b: b applied first.
Affine3x4 compose(const Affine3x4& a, const Affine3x4& b);
// The inverse, computed in double and rounded once; false (out untouched) when the linear part
// is singular or not finite.
bool invert(const Affine3x4& a, Affine3x4& out);
// The box of the transformed corners of `b` (the tightest axis-aligned box of its image).
AABB transform_box(const Affine3x4& a, const AABB& b);

constexpr uint32_t kNoInstance = kInvalidPrim;  // Hit::instance of a miss or one level

struct Instance {
    Affine3x4 object_to_world;
    uint32_t mesh = 0;  // index into InstancedScene::meshes
    uint8_t mask = 0xff;
    // false: every candidate hit on the instance runs the any-hit shader with its mesh's alpha
    // mask (a mesh without one accepts all, the shader's cost still paid); true: hits are
    // committed at once (as DXR's FORCE_OPAQUE), whatever the mesh's mask.
    bool opaque = true;
};

struct InstancedScene {
    std::string name;    // e.g. "forest.json"
    std::string source;  // its path
    std::vector<Scene> meshes;
    std::vector<Instance> instances;
    // Per mesh, its alpha mask (workloads/alpha.h); meshes past its end have none.
    std::vector<AlphaMask> alpha;

    AlphaMask mesh_alpha(uint32_t mesh) const {
        return mesh < alpha.size() ? alpha[mesh] : AlphaMask();
    }
    // Without a mask anywhere, no alpha table: a scene of opaque meshes hashes as it did before
    // masks existed. (Inline: the assimp reader's module calls it too.)
    void drop_alpha_if_none() {
        for (const AlphaMask& a : alpha)
            if (a.pattern != AlphaPattern::None) return;
        alpha.clear();
    }
    uint64_t unique_triangle_count() const;
    uint64_t instanced_triangle_count() const;  // every instance's mesh, counted per instance
    AABB bounds() const;                        // of the instances' world boxes
    // FNV-1a over every mesh's content hash, every instance (transform, mesh, mask, flag) and
    // the alpha masks.
    uint64_t content_hash() const;
    // Throws InputError (naming the scene) for an instance of no mesh, an empty mesh, or a
    // transform that is singular or not finite.
    void validate() const;
};

// The two levels, with one address space: every inner node (the TLAS's first, then each BLAS's
// in mesh order) is numbered in one node range of the layout, every triangle in one slot range
// (with its alpha data, when any instance is not opaque, in a range of the same slots), and the
// instance records (the world-to-object transform, the BLAS root and the flags: 64 bytes,
// one per instance, in TLAS leaf order) have a region of their own, so a step's record index and
// address mean the same whichever BLAS it is in.
struct TwoLevelBvh {
    BvhBuildOptions options;
    Bvh tlas;               // leaves hold instance slots (tlas.prim_order: slot -> instance id)
    std::vector<Bvh> blas;  // per mesh
    std::vector<Affine3x4> world_to_object;                   // per instance id
    std::vector<Instance> instances;                          // per instance id
    std::vector<AlphaMask> alpha;                             // per mesh
    std::vector<uint32_t> blas_node_offset, blas_tri_offset;  // per mesh, in the global ranges
    uint32_t tlas_node_count = 0;
    uint64_t instance_base_addr = 0;
    uint32_t instance_size_bytes = 64;
    // The whole address space as one layout: node records [0, tlas_node_count) are the TLAS's,
    // then each BLAS's from its blas_node_offset; triangle slots from each BLAS's
    // blas_tri_offset; instance records in TLAS slot order. Steps of either level are made
    // from it, so the timing models, traces and caches see one layout.
    BvhLayout layout;
    const AABB& bounds() const { return tlas.bounds(); }
};

// Builds every mesh's BLAS and the TLAS with `options` (builder, width, node format, leaf size,
// treelets: each level is cut on its own, the TLAS's treelets holding their leaves' instance
// records, and the layout numbers them TLAS first); `layout_sizes` gives the
// node and triangle record sizes, as build_bvh's, and the alpha data's per triangle. With a
// `cache_dir`, each BLAS goes through the BVH cache there (workloads/bvh_cache.h), so a scene
// file's meshes are built once across runs; `blas_cache_hits` (optional) counts the BLASes
// read from it.
TwoLevelBvh build_two_level(const InstancedScene& scene, const BvhBuildOptions& options,
                            const BvhLayout& layout_sizes = BvhLayout(),
                            const std::string& cache_dir = "", size_t* blas_cache_hits = nullptr);

// Traces one ray through both levels: hit.prim is the triangle's index in its mesh and
// hit.instance the instance's (kNoInstance on a miss). `mask`: instances whose mask shares no
// bit with it are skipped, as DXR's InstanceInclusionMask. On a non-opaque instance, each
// triangle hit nearer than the best so far is a candidate its mesh's alpha mask accepts or
// ignores (counted in counters.any_hits), in traversal order and a leaf's slot order. counters add
// the work of both levels (each instance entered counts one box test, its BLAS root's box, kept in
// its record); max_stack is the TLAS's deepest stack (a BLAS's sits on top of it, as the steps'
// depths say).
Hit trace_ray(const TwoLevelBvh& bvh, const Ray& ray, HitQuery query, uint8_t mask = 0xff,
              TraceCounters* counters = nullptr);

// trace_ray with its steps in `steps` (replaced), in bvh.layout's numbering: the TLAS's node
// steps, an instance's transform step (its record fetched, the ray moved into object space) for
// each instance entered, then that BLAS's node and triangle steps, each candidate's triangle
// step followed by its any-hit step. A step's stack depth counts
// both levels' stacks (the TLAS's entries stay while a BLAS is traversed).
Hit trace_ray_recorded(const TwoLevelBvh& bvh, const Ray& ray, HitQuery query,
                       std::vector<Step>& steps, uint8_t mask = 0xff,
                       TraceCounters* counters = nullptr);

}  // namespace rtsim

// BVH2 built with binned SAH, and the byte layout the timing model fetches from.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "workloads/geometry.h"
#include "workloads/scene.h"

namespace rtsim {

// Traversal stacks are sized by this bound, which the builders guarantee.
constexpr uint32_t kMaxBvhDepth = 100;

struct BvhBuildOptions {
    int sah_buckets = 12;         // centroid buckets per axis; B-1 candidate planes are evaluated
    int max_leaf_size = 4;        // a leaf never holds more triangles than this
    float traversal_cost = 1.0f;  // SAH cost of visiting an inner node, relative to...
    float intersection_cost = 1.0f;  // ...the cost of one ray-triangle test
};

// Byte layout of the BVH in simulated memory. An inner node record holds both children's boxes
// and references (Aila & Laine 2009 style), so one fetch feeds one 2-wide box test; leaves live
// in their parent's record, and triangles are stored in leaf order at tri_base_addr.
struct BvhLayout {
    uint64_t node_base_addr = 0x10000000;
    uint32_t node_size_bytes = 64;
    uint64_t tri_base_addr = 0;
    uint32_t tri_size_bytes = 48;
    uint32_t inner_node_count = 0;
    uint32_t triangle_count = 0;

    uint64_t node_addr(uint32_t mem_index) const {
        return node_base_addr + uint64_t(mem_index) * node_size_bytes;
    }
    uint64_t tri_addr(uint32_t slot) const {
        return tri_base_addr + uint64_t(slot) * tri_size_bytes;
    }
    uint64_t node_bytes_total() const { return uint64_t(inner_node_count) * node_size_bytes; }
    uint64_t tri_bytes_total() const { return uint64_t(triangle_count) * tri_size_bytes; }
};

struct BvhNode {
    AABB box;
    // Inner node: child indices into Bvh::nodes. Leaf: first slot into Bvh::prim_order, count.
    uint32_t a = 0, b = 0;
    uint32_t prim_count = 0;  // 0 for inner nodes
    uint32_t mem_index = 0;   // inner nodes: record index in the layout (depth-first order)
    bool is_leaf() const { return prim_count != 0; }
};

struct BvhQuality {
    double sah_cost = 0;  // with the traversal and intersection costs of BvhBuildOptions
    uint32_t node_count = 0, inner_count = 0, leaf_count = 0, max_depth = 0;
    double mean_leaf_size = 0;
    uint64_t bytes = 0;  // nodes + triangles in the layout
    double build_seconds = 0;
};

struct Bvh {
    std::vector<BvhNode> nodes;        // nodes[0] is the root
    std::vector<uint32_t> prim_order;  // leaf slot -> scene primitive id
    BvhLayout layout;
    BvhBuildOptions options;
    BvhQuality quality;
    std::string builder = "sah";

    const AABB& bounds() const { return nodes[0].box; }
};

// Binned SAH BVH2 (Wald 2007 / pbrt's bucketed partition). Degenerate triangles are kept.
Bvh build_bvh_sah(const Scene& scene, const BvhBuildOptions& options,
                  const BvhLayout& layout_sizes);

// Recomputes quality figures from the finished tree (also used by tests).
BvhQuality measure_bvh(const Bvh& bvh);

}  // namespace rtsim

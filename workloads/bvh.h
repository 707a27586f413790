// Bounding volume hierarchies: binary builds (binned SAH, LBVH), collapsed to the BVH2/4/8 the
// tracer and the timing model use, and the byte layout the timing model fetches from.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "workloads/geometry.h"
#include "workloads/mappable_array.h"
#include "workloads/scene.h"
#include "workloads/step.h"

namespace rtsim {

// Traversal stacks are sized by this bound, which the builders guarantee.
constexpr uint32_t kMaxBvhDepth = 100;

enum class BvhBuilder : uint8_t {
    Sah,   // binned SAH, top-down (Wald 2007; pbrt's bucketed partition)
    Lbvh,  // Morton codes, radix sort, split at the highest differing bit (Karras 2012)
};
const char* bvh_builder_name(BvhBuilder b);
BvhBuilder parse_bvh_builder(const std::string& name, const std::string& what);  // InputError

enum class NodeFormat : uint8_t {
    Full,        // float child boxes
    Compressed,  // child boxes quantised to 8 bits per plane on a per-node grid (Ylitie et al.
                 // 2017)
};
const char* node_format_name(NodeFormat f);
NodeFormat parse_node_format(const std::string& name, const std::string& what);  // InputError

struct BvhBuildOptions {
    BvhBuilder builder = BvhBuilder::Sah;
    NodeFormat node_format = NodeFormat::Full;
    int restructure_passes = 0;   // treelet restructuring sweeps after the build (0: none)
    int width = 2;                // children per node after collapsing: 2, 4 or 8
    int sah_buckets = 12;         // centroid buckets per axis; B-1 candidate planes are evaluated
    int max_leaf_size = 4;        // a leaf never holds more triangles than this
    uint32_t treelet_bytes = 0;   // cut the tree into treelets of at most this (0: none)
    float traversal_cost = 1.0f;  // SAH cost of visiting an inner node, relative to...
    float intersection_cost = 1.0f;  // ...the cost of one ray-triangle test
    // Not build settings: the box unit's datapath (workloads/reduced_box.h), which decides the
    // boxes a traversal of this tree enters. 23 bits: fp32 (and no translation).
    int box_mantissa_bits = 23;
    bool box_translate_origin = true;
    // Nor is this: host threads of the SAH build (0: all); the tree is the same for any count.
    int build_threads = 0;
};

// Stated record size of an uncompressed node of `width` children: per child a 24-byte box and a
// 4-byte reference, rounded up to a power of two (64-byte cache-line multiples): 64, 128, 256.
uint32_t default_node_size_bytes(int width);
// Stated size of a compressed node: origin (12 bytes), 3 exponent bytes, an inner-child mask
// byte, child and triangle base indices (8), and per child 6 quantised planes and a meta byte,
// rounded up to 16 bytes: 48 (BVH2), 64 (BVH4), 80 (BVH8, as in Ylitie et al.).
uint32_t compressed_node_size_bytes(int width);

// Byte layout in simulated memory. An inner-node record holds all its children's boxes and
// references (Aila & Laine 2009 style), so one fetch feeds one box test of all children; leaves
// live in their parent's record, and triangles are stored in leaf order at tri_base_addr.
struct BvhLayout {
    uint64_t node_base_addr = 0x10000000;
    uint32_t node_size_bytes = 0;  // 0: default_node_size_bytes(width)
    uint64_t tri_base_addr = 0;
    uint32_t tri_size_bytes = 48;
    uint32_t inner_node_count = 0;
    uint32_t triangle_count = 0;
    // Two-level scenes (workloads/instances.h): the instance records, one per instance in TLAS
    // leaf order. None in a one-level layout.
    uint64_t instance_base_addr = 0;
    uint32_t instance_size_bytes = 64;
    uint32_t instance_count = 0;
    // Non-opaque geometry (workloads/alpha.h): per triangle slot, the alpha data an any-hit
    // shader reads (texture coordinates and alpha), alpha_size_bytes each (0: the shader reads
    // nothing). None (alpha_count 0) when every instance is opaque.
    uint64_t alpha_base_addr = 0;
    uint32_t alpha_size_bytes = 16;
    uint32_t alpha_count = 0;

    uint64_t node_addr(uint32_t node) const {
        return node_base_addr + uint64_t(node) * node_size_bytes;
    }
    uint64_t tri_addr(uint32_t slot) const {
        return tri_base_addr + uint64_t(slot) * tri_size_bytes;
    }
    uint64_t node_bytes_total() const { return uint64_t(inner_node_count) * node_size_bytes; }
    uint64_t tri_bytes_total() const { return uint64_t(triangle_count) * tri_size_bytes; }
    uint64_t instance_bytes_total() const { return uint64_t(instance_count) * instance_size_bytes; }
    uint64_t alpha_bytes_total() const { return uint64_t(alpha_count) * alpha_size_bytes; }
    // [begin, end) of the bytes traversal fetches: the node records, the triangles, the
    // instance records and the alpha data.
    uint64_t fetch_begin() const {
        uint64_t b = std::min(node_base_addr, tri_base_addr);
        if (instance_count) b = std::min(b, instance_base_addr);
        return alpha_bytes_total() ? std::min(b, alpha_base_addr) : b;
    }
    uint64_t fetch_end() const {
        uint64_t e =
            std::max(node_base_addr + node_bytes_total(), tri_base_addr + tri_bytes_total());
        if (instance_count) e = std::max(e, instance_base_addr + instance_bytes_total());
        return alpha_bytes_total() ? std::max(e, alpha_base_addr + alpha_bytes_total()) : e;
    }

    // Treelets (Aila & Karras 2010): the tree cut into connected pieces of at most
    // treelet_bytes (nodes plus their leaves' triangles), each stored as one contiguous run of
    // node records and one of triangle slots. Treelet k holds nodes [node_start[k],
    // node_start[k+1]) and slots [tri_start[k], tri_start[k+1]); both have a final sentinel.
    // Empty when the layout has no treelets: every record is in treelet 0.
    uint32_t treelet_bytes = 0;
    std::vector<uint32_t> treelet_node_start, treelet_tri_start;
    // Two-level layouts: treelet k also holds instance records [instance_start[k],
    // instance_start[k+1]) (the TLAS's treelets; a BLAS's hold none). Empty otherwise.
    std::vector<uint32_t> treelet_instance_start;
    uint32_t treelet_count() const {
        return treelet_node_start.empty() ? 1 : uint32_t(treelet_node_start.size() - 1);
    }
    // Fills the per-record lookups from the start tables; false if the tables are inconsistent
    // with the record counts (a damaged trace header).
    bool index_treelets();
    uint32_t node_treelet(uint32_t node) const {
        return node_treelet_.empty() ? 0 : node_treelet_[node];
    }
    uint32_t tri_treelet(uint32_t slot) const {
        return tri_treelet_.empty() ? 0 : tri_treelet_[slot];
    }

    // The records of one step kind: `count` of `size_bytes` each from `base_addr`, and their
    // treelets (nullptr: the layout has none). A reader decoding steps of mixed kinds keeps one
    // per kind and picks by index instead of branching on the kind.
    struct Records {
        uint64_t base_addr;
        uint32_t size_bytes, count;
        const uint32_t* treelets;
    };
    // The records of a step kind (a new kind adds its own here).
    Records records(StepKind kind) const {
        switch (kind) {
            case StepKind::Node:
                return {node_base_addr, node_size_bytes, inner_node_count,
                        node_treelet_.empty() ? nullptr : node_treelet_.data()};
            case StepKind::Triangle:
                return {tri_base_addr, tri_size_bytes, triangle_count,
                        tri_treelet_.empty() ? nullptr : tri_treelet_.data()};
            case StepKind::Transform:  // in the TLAS treelet whose leaf holds the instance
                return {instance_base_addr, instance_size_bytes, instance_count,
                        instance_treelet_.empty() ? nullptr : instance_treelet_.data()};
            default:  // alpha data: read in its triangle's treelet, not loaded with it
                return {alpha_base_addr, alpha_size_bytes, alpha_count,
                        tri_treelet_.empty() ? nullptr : tri_treelet_.data()};
        }
    }
    // The step on record `id` (below r.count) of `kind`, testing `items` (a node's children; 1
    // for a triangle): every Step from a layout is made here.
    static Step step(const Records& r, StepKind kind, uint32_t id, uint8_t items) {
        return {r.base_addr + uint64_t(id) * r.size_bytes,
                id,
                uint16_t(r.size_bytes),
                kind,
                items,
                r.treelets ? r.treelets[id] : 0};
    }
    Step node_step(uint32_t node, uint8_t children) const {
        return step(records(StepKind::Node), StepKind::Node, node, children);
    }
    Step tri_step(uint32_t slot) const {
        return step(records(StepKind::Triangle), StepKind::Triangle, slot, 1);
    }
    Step transform_step(uint32_t record) const {
        return step(records(StepKind::Transform), StepKind::Transform, record, 1);
    }
    Step any_hit_step(uint32_t slot) const {
        return step(records(StepKind::AnyHit), StepKind::AnyHit, slot, 1);
    }

  private:
    std::vector<uint32_t> node_treelet_, tri_treelet_, instance_treelet_;
};

// Binary tree, as builders produce it.
struct BinaryNode {
    AABB box;
    uint32_t a = 0, b = 0;    // inner: child indices; leaf: first slot in prim_order, unused
    uint32_t prim_count = 0;  // 0 for inner nodes
    bool is_leaf() const { return prim_count != 0; }
};
struct BinaryBvh {
    std::vector<BinaryNode> nodes;     // nodes[0] is the root
    std::vector<uint32_t> prim_order;  // leaf slot -> scene primitive id
};
BinaryBvh build_binary_sah(const Scene& scene, const BvhBuildOptions& options);
// Position in `nodes` of the inner node with the largest surface area, or -1 if all are leaves:
// the node a collapse or a treelet opens next (the one rays are most likely to enter).
int largest_inner_node(const BinaryBvh& bvh, const uint32_t* nodes, size_t count);
inline int largest_inner_node(const BinaryBvh& bvh, const std::vector<uint32_t>& nodes) {
    return largest_inner_node(bvh, nodes.data(), nodes.size());
}
BinaryBvh build_binary_lbvh(const Scene& scene, const BvhBuildOptions& options);
// Treelet restructuring (Karras & Aila 2013), `passes` bottom-up sweeps; returns the number of
// treelets rebuilt. Never increases the SAH cost.
int restructure_treelets(BinaryBvh& bvh, const BvhBuildOptions& options, int passes);

// A node of W children, boxes in structure-of-arrays form so that one box test of all children
// vectorises. Lanes [num, W) are empty (inverted boxes never hit).
template <int W>
struct alignas(64) WideNode {
    float lo_x[W], lo_y[W], lo_z[W], hi_x[W], hi_y[W], hi_z[W];
    uint32_t child[W];  // inner child: node index; leaf child: first triangle slot
    uint8_t count[W];   // 0: inner child; otherwise the leaf's triangle count
    uint8_t num;        // children in use

    AABB box(int lane) const {
        AABB b;
        b.lo = Vec3(lo_x[lane], lo_y[lane], lo_z[lane]);
        b.hi = Vec3(hi_x[lane], hi_y[lane], hi_z[lane]);
        return b;
    }
};

// Up to four triangles of one leaf, vertex components in structure-of-arrays form
// ([vertex][axis][lane]) so that one SSE watertight test covers all four.
struct alignas(16) Tri4 {
    float v[3][3][4];
};

struct BvhQuality {
    double sah_cost = 0;  // with the traversal and intersection costs of BvhBuildOptions
    uint32_t node_count = 0, inner_count = 0, leaf_count = 0, max_depth = 0;
    double mean_leaf_size = 0;
    double mean_children = 0;  // children per inner node: how full the wide nodes are
    uint64_t bytes = 0;        // nodes + triangles in the layout
    double build_seconds = 0;  // binary build + collapse + layout
};

struct Bvh {
    BvhBuildOptions options;
    BvhLayout layout;
    BvhQuality quality;
    AABB bounds_box;
    // Exactly one of these holds the tree, per options.width; node index = layout record index
    // (depth-first order, root first).
    // (Arrays of their own after a build, views of the mapped entry after a cache hit.)
    MappableArray<WideNode<2>> nodes2;
    MappableArray<WideNode<4>> nodes4;
    MappableArray<WideNode<8>> nodes8;
    MappableArray<uint32_t> prim_order;            // triangle slot -> scene primitive id
    MappableArray<std::array<Vec3, 3>> tri_verts;  // triangle slot -> vertices, for fast tests
    MappableArray<Tri4> tri4;                      // every leaf's triangles, 4 to a block
    MappableArray<uint32_t> leaf_block;            // a leaf's first slot -> its first Tri4 block

    int width() const { return options.width; }
    const AABB& bounds() const { return bounds_box; }
    template <int W>
    const MappableArray<WideNode<W>>& nodes() const;
    size_t inner_node_count() const { return layout.inner_node_count; }
};

template <>
inline const MappableArray<WideNode<2>>& Bvh::nodes<2>() const {
    return nodes2;
}
template <>
inline const MappableArray<WideNode<4>>& Bvh::nodes<4>() const {
    return nodes4;
}
template <>
inline const MappableArray<WideNode<8>>& Bvh::nodes<8>() const {
    return nodes8;
}

// Builds the binary tree with options.builder, collapses it to options.width children per node
// (greedily opening the child of largest surface area) and lays it out. `layout_sizes` gives
// node and triangle record sizes. Throws InputError for an empty scene or a bad width.
Bvh build_bvh(const Scene& scene, const BvhBuildOptions& options,
              const BvhLayout& layout_sizes = BvhLayout());

// SAH cost and counts of the finished tree (also used by tests).
BvhQuality measure_bvh(const Bvh& bvh);
double binary_sah_cost(const BinaryBvh& bvh, const BvhBuildOptions& options);

}  // namespace rtsim

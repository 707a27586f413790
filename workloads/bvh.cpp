// Collapsing binary trees to BVH2/4/8, the memory layout, and quality figures.
#include "workloads/bvh.h"
#include "workloads/huge_pages.h"

#include <fmt/format.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "workloads/error.h"
#include "workloads/parallel.h"
#include "workloads/reduced_box.h"

namespace rtsim {

const char* bvh_builder_name(BvhBuilder b) {
    return b == BvhBuilder::Sah ? "sah" : "lbvh";
}

BvhBuilder parse_bvh_builder(const std::string& name, const std::string& what) {
    if (name == "sah") return BvhBuilder::Sah;
    if (name == "lbvh") return BvhBuilder::Lbvh;
    throw InputError(
        fmt::format("{}: unknown BVH builder '{}' (expected sah or lbvh)", what, name));
}

const char* node_format_name(NodeFormat f) {
    return f == NodeFormat::Full ? "full" : "compressed";
}

NodeFormat parse_node_format(const std::string& name, const std::string& what) {
    if (name == "full") return NodeFormat::Full;
    if (name == "compressed") return NodeFormat::Compressed;
    throw InputError(
        fmt::format("{}: unknown node format '{}' (expected full or compressed)", what, name));
}

uint32_t compressed_node_size_bytes(int width) {
    return (24 + 7 * uint32_t(width) + 15) / 16 * 16;
}

uint32_t default_node_size_bytes(int width) {
    const uint32_t raw = uint32_t(width) * (24 + 4);
    uint32_t size = 64;
    while (size < raw) size *= 2;
    return size;
}

int largest_inner_node(const BinaryBvh& bvh, const uint32_t* nodes, size_t count) {
    int best = -1;
    float best_area = -1.0f;
    for (size_t i = 0; i < count; ++i) {
        const BinaryNode& n = bvh.nodes[nodes[i]];
        if (!n.is_leaf() && n.box.surface_area() > best_area) {
            best_area = n.box.surface_area();
            best = int(i);
        }
    }
    return best;
}

double binary_sah_cost(const BinaryBvh& bvh, const BvhBuildOptions& o) {
    const double root_area = std::max(bvh.nodes[0].box.surface_area(), 1e-30f);
    double cost = 0;
    for (const BinaryNode& n : bvh.nodes) {
        const double rel = n.box.surface_area() / root_area;
        cost += n.is_leaf() ? rel * o.intersection_cost * n.prim_count : rel * o.traversal_cost;
    }
    return cost;
}

namespace {

uint32_t binary_depth(const BinaryBvh& bvh) {
    uint32_t depth = 0;
    std::vector<std::pair<uint32_t, uint32_t>> stack = {{0, 0}};
    while (!stack.empty()) {
        const auto [i, d] = stack.back();
        stack.pop_back();
        depth = std::max(depth, d);
        const BinaryNode& n = bvh.nodes[i];
        if (!n.is_leaf()) {
            stack.push_back({n.a, d + 1});
            stack.push_back({n.b, d + 1});
        }
    }
    return depth;
}

// Compressed wide nodes (Ylitie, Karras & Laine 2017): child boxes stored as 8-bit offsets on a
// per-node grid with origin p (the node box's low corner) and a power-of-two step per axis.
// The tracer then sees exactly the boxes the hardware decodes: each child box is rounded
// outwards to the grid, so it still contains its child (conservative), at the price of some
// extra box hits. The float decode p + q * 2^e is nudged outwards where it rounds inwards.
template <int W>
void quantize_boxes(WideNode<W>& node) {
    float* lo[3] = {node.lo_x, node.lo_y, node.lo_z};
    float* hi[3] = {node.hi_x, node.hi_y, node.hi_z};
    const float inf = std::numeric_limits<float>::infinity();
    for (int a = 0; a < 3; ++a) {
        float p = inf, top = -inf;
        for (int l = 0; l < node.num; ++l) {
            p = std::min(p, lo[a][l]);
            top = std::max(top, hi[a][l]);
        }
        const float extent = top - p;
        int e = extent > 0.0f ? int(std::ceil(std::log2(extent / 255.0f))) : -126;
        e = std::clamp(e, -126, 127);
        while (e < 127 && std::ldexp(255.0f, e) < extent) ++e;  // guard log2 rounding
        const float step = std::ldexp(1.0f, e);
        for (int l = 0; l < node.num; ++l) {
            const float qlo = std::clamp(std::floor((lo[a][l] - p) / step), 0.0f, 255.0f);
            const float qhi = std::clamp(std::ceil((hi[a][l] - p) / step), 0.0f, 255.0f);
            float dlo = p + qlo * step, dhi = p + qhi * step;
            while (dlo > lo[a][l]) dlo = std::nextafter(dlo, -inf);
            while (dhi < hi[a][l]) dhi = std::nextafter(dhi, inf);
            lo[a][l] = dlo;
            hi[a][l] = dhi;
        }
    }
}

template <int W>
class Collapser {
  public:
    Collapser(const BinaryBvh& in, std::vector<WideNode<W>>& out, bool quantize)
        : in_(in), out_(out), quantize_(quantize) {}

    void run() {
        out_.clear();
        // At most one wide node per binary inner node (wide nodes need not be full); reserved
        // address space that is never written costs nothing, but growing past a short
        // reservation moves the array onto small pages.
        reserve_huge(out_, in_.nodes.size() / 2 + 1);
        if (in_.nodes[0].is_leaf()) {
            // A tree that is one leaf still gets a root record, so traversal always starts at one.
            Kids only;
            only.at[0] = 0;
            only.size = 1;
            emit(only);
        } else {
            emit_from(0);
        }
    }

  private:
    // Up to W binary nodes, left to right.
    struct Kids {
        std::array<uint32_t, W> at;
        int size = 0;
    };

    // Opens the binary node `b` into up to W children and emits the wide node; returns its index.
    uint32_t emit_from(uint32_t b) {
        Kids kids;
        kids.at[0] = in_.nodes[b].a;
        kids.at[1] = in_.nodes[b].b;
        kids.size = 2;
        while (kids.size < W) {
            const int best = largest_inner_node(in_, kids.at.data(), size_t(kids.size));
            if (best < 0) break;
            const BinaryNode& k = in_.nodes[kids.at[best]];
            // Its two children take its place, keeping left-to-right (depth-first) order.
            for (int i = kids.size; i > best + 1; --i) kids.at[i] = kids.at[i - 1];
            kids.at[best] = k.a;
            kids.at[best + 1] = k.b;
            kids.size++;
        }
        return emit(kids);
    }

    uint32_t emit(const Kids& kids) {
        const auto index = static_cast<uint32_t>(out_.size());
        out_.emplace_back();
        WideNode<W> node{};
        for (int l = 0; l < W; ++l) {
            node.lo_x[l] = node.lo_y[l] = node.lo_z[l] = std::numeric_limits<float>::infinity();
            node.hi_x[l] = node.hi_y[l] = node.hi_z[l] = -std::numeric_limits<float>::infinity();
        }
        node.num = static_cast<uint8_t>(kids.size);
        for (int l = 0; l < kids.size; ++l) {
            const BinaryNode& k = in_.nodes[kids.at[l]];
            node.lo_x[l] = k.box.lo.x;
            node.lo_y[l] = k.box.lo.y;
            node.lo_z[l] = k.box.lo.z;
            node.hi_x[l] = k.box.hi.x;
            node.hi_y[l] = k.box.hi.y;
            node.hi_z[l] = k.box.hi.z;
            node.count[l] = static_cast<uint8_t>(k.prim_count);
            node.child[l] = k.is_leaf() ? k.a : 0;
        }
        if (quantize_) quantize_boxes(node);
        out_[index] = node;
        // Children's records follow in depth-first order (emit_from may grow out_).
        for (int l = 0; l < kids.size; ++l)
            if (!in_.nodes[kids.at[l]].is_leaf()) {
                const uint32_t c = emit_from(kids.at[l]);
                out_[index].child[l] = c;
            }
        return index;
    }

    const BinaryBvh& in_;
    std::vector<WideNode<W>>& out_;
    bool quantize_;
};

template <int W>
BvhQuality measure(const MappableArray<WideNode<W>>& nodes, const AABB& root,
                   const BvhBuildOptions& o) {
    BvhQuality q;
    const double root_area = std::max(root.surface_area(), 1e-30f);
    struct Item {
        uint32_t node, depth;
    };
    std::vector<Item> stack = {{0, 0}};
    uint64_t leaf_prims = 0;
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        const WideNode<W>& n = nodes[it.node];
        q.inner_count++;
        AABB box;
        for (int l = 0; l < n.num; ++l) box.grow(n.box(l));
        q.sah_cost += box.surface_area() / root_area * o.traversal_cost;
        for (int l = 0; l < n.num; ++l) {
            if (n.count[l]) {
                q.leaf_count++;
                leaf_prims += n.count[l];
                q.max_depth = std::max(q.max_depth, it.depth + 1);
                q.sah_cost +=
                    n.box(l).surface_area() / root_area * o.intersection_cost * n.count[l];
            } else {
                stack.push_back({n.child[l], it.depth + 1});
            }
        }
    }
    q.node_count = q.inner_count + q.leaf_count;
    q.mean_leaf_size = q.leaf_count ? double(leaf_prims) / q.leaf_count : 0.0;
    q.mean_children =
        double(q.node_count - 1) / q.inner_count;  // every node but the root is a child
    return q;
}

// Cuts the tree into treelets (Aila & Karras 2010) and lays each out contiguously. The cut is
// Kundu & Misra's (1977) bottom-up greedy, which gives the fewest connected pieces within the
// budget: going up the tree, a node gathers what is left of its children's pieces and, while
// that exceeds the budget, cuts off its heaviest child piece as a treelet. A node's cost is its
// record plus its leaf children's triangles, which move with it; a node over budget on its own
// forms a treelet alone. Treelets are numbered in depth-first order of their roots (the root
// treelet is 0).
template <int W>
void cut_treelets(std::vector<WideNode<W>>& nodes, std::vector<uint32_t>& prim_order,
                  BvhLayout& L) {
    const size_t n = nodes.size();
    std::vector<uint64_t> left(n);  // a node's piece once its heavy children are cut off
    std::vector<bool> is_root(n, false);
    is_root[0] = true;
    // Children have larger indices than their parent (depth-first preorder): going down the
    // indices visits every node after its children.
    for (size_t i = n; i-- > 0;) {
        uint64_t w = L.node_size_bytes;
        std::vector<std::pair<uint64_t, uint32_t>> kids;
        for (int l = 0; l < nodes[i].num; ++l) {
            if (nodes[i].count[l]) {
                w += uint64_t(nodes[i].count[l]) * L.tri_size_bytes;
            } else {
                const uint32_t c = nodes[i].child[l];
                kids.push_back({left[c], c});
                w += left[c];
            }
        }
        std::sort(kids.rbegin(), kids.rend());
        for (size_t k = 0; k < kids.size() && w > L.treelet_bytes; ++k) {
            is_root[kids[k].second] = true;
            w -= kids[k].first;
        }
        left[i] = w;
    }
    // Members of each treelet, from its root down to the roots of the next ones.
    std::vector<std::vector<uint32_t>> members;
    std::vector<uint32_t> roots = {0};
    for (size_t r = 0; r < roots.size(); ++r) {
        std::vector<uint32_t> treelet, stack = {roots[r]};
        while (!stack.empty()) {
            const uint32_t i = stack.back();
            stack.pop_back();
            treelet.push_back(i);
            for (int l = nodes[i].num; l-- > 0;) {
                if (nodes[i].count[l]) continue;
                const uint32_t c = nodes[i].child[l];
                (is_root[c] ? roots : stack).push_back(c);
            }
        }
        // Old indices are depth-first preorder, so sorted members are the treelet's own preorder.
        std::sort(treelet.begin(), treelet.end());
        members.push_back(std::move(treelet));
    }
    std::vector<uint32_t> new_index(n);
    uint32_t next = 0;
    for (const auto& t : members)
        for (uint32_t i : t) new_index[i] = next++;
    std::vector<WideNode<W>> out(n);
    std::vector<uint32_t> order;
    order.reserve(prim_order.size());
    L.treelet_node_start.assign(1, 0);
    L.treelet_tri_start.assign(1, 0);
    for (const auto& t : members) {
        for (uint32_t i : t) {
            WideNode<W> node = nodes[i];
            for (int l = 0; l < node.num; ++l) {
                if (!node.count[l]) {
                    node.child[l] = new_index[node.child[l]];
                    continue;
                }
                const uint32_t first = node.child[l];
                node.child[l] = uint32_t(order.size());
                for (uint32_t k = 0; k < node.count[l]; ++k) order.push_back(prim_order[first + k]);
            }
            out[new_index[i]] = node;
        }
        L.treelet_node_start.push_back(L.treelet_node_start.back() + uint32_t(t.size()));
        L.treelet_tri_start.push_back(uint32_t(order.size()));
    }
    nodes = std::move(out);
    prim_order = std::move(order);
}

}  // namespace

// Packs each leaf's triangles into Tri4 blocks (unused lanes stay zero; tests mask them off).
template <int W>
void build_tri_blocks(const std::vector<WideNode<W>>& nodes,
                      const std::vector<std::array<Vec3, 3>>& tri_verts,
                      std::vector<uint32_t>& leaf_block, std::vector<Tri4>& tri4) {
    reserve_huge(leaf_block, tri_verts.size());
    leaf_block.assign(tri_verts.size(), 0);
    tri4.clear();
    size_t blocks = 0;  // counted first: grown block by block, the array was copied ~20 times
    for (const WideNode<W>& n : nodes)
        for (int l = 0; l < n.num; ++l) blocks += (n.count[l] + 3) / 4;
    reserve_huge(tri4, blocks);
    for (const WideNode<W>& n : nodes)
        for (int l = 0; l < n.num; ++l) {
            if (!n.count[l]) continue;
            leaf_block[n.child[l]] = static_cast<uint32_t>(tri4.size());
            for (uint32_t base = 0; base < n.count[l]; base += 4) {
                Tri4 block{};
                for (uint32_t lane = 0; lane < 4 && base + lane < n.count[l]; ++lane) {
                    const auto& t = tri_verts[n.child[l] + base + lane];
                    for (int vert = 0; vert < 3; ++vert)
                        for (int a = 0; a < 3; ++a) block.v[vert][a][lane] = t[vert][a];
                }
                tri4.push_back(block);
            }
        }
}

// The collapsed tree of width W, its treelets cut (when asked) and its triangles laid out in
// leaf order: built in vectors of their own, then handed to the Bvh.
template <int W>
void lay_out(BinaryBvh& bin, bool quantize, const Scene& scene, MappableArray<WideNode<W>>& out,
             Bvh& bvh) {
    std::vector<WideNode<W>> nodes;
    Collapser<W>(bin, nodes, quantize).run();
    // The binary tree is done with: freed before the triangle arrays are made, it no longer
    // sits in the build's peak (36 bytes per node, two nodes per triangle).
    std::vector<BinaryNode>().swap(bin.nodes);
    std::vector<uint32_t> prim_order = std::move(bin.prim_order);
    if (bvh.options.treelet_bytes > 0) cut_treelets(nodes, prim_order, bvh.layout);
    std::vector<std::array<Vec3, 3>> tri_verts;
    reserve_huge(tri_verts, prim_order.size());
    tri_verts.resize(prim_order.size());
    const int threads = resolve_threads(bvh.options.build_threads);
    parallel_blocks(prim_order.size(), 1 << 18, threads, [&](size_t begin, size_t end) {
        for (size_t s = begin; s < end; ++s)
            for (int c = 0; c < 3; ++c) tri_verts[s][c] = scene.v(prim_order[s], c);
    });
    std::vector<uint32_t> leaf_block;
    std::vector<Tri4> tri4;
    build_tri_blocks(nodes, tri_verts, leaf_block, tri4);
    out = std::move(nodes);
    bvh.prim_order = std::move(prim_order);
    bvh.tri_verts = std::move(tri_verts);
    bvh.leaf_block = std::move(leaf_block);
    bvh.tri4 = std::move(tri4);
}

BvhQuality measure_bvh(const Bvh& bvh) {
    BvhQuality q;
    switch (bvh.width()) {
        case 2:
            q = measure(bvh.nodes2, bvh.bounds(), bvh.options);
            break;
        case 4:
            q = measure(bvh.nodes4, bvh.bounds(), bvh.options);
            break;
        default:
            q = measure(bvh.nodes8, bvh.bounds(), bvh.options);
            break;
    }
    q.bytes = bvh.layout.node_bytes_total() + bvh.layout.tri_bytes_total();
    q.build_seconds = bvh.quality.build_seconds;
    return q;
}

Bvh build_bvh(const Scene& scene, const BvhBuildOptions& options, const BvhLayout& layout_sizes) {
    if (options.width != 2 && options.width != 4 && options.width != 8)
        throw InputError(fmt::format("bvh.width: expected 2, 4 or 8, got {}", options.width));
    if (options.max_leaf_size < 1 || options.max_leaf_size > 255)
        throw InputError(
            fmt::format("bvh.max_leaf_size: expected 1..255, got {}", options.max_leaf_size));
    if (options.box_mantissa_bits < kMinMantissaBits ||
        options.box_mantissa_bits > kFullMantissaBits)
        throw InputError(fmt::format("box_unit.mantissa_bits: expected {}..{}, got {}",
                                     kMinMantissaBits, kFullMantissaBits,
                                     options.box_mantissa_bits));
    const auto t0 = std::chrono::steady_clock::now();
    BinaryBvh bin = options.builder == BvhBuilder::Sah ? build_binary_sah(scene, options)
                                                       : build_binary_lbvh(scene, options);
    if (options.restructure_passes > 0) {
        // Restructuring may deepen the tree; traversal stacks are sized for kMaxBvhDepth, so a
        // result that deep (only on pathological input) is dropped for the original.
        BinaryBvh restructured = bin;
        restructure_treelets(restructured, options, options.restructure_passes);
        if (binary_depth(restructured) < kMaxBvhDepth - 1) bin = std::move(restructured);
    }
    Bvh bvh;
    bvh.options = options;
    bvh.bounds_box = bin.nodes[0].box;
    const bool quantize = options.node_format == NodeFormat::Compressed;
    BvhLayout& L = bvh.layout;
    L = layout_sizes;
    if (L.node_size_bytes == 0)
        L.node_size_bytes = quantize ? compressed_node_size_bytes(options.width)
                                     : default_node_size_bytes(options.width);
    L.treelet_bytes = options.treelet_bytes;
    L.treelet_node_start.clear();
    L.treelet_tri_start.clear();
    switch (options.width) {
        case 2:
            lay_out<2>(bin, quantize, scene, bvh.nodes2, bvh);
            break;
        case 4:
            lay_out<4>(bin, quantize, scene, bvh.nodes4, bvh);
            break;
        default:
            lay_out<8>(bin, quantize, scene, bvh.nodes8, bvh);
            break;
    }

    L.inner_node_count = static_cast<uint32_t>(options.width == 2   ? bvh.nodes2.size()
                                               : options.width == 4 ? bvh.nodes4.size()
                                                                    : bvh.nodes8.size());
    L.triangle_count = static_cast<uint32_t>(bvh.prim_order.size());
    L.index_treelets();
    const uint64_t page = 4096;
    L.tri_base_addr = (L.node_base_addr + L.node_bytes_total() + page - 1) / page * page;
    bvh.quality.build_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    bvh.quality = measure_bvh(bvh);
    return bvh;
}

bool BvhLayout::index_treelets() {
    node_treelet_.clear();
    tri_treelet_.clear();
    instance_treelet_.clear();
    if (treelet_node_start.empty() && treelet_tri_start.empty())
        return treelet_instance_start.empty();
    auto fill = [](const std::vector<uint32_t>& start, uint32_t records,
                   std::vector<uint32_t>& of) {
        if (start.size() < 2 || start.front() != 0 || start.back() != records) return false;
        for (size_t k = 0; k + 1 < start.size(); ++k)
            if (start[k + 1] < start[k]) return false;  // then every run lies inside [0, records)
        of.assign(records, 0);
        for (size_t k = 0; k + 1 < start.size(); ++k)
            for (uint32_t i = start[k]; i < start[k + 1]; ++i) of[i] = uint32_t(k);
        return true;
    };
    const bool instances_ok = treelet_instance_start.empty() ||
                              (treelet_instance_start.size() == treelet_node_start.size() &&
                               fill(treelet_instance_start, instance_count, instance_treelet_));
    if (treelet_node_start.size() != treelet_tri_start.size() ||
        !fill(treelet_node_start, inner_node_count, node_treelet_) ||
        !fill(treelet_tri_start, triangle_count, tri_treelet_) || !instances_ok) {
        node_treelet_.clear();
        tri_treelet_.clear();
        instance_treelet_.clear();
        return false;
    }
    return true;
}

}  // namespace rtsim

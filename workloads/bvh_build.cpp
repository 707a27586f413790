// Binary BVH builders: binned SAH and LBVH.
#include <fmt/format.h>
#include <algorithm>
#include <cstring>
#include <future>
#include <memory>

#include "workloads/bvh.h"
#include "workloads/error.h"
#include "workloads/huge_pages.h"
#include "workloads/parallel.h"

namespace rtsim {
namespace {

// Past this depth the builders split by index, so depth <= kMaxSahDepth + log2(n) < kMaxBvhDepth.
constexpr uint32_t kMaxSahDepth = 64;

// Appends two children to nodes[index] and returns the first one's index.
uint32_t append_children(std::vector<BinaryNode>& nodes, uint32_t index) {
    const auto left = static_cast<uint32_t>(nodes.size());
    nodes.emplace_back();
    nodes.emplace_back();
    nodes[index].a = left;
    nodes[index].b = left + 1;
    return left;
}

struct BuildPrim {
    AABB box;
    uint32_t id;
    // Computed where needed rather than stored: 28 bytes a primitive instead of 40, and the
    // partitions that move them are memory-bound.
    float centroid(int axis) const { return (box.lo[axis] + box.hi[axis]) * 0.5f; }
};

// Binned SAH, top-down. Large subtrees are built on threads of their own, each into a fragment
// (an array whose first node is the subtree's root); the fragments are concatenated once at the
// end. Node numbering therefore depends on the thread count, but nothing reads it: the collapse
// follows child links, so the laid-out tree is the same bit for bit for any thread count. Each
// node's split depends only on its own primitives, and subtrees partition disjoint ranges.
class SahBuilder {
  public:
    SahBuilder(const Scene& scene, const BvhBuildOptions& opt)
        : opt_(opt), threads_(resolve_threads(opt.build_threads)) {
        reserve_huge(prims_, scene.triangle_count());
        prims_.resize(scene.triangle_count());
        parallel_blocks(prims_.size(), kBlockPrims, threads_, [&](size_t b, size_t e) {
            for (size_t i = b; i < e; ++i) prims_[i] = {scene.triangle_bounds(i), uint32_t(i)};
        });
    }

    void build(BinaryBvh& bvh) {
        Fragment root;
        reserve_huge(root.nodes, 2 * prims_.size());
        root.nodes.emplace_back();
        // Subtrees split off to threads down to this many levels: about four per host thread.
        int levels = 0;
        while (threads_ > 1 && (1 << levels) < 4 * threads_) ++levels;
        Scratch scratch(opt_.sah_buckets);
        build_node(root, 0, 0, static_cast<uint32_t>(prims_.size()), 0, scratch, levels, threads_);
        assemble(root, bvh.nodes);
        reserve_huge(bvh.prim_order, prims_.size());
        bvh.prim_order.resize(prims_.size());
        parallel_blocks(prims_.size(), kBlockPrims, threads_, [&](size_t b, size_t e) {
            for (size_t i = b; i < e; ++i) bvh.prim_order[i] = prims_[i].id;
        });
    }

  private:
    struct Bucket {
        AABB box;
        uint32_t count = 0;
    };
    // A node's binning tables, reused by every node one thread builds (allocated per node, they
    // were millions of allocations in a large build).
    struct Scratch {
        explicit Scratch(int buckets)
            : buckets(size_t(buckets)), right_area(size_t(buckets)), right_count(size_t(buckets)) {}
        std::vector<Bucket> buckets;
        std::vector<float> right_area;
        std::vector<uint32_t> right_count;
    };
    // A subtree built on a thread of its own. `links` name the nodes whose right child is the
    // root of another fragment (their `b` is filled in by assemble).
    struct Fragment {
        std::vector<BinaryNode> nodes;
        std::vector<std::pair<uint32_t, std::unique_ptr<Fragment>>> links;
        uint32_t base = 0;  // its first node's index once assembled
    };
    // Subtrees smaller than this are not worth a thread.
    static constexpr uint32_t kParallelPrims = 32768;
    // Nodes with this many primitives bin on every thread their subtree owns.
    static constexpr uint32_t kParallelBinPrims = 1u << 19;
    static constexpr size_t kBlockPrims = 1u << 18;

    void make_leaf(BinaryNode& node, uint32_t begin, uint32_t end) {
        node.a = begin;
        node.prim_count = end - begin;
    }

    // Applies body(begin, end, acc) to [begin, end), or, for a large range and more than one
    // thread, to blocks of it, each block's result starting from acc's value on entry (an
    // empty one) and folded into acc with merge. Min, max and integer sums are exact in any
    // grouping, so the result is the same for any thread count.
    template <class T, class Body, class Merge>
    void fold(uint32_t begin, uint32_t end, int share, T& acc, Body body, Merge merge) const {
        if (share <= 1 || end - begin < kParallelBinPrims) return body(begin, end, acc);
        const size_t blocks = (end - begin + kBlockPrims - 1) / kBlockPrims;
        std::vector<T> part(blocks, acc);
        parallel_blocks(end - begin, kBlockPrims, share, [&](size_t b, size_t e) {
            body(begin + uint32_t(b), begin + uint32_t(e), part[b / kBlockPrims]);
        });
        for (const T& p : part) merge(acc, p);
    }

    // Builds node `index` of `frag` over prims_[begin, end); children are appended to frag.
    // `levels`: how many more levels may hand a subtree to a thread of its own; `share`: the host
    // threads this subtree may use for one node's loops.
    void build_node(Fragment& frag, uint32_t index, uint32_t begin, uint32_t end, uint32_t depth,
                    Scratch& sc, int levels, int share) {
        std::vector<BinaryNode>& nodes = frag.nodes;
        using Boxes = std::pair<AABB, AABB>;  // primitives' bounds, centroids' bounds
        Boxes boxes;
        fold(
            begin, end, share, boxes,
            [&](uint32_t b, uint32_t e, Boxes& acc) {
                for (uint32_t i = b; i < e; ++i) {
                    acc.first.grow(prims_[i].box);
                    acc.second.grow(prims_[i].box.center());
                }
            },
            [](Boxes& acc, const Boxes& p) {
                acc.first.grow(p.first);
                acc.second.grow(p.second);
            });
        const AABB& box = boxes.first;
        const AABB& cbox = boxes.second;
        nodes[index].box = box;
        const uint32_t n = end - begin;
        if (n == 1) return make_leaf(nodes[index], begin, end);

        uint32_t mid = begin;
        const int axis = max_axis(cbox.extent());
        const float lo = cbox.lo[axis], ext = cbox.extent()[axis];
        if (!(ext > 0.0f) || depth >= kMaxSahDepth) {
            // Centroids coincide (SAH cannot separate them) or the tree is pathologically deep:
            // split by index, which bounds both leaf size and the traversal stack.
            if (n <= uint32_t(opt_.max_leaf_size)) return make_leaf(nodes[index], begin, end);
            mid = begin + n / 2;
        } else {
            const int nb = opt_.sah_buckets;
            auto bucket_of = [&](const BuildPrim& p) {
                int b = static_cast<int>(nb * ((p.centroid(axis) - lo) / ext));
                return std::clamp(b, 0, nb - 1);
            };
            std::vector<Bucket>& buckets = sc.buckets;
            std::fill(buckets.begin(), buckets.end(), Bucket());
            auto bin = [&](uint32_t b, uint32_t e, std::vector<Bucket>& into) {
                for (uint32_t i = b; i < e; ++i) {
                    Bucket& bk = into[bucket_of(prims_[i])];
                    bk.count++;
                    bk.box.grow(prims_[i].box);
                }
            };
            fold(begin, end, share, buckets, bin,
                 [](std::vector<Bucket>& acc, const std::vector<Bucket>& p) {
                     for (size_t k = 0; k < acc.size(); ++k) {
                         acc[k].count += p[k].count;
                         acc[k].box.grow(p[k].box);
                     }
                 });
            // Sweep from the right to get suffix areas, then from the left to evaluate B-1 planes.
            std::vector<float>& right_area = sc.right_area;
            std::vector<uint32_t>& right_count = sc.right_count;
            AABB acc;
            uint32_t cnt = 0;
            for (int b = nb - 1; b > 0; --b) {
                acc.grow(buckets[b].box);
                cnt += buckets[b].count;
                right_area[b] = acc.surface_area();
                right_count[b] = cnt;
            }
            acc = AABB();
            cnt = 0;
            float best_cost = std::numeric_limits<float>::infinity();
            int best_plane = -1;
            const float inv_area = 1.0f / std::max(box.surface_area(), 1e-30f);
            for (int b = 0; b < nb - 1; ++b) {
                acc.grow(buckets[b].box);
                cnt += buckets[b].count;
                if (cnt == 0 || right_count[b + 1] == 0) continue;
                float cost = opt_.traversal_cost + opt_.intersection_cost * inv_area *
                                                       (acc.surface_area() * cnt +
                                                        right_area[b + 1] * right_count[b + 1]);
                if (cost < best_cost) {
                    best_cost = cost;
                    best_plane = b;
                }
            }
            const float leaf_cost = opt_.intersection_cost * n;
            if (n <= uint32_t(opt_.max_leaf_size) && (best_plane < 0 || leaf_cost <= best_cost))
                return make_leaf(nodes[index], begin, end);
            if (best_plane < 0) {
                mid = begin + n / 2;
            } else {
                auto it =
                    std::partition(prims_.begin() + begin, prims_.begin() + end,
                                   [&](const BuildPrim& p) { return bucket_of(p) <= best_plane; });
                mid = static_cast<uint32_t>(it - prims_.begin());
                if (mid == begin || mid == end) mid = begin + n / 2;
            }
        }
        const uint32_t left = append_children(nodes, index);
        if (levels > 0 && mid - begin >= kParallelPrims && end - mid >= kParallelPrims) {
            // The right subtree becomes a fragment of its own, built beside the left one.
            frag.links.push_back({index, std::make_unique<Fragment>()});
            Fragment& apart = *frag.links.back().second;
            nodes.pop_back();  // the right child's record is the fragment's root
            reserve_huge(apart.nodes, 2 * size_t(end - mid));
            apart.nodes.emplace_back();
            const int right_share = share / 2;
            auto right = std::async(std::launch::async, [&, right_share] {
                Scratch own(opt_.sah_buckets);
                build_node(apart, 0, mid, end, depth + 1, own, levels - 1, right_share);
            });
            build_node(frag, left, begin, mid, depth + 1, sc, levels - 1, share - right_share);
            right.get();
            return;
        }
        build_node(frag, left, begin, mid, depth + 1, sc, levels, share);
        build_node(frag, left + 1, mid, end, depth + 1, sc, levels, share);
    }

    // Concatenates the fragments, root first and each fragment's links in the order they were
    // made, into `out` with child indices moved by each fragment's offset.
    void assemble(Fragment& root, std::vector<BinaryNode>& out) {
        std::vector<Fragment*> order;
        uint32_t total = 0;
        auto place = [&](auto&& self, Fragment& f) -> void {
            order.push_back(&f);
            f.base = total;
            total += uint32_t(f.nodes.size());
            for (auto& link : f.links) self(self, *link.second);
        };
        place(place, root);
        out = std::move(root.nodes);
        out.resize(total);
        parallel_blocks(order.size(), 1, threads_, [&](size_t b, size_t e) {
            for (size_t k = b; k < e; ++k) {
                const Fragment& f = *order[k];
                if (k > 0)  // the root's nodes are in place already
                    for (size_t i = 0; i < f.nodes.size(); ++i) {
                        BinaryNode node = f.nodes[i];
                        if (!node.is_leaf()) {
                            node.a += f.base;
                            node.b += f.base;
                        }
                        out[f.base + i] = node;
                    }
                for (const auto& link : f.links) out[f.base + link.first].b = link.second->base;
            }
        });
    }

    BvhBuildOptions opt_;
    int threads_;
    std::vector<BuildPrim> prims_;
};

// LBVH: primitives sorted along a Morton curve of their centroids; each node splits its range
// where the highest bit that differs between its first and last code flips.
class LbvhBuilder {
  public:
    LbvhBuilder(const Scene& scene, const BvhBuildOptions& opt) : scene_(scene), opt_(opt) {}

    void build(BinaryBvh& bvh) {
        const auto n = static_cast<uint32_t>(scene_.triangle_count());
        std::vector<Vec3> centroids(n);
        AABB cbox;
        for (uint32_t i = 0; i < n; ++i) {
            centroids[i] = scene_.triangle_bounds(i).center();
            cbox.grow(centroids[i]);
        }
        std::vector<uint32_t> codes(n);
        const Vec3 ext = cbox.extent();
        for (uint32_t i = 0; i < n; ++i) {
            uint32_t code = 0;
            for (int a = 0; a < 3; ++a) {
                const float rel = ext[a] > 0.0f ? (centroids[i][a] - cbox.lo[a]) / ext[a] : 0.5f;
                code |= spread_bits(std::min(1023u, static_cast<uint32_t>(rel * 1024.0f)))
                        << (2 - a);
            }
            codes[i] = code;
        }
        // LSD radix sort, 3 passes of 10 bits; stable, so equal codes keep the file order.
        std::vector<uint32_t> order(n), tmp(n);
        for (uint32_t i = 0; i < n; ++i) order[i] = i;
        std::vector<uint32_t> count(1024);
        for (int pass = 0; pass < 3; ++pass) {
            const int shift = 10 * pass;
            std::fill(count.begin(), count.end(), 0);
            for (uint32_t i : order) count[(codes[i] >> shift) & 1023]++;
            uint32_t sum = 0;
            for (uint32_t& c : count) {
                const uint32_t c0 = c;
                c = sum;
                sum += c0;
            }
            for (uint32_t i : order) tmp[count[(codes[i] >> shift) & 1023]++] = i;
            order.swap(tmp);
        }
        sorted_codes_.resize(n);
        for (uint32_t i = 0; i < n; ++i) sorted_codes_[i] = codes[order[i]];
        bvh.prim_order = order;
        bvh.nodes.clear();
        bvh.nodes.reserve(2 * n);
        bvh.nodes.emplace_back();
        build_node(bvh, 0, 0, n, 0);
    }

  private:
    // Inserts two zero bits between each of the 10 low bits.
    static uint32_t spread_bits(uint32_t v) {
        v = (v | (v << 16)) & 0x030000FF;
        v = (v | (v << 8)) & 0x0300F00F;
        v = (v | (v << 4)) & 0x030C30C3;
        v = (v | (v << 2)) & 0x09249249;
        return v;
    }

    void build_node(BinaryBvh& bvh, uint32_t index, uint32_t begin, uint32_t end, uint32_t depth) {
        const uint32_t n = end - begin;
        if (n <= uint32_t(opt_.max_leaf_size)) {
            AABB box;
            for (uint32_t i = begin; i < end; ++i)
                box.grow(scene_.triangle_bounds(bvh.prim_order[i]));
            bvh.nodes[index].box = box;
            bvh.nodes[index].a = begin;
            bvh.nodes[index].prim_count = n;
            return;
        }
        uint32_t mid = begin + n / 2;  // equal codes, or too deep: split by index
        const uint32_t first = sorted_codes_[begin], last = sorted_codes_[end - 1];
        if (first != last && depth < kMaxSahDepth) {
            const int bit = 31 - __builtin_clz(first ^ last);
            // First index whose code has `bit` set; codes are sorted, so binary search.
            const auto it =
                std::partition_point(sorted_codes_.begin() + begin, sorted_codes_.begin() + end,
                                     [&](uint32_t c) { return ((c >> bit) & 1u) == 0; });
            mid = static_cast<uint32_t>(it - sorted_codes_.begin());
        }
        const uint32_t left = append_children(bvh.nodes, index);
        build_node(bvh, left, begin, mid, depth + 1);
        build_node(bvh, left + 1, mid, end, depth + 1);
        AABB box = bvh.nodes[left].box;
        box.grow(bvh.nodes[left + 1].box);
        bvh.nodes[index].box = box;
    }

    const Scene& scene_;
    BvhBuildOptions opt_;
    std::vector<uint32_t> sorted_codes_;
};

void require_triangles(const Scene& scene) {
    if (scene.triangles.empty())
        throw InputError(fmt::format("{}: scene has no triangles", scene.name));
}

}  // namespace

BinaryBvh build_binary_sah(const Scene& scene, const BvhBuildOptions& options) {
    require_triangles(scene);
    BinaryBvh bvh;
    SahBuilder(scene, options).build(bvh);
    return bvh;
}

BinaryBvh build_binary_lbvh(const Scene& scene, const BvhBuildOptions& options) {
    require_triangles(scene);
    BinaryBvh bvh;
    LbvhBuilder(scene, options).build(bvh);
    return bvh;
}

}  // namespace rtsim

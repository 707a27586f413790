// Binary BVH builders: binned SAH and LBVH.
#include <fmt/format.h>
#include <algorithm>
#include <cstring>

#include "workloads/bvh.h"
#include "workloads/error.h"

namespace rtsim {
namespace {

// Past this depth the builders split by index, so depth <= kMaxSahDepth + log2(n) < kMaxBvhDepth.
constexpr uint32_t kMaxSahDepth = 64;

// Appends two children to nodes[index] and returns the first one's index.
uint32_t append_children(BinaryBvh& bvh, uint32_t index) {
    const auto left = static_cast<uint32_t>(bvh.nodes.size());
    bvh.nodes.emplace_back();
    bvh.nodes.emplace_back();
    bvh.nodes[index].a = left;
    bvh.nodes[index].b = left + 1;
    return left;
}

struct BuildPrim {
    AABB box;
    Vec3 centroid;
    uint32_t id;
};

class SahBuilder {
  public:
    SahBuilder(const Scene& scene, const BvhBuildOptions& opt) : opt_(opt) {
        prims_.resize(scene.triangle_count());
        for (uint32_t i = 0; i < prims_.size(); ++i) {
            prims_[i].box = scene.triangle_bounds(i);
            prims_[i].centroid = prims_[i].box.center();
            prims_[i].id = i;
        }
    }

    void build(BinaryBvh& bvh) {
        bvh.nodes.clear();
        bvh.nodes.reserve(2 * prims_.size());
        bvh.nodes.emplace_back();
        build_node(bvh, 0, 0, static_cast<uint32_t>(prims_.size()), 0);
        bvh.prim_order.resize(prims_.size());
        for (size_t i = 0; i < prims_.size(); ++i) bvh.prim_order[i] = prims_[i].id;
    }

  private:
    struct Bucket {
        AABB box;
        uint32_t count = 0;
    };

    void make_leaf(BinaryNode& node, uint32_t begin, uint32_t end) {
        node.a = begin;
        node.prim_count = end - begin;
    }

    // Builds nodes[index] over prims_[begin, end); children are appended to bvh.nodes.
    void build_node(BinaryBvh& bvh, uint32_t index, uint32_t begin, uint32_t end, uint32_t depth) {
        AABB box, cbox;
        for (uint32_t i = begin; i < end; ++i) {
            box.grow(prims_[i].box);
            cbox.grow(prims_[i].centroid);
        }
        bvh.nodes[index].box = box;
        const uint32_t n = end - begin;
        if (n == 1) return make_leaf(bvh.nodes[index], begin, end);

        uint32_t mid = begin;
        const int axis = max_axis(cbox.extent());
        const float lo = cbox.lo[axis], ext = cbox.extent()[axis];
        if (!(ext > 0.0f) || depth >= kMaxSahDepth) {
            // Centroids coincide (SAH cannot separate them) or the tree is pathologically deep:
            // split by index, which bounds both leaf size and the traversal stack.
            if (n <= uint32_t(opt_.max_leaf_size)) return make_leaf(bvh.nodes[index], begin, end);
            mid = begin + n / 2;
        } else {
            const int nb = opt_.sah_buckets;
            std::vector<Bucket> buckets(nb);
            auto bucket_of = [&](const BuildPrim& p) {
                int b = static_cast<int>(nb * ((p.centroid[axis] - lo) / ext));
                return std::clamp(b, 0, nb - 1);
            };
            for (uint32_t i = begin; i < end; ++i) {
                Bucket& bk = buckets[bucket_of(prims_[i])];
                bk.count++;
                bk.box.grow(prims_[i].box);
            }
            // Sweep from the right to get suffix areas, then from the left to evaluate B-1 planes.
            std::vector<float> right_area(nb);
            std::vector<uint32_t> right_count(nb);
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
                return make_leaf(bvh.nodes[index], begin, end);
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
        const uint32_t left = append_children(bvh, index);
        build_node(bvh, left, begin, mid, depth + 1);
        build_node(bvh, left + 1, mid, end, depth + 1);
    }

    BvhBuildOptions opt_;
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
        const uint32_t left = append_children(bvh, index);
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

#include "workloads/bvh.h"

#include <fmt/format.h>
#include <algorithm>
#include <chrono>

#include "workloads/error.h"

namespace rtsim {
namespace {

struct BuildPrim {
    AABB box;
    Vec3 centroid;
    uint32_t id;
};

// Past this depth the builder splits by index, so depth <= kMaxSahDepth + log2(n) < kMaxBvhDepth.
constexpr uint32_t kMaxSahDepth = 64;

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

    void build(Bvh& bvh) {
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

    void make_leaf(BvhNode& node, uint32_t begin, uint32_t end) {
        node.a = begin;
        node.prim_count = end - begin;
    }

    // Builds nodes[index] over prims_[begin, end); children are appended to bvh.nodes.
    void build_node(Bvh& bvh, uint32_t index, uint32_t begin, uint32_t end, uint32_t depth) {
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
        const auto left = static_cast<uint32_t>(bvh.nodes.size());
        bvh.nodes.emplace_back();
        bvh.nodes.emplace_back();
        bvh.nodes[index].a = left;
        bvh.nodes[index].b = left + 1;
        build_node(bvh, left, begin, mid, depth + 1);
        build_node(bvh, left + 1, mid, end, depth + 1);
    }

    BvhBuildOptions opt_;
    std::vector<BuildPrim> prims_;
};

// Inner-node records in depth-first order: a parent's record sits near its left subtree's.
void assign_layout(Bvh& bvh) {
    uint32_t next = 0;
    std::vector<uint32_t> stack = {0};
    while (!stack.empty()) {
        uint32_t i = stack.back();
        stack.pop_back();
        BvhNode& n = bvh.nodes[i];
        if (n.is_leaf()) continue;
        n.mem_index = next++;
        stack.push_back(n.b);
        stack.push_back(n.a);
    }
    BvhLayout& L = bvh.layout;
    L.inner_node_count = next;
    L.triangle_count = static_cast<uint32_t>(bvh.prim_order.size());
    const uint64_t page = 4096;
    L.tri_base_addr = (L.node_base_addr + L.node_bytes_total() + page - 1) / page * page;
}

}  // namespace

BvhQuality measure_bvh(const Bvh& bvh) {
    BvhQuality q;
    q.build_seconds = bvh.quality.build_seconds;
    const double root_area = std::max(bvh.nodes[0].box.surface_area(), 1e-30f);
    struct Item {
        uint32_t node, depth;
    };
    std::vector<Item> stack = {{0, 0}};
    uint64_t leaf_prims = 0;
    while (!stack.empty()) {
        Item it = stack.back();
        stack.pop_back();
        const BvhNode& n = bvh.nodes[it.node];
        q.node_count++;
        q.max_depth = std::max(q.max_depth, it.depth);
        const double rel_area = n.box.surface_area() / root_area;
        if (n.is_leaf()) {
            q.leaf_count++;
            leaf_prims += n.prim_count;
            q.sah_cost += rel_area * bvh.options.intersection_cost * n.prim_count;
        } else {
            q.inner_count++;
            q.sah_cost += rel_area * bvh.options.traversal_cost;
            stack.push_back({n.a, it.depth + 1});
            stack.push_back({n.b, it.depth + 1});
        }
    }
    q.mean_leaf_size = q.leaf_count ? double(leaf_prims) / q.leaf_count : 0.0;
    q.bytes = bvh.layout.node_bytes_total() + bvh.layout.tri_bytes_total();
    return q;
}

Bvh build_bvh_sah(const Scene& scene, const BvhBuildOptions& options,
                  const BvhLayout& layout_sizes) {
    if (scene.triangles.empty())
        throw InputError(fmt::format("{}: scene has no triangles", scene.name));
    const auto t0 = std::chrono::steady_clock::now();
    Bvh bvh;
    bvh.options = options;
    bvh.layout = layout_sizes;
    SahBuilder builder(scene, options);
    builder.build(bvh);
    assign_layout(bvh);
    bvh.quality.build_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    bvh.quality = measure_bvh(bvh);
    return bvh;
}

}  // namespace rtsim

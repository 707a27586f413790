// Treelet restructuring (Karras & Aila 2013): for every inner node, bottom up, grow a treelet of
// up to 7 leaves below it (repeatedly opening the treelet leaf of largest surface area), find the
// binary topology over those leaves that minimises SAH cost by dynamic programming over subsets,
// and rebuild the treelet's inner nodes in that shape when it is cheaper. Leaves of the treelet
// are whole subtrees and stay untouched, so the tree keeps every primitive exactly once.
#include <algorithm>
#include <array>
#include <functional>
#include <limits>
#include <vector>

#include "workloads/bvh.h"

namespace rtsim {
namespace {

constexpr int kTreeletLeaves = 7;
constexpr int kSubsets = 1 << kTreeletLeaves;

class Restructurer {
  public:
    Restructurer(BinaryBvh& bvh, const BvhBuildOptions& o) : bvh_(bvh), opt_(o) {}

    // Returns how many treelets were rebuilt.
    int pass() {
        cost_.assign(bvh_.nodes.size(), 0.0f);
        rebuilt_ = 0;
        visit(0);
        return rebuilt_;
    }

  private:
    float node_cost(uint32_t i) const {
        const BinaryNode& n = bvh_.nodes[i];
        return n.is_leaf() ? opt_.intersection_cost * n.box.surface_area() * n.prim_count
                           : opt_.traversal_cost * n.box.surface_area() + cost_[n.a] + cost_[n.b];
    }

    // Post-order: children first, so a treelet's leaves carry their final subtree costs.
    void visit(uint32_t root) {
        // Iterative post-order keeps deep trees off the call stack.
        std::vector<std::pair<uint32_t, bool>> stack = {{root, false}};
        while (!stack.empty()) {
            auto [i, expanded] = stack.back();
            stack.pop_back();
            const BinaryNode& n = bvh_.nodes[i];
            if (n.is_leaf()) {
                cost_[i] = node_cost(i);
                continue;
            }
            if (!expanded) {
                stack.push_back({i, true});
                stack.push_back({n.a, false});
                stack.push_back({n.b, false});
                continue;
            }
            optimise(i);
            cost_[i] = node_cost(i);
        }
    }

    void optimise(uint32_t root) {
        // Grow the treelet: leaves are subtree roots; internal holds the inner nodes it replaces.
        std::vector<uint32_t> leaves = {bvh_.nodes[root].a, bvh_.nodes[root].b};
        std::vector<uint32_t> internal = {root};
        while (int(leaves.size()) < kTreeletLeaves) {
            const int best = largest_inner_node(bvh_, leaves);
            if (best < 0) break;
            const uint32_t opened = leaves[best];
            internal.push_back(opened);
            leaves[best] = bvh_.nodes[opened].a;
            leaves.push_back(bvh_.nodes[opened].b);
        }
        const int n = int(leaves.size());
        if (n < 3) return;  // two leaves have one topology
        const int full = (1 << n) - 1;

        // Dynamic programming over subsets (the paper's Algorithm 2, without leaf collapsing).
        std::array<AABB, kSubsets> box;
        std::array<float, kSubsets> best_cost;
        std::array<int, kSubsets> best_split;
        for (int s = 1; s <= full; ++s) {
            const int low = s & -s;
            if (s == low) {
                const int k = __builtin_ctz(s);
                box[s] = bvh_.nodes[leaves[k]].box;
                best_cost[s] = cost_[leaves[k]];
                continue;
            }
            box[s] = box[s ^ low];
            box[s].grow(box[low]);
            float c = std::numeric_limits<float>::infinity();
            int split = 0;
            // Proper subsets containing the lowest member: each partition once.
            for (int p = (s - 1) & s; p; p = (p - 1) & s) {
                if (!(p & low)) continue;
                const float pc = best_cost[p] + best_cost[s ^ p];
                if (pc < c) {
                    c = pc;
                    split = p;
                }
            }
            best_cost[s] = opt_.traversal_cost * box[s].surface_area() + c;
            best_split[s] = split;
        }
        // Current cost of the treelet, from its inner nodes' own terms plus the leaves' subtrees.
        float current = 0.0f;
        for (uint32_t i : internal)
            current += opt_.traversal_cost * bvh_.nodes[i].box.surface_area();
        for (uint32_t l : leaves) current += cost_[l];
        if (!(best_cost[full] < current * (1.0f - 1e-6f))) return;  // no real gain: keep it

        // Rebuild with the same inner node slots, root first.
        size_t next_slot = 0;
        std::function<uint32_t(int)> build = [&](int s) -> uint32_t {
            if ((s & (s - 1)) == 0) return leaves[__builtin_ctz(s)];
            const uint32_t slot = internal[next_slot++];
            const int p = best_split[s];
            const uint32_t a = build(p), b = build(s ^ p);
            BinaryNode& node = bvh_.nodes[slot];
            node.a = a;
            node.b = b;
            node.prim_count = 0;
            node.box = box[s];
            cost_[slot] = node_cost(slot);
            return slot;
        };
        build(full);
        ++rebuilt_;
    }

    BinaryBvh& bvh_;
    BvhBuildOptions opt_;
    std::vector<float> cost_;
    int rebuilt_ = 0;
};

}  // namespace

int restructure_treelets(BinaryBvh& bvh, const BvhBuildOptions& options, int passes) {
    int rebuilt = 0;
    if (bvh.nodes.empty() || bvh.nodes[0].is_leaf()) return 0;
    Restructurer r(bvh, options);
    for (int p = 0; p < passes; ++p) {
        const int n = r.pass();
        rebuilt += n;
        if (n == 0) break;
    }
    return rebuilt;
}

}  // namespace rtsim

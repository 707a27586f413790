#include "workloads/packet.h"

#include <algorithm>
#include <vector>

#include "workloads/intersect.h"
#include "workloads/reduced_box.h"

namespace rtsim {

void PacketStats::add(const PacketStats& o) {
    packets += o.packets;
    node_visits += o.node_visits;
    active_lanes += o.active_lanes;
    lane_slots += o.lane_slots;
    box_tests += o.box_tests;
    tri_tests += o.tri_tests;
    switches += o.switches;
    single_ray_nodes += o.single_ray_nodes;
}

namespace {

struct PacketEntry {
    uint32_t child, count;  // as WideNode lanes: node index, or leaf first slot and count
    uint64_t mask;          // rays that hit this child's box
    float tnear;            // the nearest of those rays' entry distances, for ordering
};

template <int W>
void traverse_packet(const Bvh& bvh, const Ray* rays, const RayPrecomp* rp, int n, HitQuery query,
                     Hit* hits, uint64_t start_mask, const PacketOptions& opt, PacketStats& st,
                     std::vector<Step>* steps) {
    const auto& nodes = bvh.nodes<W>();
    const bool any = query == HitQuery::Any;
    uint64_t done = 0;  // any-hit rays that found their hit
    std::vector<PacketEntry> stack;
    stack.push_back({0, 0, start_mask, 0.0f});
    while (!stack.empty()) {
        const PacketEntry e = stack.back();
        stack.pop_back();
        uint64_t mask = e.mask & ~done;
        if (!mask) continue;
        // Culled when every ray of the entry has found a hit nearer than its nearest entry point.
        float far_hit = 0.0f;
        for (uint64_t m = mask; m; m &= m - 1)
            far_hit = std::max(far_hit, hits[__builtin_ctzll(m)].t);
        if (e.tnear > far_hit * kCullScale) continue;
        if (e.count) {
            uint8_t tested[256] = {};  // per triangle of the leaf: rays that test it
            for (uint64_t m = mask; m; m &= m - 1) {
                const int i = __builtin_ctzll(m);
                for (uint32_t k = 0; k < e.count; ++k) {
                    const uint32_t slot = e.child + k;
                    const auto& v = bvh.tri_verts[slot];
                    st.tri_tests++;
                    tested[k]++;
                    if (intersect_triangle(rp[i], v[0], v[1], v[2], rays[i].tmin, hits[i])) {
                        hits[i].prim = bvh.prim_order[slot];
                        if (any) {
                            done |= uint64_t(1) << i;
                            break;
                        }
                    }
                }
            }
            if (steps)
                for (uint32_t k = 0; k < e.count; ++k) {
                    steps->push_back(bvh.layout.tri_step(e.child + k));
                    steps->back().lanes = tested[k];
                }
            continue;
        }
        const int active = __builtin_popcountll(mask);
        if (opt.switch_threshold > 0.0f && active < opt.switch_threshold * n) {
            // Too few rays left to fill the lanes: finish this subtree one ray at a time.
            st.switches++;
            for (uint64_t m = mask; m; m &= m - 1) {
                const int i = __builtin_ctzll(m);
                TraceCounters c;
                trace_subtree(bvh, rays[i], query, e.child, 0, hits[i], c);
                st.single_ray_nodes += c.nodes;
                st.box_tests += c.box_tests;
                st.tri_tests += c.tri_tests;
                if (any && hits[i].valid()) done |= uint64_t(1) << i;
            }
            continue;
        }
        const WideNode<W>& node = nodes[e.child];
        if (steps) {
            steps->push_back(bvh.layout.node_step(e.child, node.num));
            steps->back().lanes = uint8_t(active);
        }
        st.node_visits++;
        st.active_lanes += uint64_t(active);
        st.lane_slots += uint64_t(n);
        PacketEntry kids[W];
        int k = 0;
        for (int l = 0; l < node.num; ++l) {
            const AABB box = node.box(l);
            PacketEntry c{node.child[l], node.count[l], 0, std::numeric_limits<float>::infinity()};
            for (uint64_t m = mask; m; m &= m - 1) {
                const int i = __builtin_ctzll(m);
                st.box_tests++;
                float tn;
                if (intersect_box_bits(rp[i], box, rays[i].tmin, hits[i].t * kCullScale, tn,
                                       bvh.options, std::max(e.tnear, rays[i].tmin))) {
                    c.mask |= uint64_t(1) << i;
                    c.tnear = std::min(c.tnear, tn);
                }
            }
            if (c.mask) kids[k++] = c;
        }
        // Far children first on the stack, so the nearest is visited next (ties: lower lane).
        for (int i = 1; i < k; ++i)
            for (int j = i; j > 0 && kids[j - 1].tnear <= kids[j].tnear; --j)
                std::swap(kids[j - 1], kids[j]);
        for (int i = 0; i < k; ++i) stack.push_back(kids[i]);
    }
}

}  // namespace

void trace_packet(const Bvh& bvh, const Ray* rays, int n, HitQuery query, Hit* hits,
                  const PacketOptions& opt, PacketStats& st, std::vector<Step>* steps) {
    n = std::clamp(n, 0, kMaxPacketSize);
    std::vector<RayPrecomp> rp;
    rp.reserve(n);
    uint64_t mask = 0;
    for (int i = 0; i < n; ++i) {
        rp.emplace_back(rays[i]);
        hits[i] = Hit();
        hits[i].t = rays[i].tmax;
        float tn;
        if (finite_ray(rays[i]) && intersect_box_bits(rp[i], bvh.bounds(), rays[i].tmin,
                                                      rays[i].tmax, tn, bvh.options, rays[i].tmin))
            mask |= uint64_t(1) << i;
    }
    st.packets++;
    if (mask) {
        switch (bvh.width()) {
            case 2:
                traverse_packet<2>(bvh, rays, rp.data(), n, query, hits, mask, opt, st, steps);
                break;
            case 4:
                traverse_packet<4>(bvh, rays, rp.data(), n, query, hits, mask, opt, st, steps);
                break;
            default:
                traverse_packet<8>(bvh, rays, rp.data(), n, query, hits, mask, opt, st, steps);
                break;
        }
    }
    for (int i = 0; i < n; ++i)
        if (!hits[i].valid()) hits[i].t = std::numeric_limits<float>::infinity();
}

}  // namespace rtsim

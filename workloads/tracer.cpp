#include "workloads/tracer.h"

#include "workloads/intersect.h"

namespace rtsim {
namespace {

struct NullSink {
    void node(const BvhLayout&, uint32_t, uint8_t) {}
    void tri(const BvhLayout&, uint32_t) {}
};

struct VectorSink {
    std::vector<Step>* out;
    void node(const BvhLayout& L, uint32_t index, uint8_t children) {
        out->push_back(
            {L.node_addr(index), index, uint16_t(L.node_size_bytes), StepKind::Node, children});
    }
    void tri(const BvhLayout& L, uint32_t slot) {
        out->push_back({L.tri_addr(slot), slot, uint16_t(L.tri_size_bytes), StepKind::Triangle, 1});
    }
};

// A box's entry distance and a triangle's hit distance on the box's face are two roundings of
// one number and may differ by a few ulps. Culling boxes strictly beyond the current hit could
// then drop a triangle that is nearer than the one found: keep boxes within this margin.
constexpr float kCullScale = 1.0f + 1.0f / 65536.0f;

struct Entry {
    uint32_t child;  // node index, or first triangle slot of a leaf
    uint32_t count;  // 0: inner node; otherwise leaf triangle count
    float tnear;
};

// Tests the ray against all W child boxes of a node at once (a loop the compiler vectorises);
// writes the entry distance of each child hit and returns the hit lanes as a bit mask.
template <int W>
inline unsigned box_test(const WideNode<W>& n, const RayPrecomp& r, float tmin, float tmax,
                         float* tnear) {
    unsigned mask = 0;
    for (int l = 0; l < W; ++l) {
        const float x0 = (n.lo_x[l] - r.org.x) * r.inv_dir.x,
                    x1 = (n.hi_x[l] - r.org.x) * r.inv_dir.x;
        const float y0 = (n.lo_y[l] - r.org.y) * r.inv_dir.y,
                    y1 = (n.hi_y[l] - r.org.y) * r.inv_dir.y;
        const float z0 = (n.lo_z[l] - r.org.z) * r.inv_dir.z,
                    z1 = (n.hi_z[l] - r.org.z) * r.inv_dir.z;
        const float tn = std::max(std::max(std::min(x0, x1), std::min(y0, y1)),
                                  std::max(std::min(z0, z1), tmin));
        const float tf = std::min(std::min(std::max(x0, x1), std::max(y0, y1)) * kSlabFarScale,
                                  std::min(std::max(z0, z1) * kSlabFarScale, tmax));
        tnear[l] = tn;
        mask |= unsigned(tn <= tf) << l;
    }
    return mask;
}

template <int W, class Sink>
Hit traverse(const Bvh& bvh, const Ray& ray, HitQuery query, Sink& sink, TraceCounters& c) {
    Hit hit;
    hit.t = ray.tmax;
    const RayPrecomp rp(ray);
    float root_t;
    if (!intersect_box(rp, bvh.bounds(), ray.tmin, ray.tmax, root_t)) {
        hit.t = std::numeric_limits<float>::infinity();
        return hit;
    }
    const std::vector<WideNode<W>>& nodes = bvh.nodes<W>();
    // Each pop pushes at most W-1 entries more than it removes, per level of depth.
    Entry stack[(W - 1) * kMaxBvhDepth + 2];
    int sp = 0;
    stack[sp++] = {0, 0, root_t};
    uint32_t depth_max = 1;
    const bool any = query == HitQuery::Any;
    while (sp > 0) {
        const Entry e = stack[--sp];
        if (e.tnear > hit.t * kCullScale) continue;  // a closer hit was found after the push
        if (e.count) {
            for (uint32_t i = 0; i < e.count; ++i) {
                const uint32_t slot = e.child + i;
                const auto& v = bvh.tri_verts[slot];
                sink.tri(bvh.layout, slot);
                c.tri_tests++;
                if (intersect_triangle(rp, v[0], v[1], v[2], ray.tmin, hit)) {
                    hit.prim = bvh.prim_order[slot];
                    if (any) return hit;
                }
            }
            continue;
        }
        const WideNode<W>& n = nodes[e.child];
        sink.node(bvh.layout, e.child, n.num);
        c.nodes++;
        c.box_tests += n.num;
        float tn[W];
        unsigned mask = box_test<W>(n, rp, ray.tmin, hit.t * kCullScale, tn) &
                        ((1u << n.num) - 1);  // empty lanes off
        // Push hit children far to near, so the nearest is popped first.
        int order[W], k = 0;
        for (; mask; mask &= mask - 1) {
            const int l = __builtin_ctz(mask);
            int j = k++;
            while (j > 0 && tn[order[j - 1]] <= tn[l]) {  // ties: lower lane popped first
                order[j] = order[j - 1];
                --j;
            }
            order[j] = l;
        }
        for (int i = 0; i < k; ++i)
            stack[sp++] = {n.child[order[i]], n.count[order[i]], tn[order[i]]};
        depth_max = std::max<uint32_t>(depth_max, sp);
    }
    c.max_stack = depth_max;
    if (!hit.valid()) hit.t = std::numeric_limits<float>::infinity();
    return hit;
}

template <class Sink>
Hit dispatch(const Bvh& bvh, const Ray& ray, HitQuery q, Sink& sink, TraceCounters& c) {
    switch (bvh.width()) {
        case 2:
            return traverse<2>(bvh, ray, q, sink, c);
        case 4:
            return traverse<4>(bvh, ray, q, sink, c);
        default:
            return traverse<8>(bvh, ray, q, sink, c);
    }
}

}  // namespace

Hit trace_ray(const Bvh& bvh, const Ray& ray, HitQuery query, std::vector<Step>* steps,
              TraceCounters* counters) {
    TraceCounters local;
    TraceCounters& c = counters ? *counters : local;
    if (steps) {
        VectorSink sink{steps};
        return dispatch(bvh, ray, query, sink, c);
    }
    NullSink sink;
    return dispatch(bvh, ray, query, sink, c);
}

}  // namespace rtsim

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
    void node(const BvhLayout& L, uint32_t mem_index, uint8_t children) {
        out->push_back({L.node_addr(mem_index), mem_index, uint16_t(L.node_size_bytes),
                        StepKind::Node, children});
    }
    void tri(const BvhLayout& L, uint32_t slot) {
        out->push_back({L.tri_addr(slot), slot, uint16_t(L.tri_size_bytes), StepKind::Triangle, 1});
    }
};

// A box's entry distance and a triangle's hit distance on the box's face are two roundings of
// one number and may differ by a few ulps. Culling boxes strictly beyond the current hit could
// then drop a triangle that is nearer than the one found: keep boxes within this margin.
constexpr float kCullScale = 1.0f + 1.0f / 65536.0f;

template <class Sink>
Hit traverse(const Scene& scene, const Bvh& bvh, const Ray& ray, HitQuery query, Sink& sink,
             TraceCounters& c) {
    Hit hit;
    hit.t = ray.tmax;
    const RayPrecomp rp(ray);
    float tnear;
    if (!intersect_box(rp, bvh.nodes[0].box, ray.tmin, ray.tmax, tnear)) {
        hit.t = std::numeric_limits<float>::infinity();
        return hit;
    }
    struct Entry {
        uint32_t node;
        float tnear;
    };
    Entry stack[kMaxBvhDepth + 2];  // holds at most depth + 1 entries
    int sp = 0;
    stack[sp++] = {0, tnear};
    uint32_t depth_max = 1;
    const bool any = query == HitQuery::Any;
    while (sp > 0) {
        const Entry e = stack[--sp];
        if (e.tnear > hit.t * kCullScale) continue;  // a closer hit was found after the push
        const BvhNode& n = bvh.nodes[e.node];
        if (n.is_leaf()) {
            for (uint32_t i = 0; i < n.prim_count; ++i) {
                const uint32_t slot = n.a + i;
                const uint32_t prim = bvh.prim_order[slot];
                sink.tri(bvh.layout, slot);
                c.tri_tests++;
                if (intersect_triangle(rp, scene.v(prim, 0), scene.v(prim, 1), scene.v(prim, 2),
                                       ray.tmin, hit)) {
                    hit.prim = prim;
                    if (any) return hit;
                }
            }
            continue;
        }
        sink.node(bvh.layout, n.mem_index, 2);
        c.nodes++;
        c.box_tests += 2;
        float t0, t1;
        const float tmax = hit.t * kCullScale;
        const bool h0 = intersect_box(rp, bvh.nodes[n.a].box, ray.tmin, tmax, t0);
        const bool h1 = intersect_box(rp, bvh.nodes[n.b].box, ray.tmin, tmax, t1);
        if (h0 && h1) {
            // Nearest child on top of the stack.
            if (t0 <= t1) {
                stack[sp++] = {n.b, t1};
                stack[sp++] = {n.a, t0};
            } else {
                stack[sp++] = {n.a, t0};
                stack[sp++] = {n.b, t1};
            }
        } else if (h0) {
            stack[sp++] = {n.a, t0};
        } else if (h1) {
            stack[sp++] = {n.b, t1};
        }
        depth_max = std::max<uint32_t>(depth_max, sp);
    }
    c.max_stack = depth_max;
    if (!hit.valid()) hit.t = std::numeric_limits<float>::infinity();
    return hit;
}

}  // namespace

Hit trace_ray(const Scene& scene, const Bvh& bvh, const Ray& ray, HitQuery query,
              std::vector<Step>* steps, TraceCounters* counters) {
    TraceCounters local;
    TraceCounters& c = counters ? *counters : local;
    if (steps) {
        VectorSink sink{steps};
        return traverse(scene, bvh, ray, query, sink, c);
    }
    NullSink sink;
    return traverse(scene, bvh, ray, query, sink, c);
}

}  // namespace rtsim

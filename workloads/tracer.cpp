#include "workloads/tracer.h"

#include <cstddef>
#include <type_traits>

#include "workloads/instances.h"
#include "workloads/intersect.h"
#include "workloads/reduced_box.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace rtsim {
namespace {

struct NullSink {
    void at_stack(int, bool) {}
    void node(const BvhLayout&, uint32_t, uint8_t) {}
    void tri(const BvhLayout&, uint32_t) {}
    void transform(uint32_t) {}
    void any_hit(const BvhLayout&, uint32_t) {}
    void enter_blas(uint32_t, uint32_t) {}
    void leave_blas() {}
};

// Records the steps with the stack as each was fetched: a leaf's first triangle carries the
// leaf's pop, the rest of its triangles none.
struct VectorSink {
    std::vector<Step>* out;
    uint8_t stack = 0;
    void at_stack(int depth, bool popped) { stack = stack_byte(unsigned(depth), popped); }
    void node(const BvhLayout& L, uint32_t index, uint8_t children) {
        out->push_back(L.node_step(index, children));
        out->back().stack = stack;
    }
    void tri(const BvhLayout& L, uint32_t slot) {
        out->push_back(L.tri_step(slot));
        out->back().stack = stack;
        stack &= uint8_t(~kStackPopped);
    }
};

// Records a two-level traversal's steps in the two-level layout's numbering: a BLAS's records
// are offset into the global ranges while it is traversed, and its stack depths sit on top of
// the TLAS's.
struct GlobalSink {
    std::vector<Step>* out;
    const BvhLayout* global;
    uint32_t node_offset = 0, tri_offset = 0;
    int base_depth = 0, tlas_depth = 0;
    bool in_blas = false;
    uint8_t stack = 0;
    void at_stack(int depth, bool popped) {
        if (!in_blas) tlas_depth = depth;
        stack = stack_byte(unsigned(base_depth + depth), popped);
    }
    void node(const BvhLayout&, uint32_t index, uint8_t children) {
        out->push_back(global->node_step(index + node_offset, children));
        out->back().stack = stack;
    }
    void tri(const BvhLayout&, uint32_t slot) {
        out->push_back(global->tri_step(slot + tri_offset));
        out->back().stack = stack;
        stack &= uint8_t(~kStackPopped);
    }
    void transform(uint32_t record) {
        out->push_back(global->transform_step(record));
        out->back().stack = stack;
        stack &= uint8_t(~kStackPopped);
    }
    void any_hit(const BvhLayout&, uint32_t slot) {
        out->push_back(global->any_hit_step(slot + tri_offset));
        out->back().stack = stack;
    }
    void enter_blas(uint32_t nodes, uint32_t tris) {
        node_offset = nodes;
        tri_offset = tris;
        base_depth = tlas_depth;
        in_blas = true;
    }
    void leave_blas() {
        node_offset = tri_offset = 0;
        base_depth = 0;
        in_blas = false;
    }
};

struct Entry {
    uint32_t child;  // node index, or first triangle slot of a leaf
    uint32_t count;  // 0: inner node; otherwise leaf triangle count
    float tnear;
};

// Per-ray constants of the wide box test: for each axis, which of a node's lo/hi arrays holds
// the near plane (by the sign of the direction), so no min/max is needed to order them, and an
// inverted (empty) lane can never be hit.
template <int W>
struct BoxRay {
    float org[3], inv[3];
    size_t near_off[3], far_off[3];  // byte offsets of the near/far arrays in WideNode<W>
    explicit BoxRay(const RayPrecomp& r) {
        const size_t lo[3] = {offsetof(WideNode<W>, lo_x), offsetof(WideNode<W>, lo_y),
                              offsetof(WideNode<W>, lo_z)};
        const size_t hi[3] = {offsetof(WideNode<W>, hi_x), offsetof(WideNode<W>, hi_y),
                              offsetof(WideNode<W>, hi_z)};
        for (int a = 0; a < 3; ++a) {
            org[a] = r.org[a];
            inv[a] = r.inv_dir[a];
            const bool negative = std::signbit(r.inv_dir[a]);
            near_off[a] = negative ? hi[a] : lo[a];
            far_off[a] = negative ? lo[a] : hi[a];
        }
    }
    const float* plane(const WideNode<W>& n, size_t off) const {
        return reinterpret_cast<const float*>(reinterpret_cast<const char*>(&n) + off);
    }
};

// Tests the ray against all W child boxes of a node; writes each lane's entry distance and
// returns the hit lanes as a bit mask. The far distance is scaled by kSlabFarScale (Ize 2013).
template <int W>
inline unsigned box_test(const WideNode<W>& n, const BoxRay<W>& r, float tmin, float tmax,
                         float* tnear) {
#if defined(__SSE2__)
    if constexpr (W % 4 == 0) {
        unsigned mask = 0;
        const __m128 scale = _mm_set1_ps(kSlabFarScale);
        for (int k = 0; k < W; k += 4) {
            __m128 tn = _mm_set1_ps(tmin), tf = _mm_set1_ps(tmax);
            for (int a = 0; a < 3; ++a) {
                const __m128 o = _mm_set1_ps(r.org[a]), inv = _mm_set1_ps(r.inv[a]);
                const __m128 t0 =
                    _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(r.plane(n, r.near_off[a]) + k), o), inv);
                const __m128 t1 =
                    _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(r.plane(n, r.far_off[a]) + k), o), inv);
                // The new distance first: max/min return the second operand when either is
                // NaN, so a NaN distance (origin in a plane the ray runs along) is ignored.
                tn = _mm_max_ps(t0, tn);
                tf = _mm_min_ps(_mm_mul_ps(t1, scale), tf);
            }
            _mm_storeu_ps(tnear + k, tn);
            mask |= unsigned(_mm_movemask_ps(_mm_cmple_ps(tn, tf))) << k;
        }
        return mask;
    }
#endif
    unsigned mask = 0;
    for (int l = 0; l < W; ++l) {
        float tn = tmin, tf = tmax;
        for (int a = 0; a < 3; ++a) {
            const float t0 = (r.plane(n, r.near_off[a])[l] - r.org[a]) * r.inv[a];
            const float t1 = (r.plane(n, r.far_off[a])[l] - r.org[a]) * r.inv[a] * kSlabFarScale;
            tn = t0 > tn ? t0 : tn;
            tf = t1 < tf ? t1 : tf;
        }
        tnear[l] = tn;
        mask |= unsigned(tn <= tf) << l;
    }
    return mask;
}

// box_test on the reduced-precision datapath, lane by lane (the fp32 path's mask and tnear).
template <int W>
inline unsigned box_test_reduced(const WideNode<W>& n, const ReducedBoxRay& r, float tmin,
                                 float tmax, float* tnear, float t_ref) {
    unsigned mask = 0;
    for (int l = 0; l < n.num; ++l)
        if (intersect_box_reduced(r, n.box(l), tmin, tmax, tnear[l], t_ref)) mask |= 1u << l;
    return mask;
}

// Watertight test of up to four triangles at once: the same IEEE operations in the same order as
// intersect_triangle_perm, lane by lane, so results are bit-identical. Returns the mask of lanes
// below `lanes` hit with t in [tmin, tmax) and fills t, u, v; or -1 when a lane lies exactly on
// an edge in float (U, V or W is 0), for the caller to decide with the scalar test's
// double-precision fallback.
inline int intersect_tri4(const RayPrecomp& r, const Tri4& tri, int lanes, float tmin, float tmax,
                          float* t, float* u, float* v) {
#if defined(__SSE2__)
    const __m128 ox = _mm_set1_ps(r.org[r.kx]), oy = _mm_set1_ps(r.org[r.ky]),
                 oz = _mm_set1_ps(r.org[r.kz]);
    const __m128 sx = _mm_set1_ps(r.sx), sy = _mm_set1_ps(r.sy), sz = _mm_set1_ps(r.sz);
    __m128 px[3], py[3],
        pz[3];  // vertices relative to the origin, sheared: x, y; and z before shearing
    for (int vert = 0; vert < 3; ++vert) {
        const __m128 z = _mm_sub_ps(_mm_load_ps(tri.v[vert][r.kz]), oz);
        px[vert] = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(tri.v[vert][r.kx]), ox), _mm_mul_ps(sx, z));
        py[vert] = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(tri.v[vert][r.ky]), oy), _mm_mul_ps(sy, z));
        pz[vert] = z;
    }
    const __m128 U = _mm_sub_ps(_mm_mul_ps(px[2], py[1]), _mm_mul_ps(py[2], px[1]));
    const __m128 V = _mm_sub_ps(_mm_mul_ps(px[0], py[2]), _mm_mul_ps(py[0], px[2]));
    const __m128 Wc = _mm_sub_ps(_mm_mul_ps(px[1], py[0]), _mm_mul_ps(py[1], px[0]));
    const __m128 zero = _mm_setzero_ps();
    const int valid = (1 << lanes) - 1;
    const __m128 on_edge =
        _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(U, zero), _mm_cmpeq_ps(V, zero)), _mm_cmpeq_ps(Wc, zero));
    if (_mm_movemask_ps(on_edge) & valid) return -1;
    const __m128 neg =
        _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(U, zero), _mm_cmplt_ps(V, zero)), _mm_cmplt_ps(Wc, zero));
    const __m128 pos =
        _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(U, zero), _mm_cmpgt_ps(V, zero)), _mm_cmpgt_ps(Wc, zero));
    const __m128 det = _mm_add_ps(_mm_add_ps(U, V), Wc);
    const __m128 T = _mm_add_ps(
        _mm_add_ps(_mm_mul_ps(U, _mm_mul_ps(sz, pz[0])), _mm_mul_ps(V, _mm_mul_ps(sz, pz[1]))),
        _mm_mul_ps(Wc, _mm_mul_ps(sz, pz[2])));
    const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), det);
    const __m128 tt = _mm_mul_ps(T, inv);
    const __m128 ok =
        _mm_and_ps(_mm_cmpge_ps(tt, _mm_set1_ps(tmin)), _mm_cmplt_ps(tt, _mm_set1_ps(tmax)));
    const __m128 good = _mm_andnot_ps(_mm_or_ps(_mm_and_ps(neg, pos), _mm_cmpeq_ps(det, zero)), ok);
    _mm_storeu_ps(t, tt);
    _mm_storeu_ps(u, _mm_mul_ps(V, inv));
    _mm_storeu_ps(v, _mm_mul_ps(Wc, inv));
    return _mm_movemask_ps(good) & valid;
#else
    (void)r, (void)tri, (void)lanes, (void)tmin, (void)tmax, (void)t, (void)u, (void)v;
    return -1;
#endif
}

// Tests a leaf's triangles (slots first .. first+count-1, in order). Returns true when an any-hit
// query found its hit. Steps and counters are exactly those of testing one triangle at a time:
// an any-hit query stops at the first hit in slot order; a closest-hit query keeps the nearest
// (the earliest slot on a tie).
template <class Sink, class Counters>
inline bool test_leaf(const Bvh& bvh, const RayPrecomp& rp, const Ray& ray, bool any,
                      uint32_t first, uint32_t count, Hit& hit, Sink& sink, Counters& c) {
    uint32_t block = bvh.leaf_block[first];
    for (uint32_t base = 0; base < count; base += 4, ++block) {
        const int lanes = int(std::min<uint32_t>(4, count - base));
        alignas(16) float t[4], u[4], v[4];
        const int mask = intersect_tri4(rp, bvh.tri4[block], lanes, ray.tmin, hit.t, t, u, v);
        if (mask < 0) {
            // A lane on an edge: decide this block one triangle at a time.
            for (int l = 0; l < lanes; ++l) {
                const uint32_t slot = first + base + l;
                const auto& tv = bvh.tri_verts[slot];
                sink.tri(bvh.layout, slot);
                c.tri_tests++;
                if (intersect_triangle(rp, tv[0], tv[1], tv[2], ray.tmin, hit)) {
                    hit.prim = bvh.prim_order[slot];
                    if (any) return true;
                }
            }
            continue;
        }
        int pick = -1;
        if (mask) {
            if (any) {
                pick = __builtin_ctz(unsigned(mask));
            } else {
                for (int l = 0; l < lanes; ++l)
                    if ((mask >> l) & 1 && (pick < 0 || t[l] < t[pick])) pick = l;
            }
        }
        const int tested = any && pick >= 0 ? pick + 1 : lanes;
        for (int l = 0; l < tested; ++l) sink.tri(bvh.layout, first + base + l);
        c.tri_tests += tested;
        if (pick >= 0) {
            hit.t = t[pick];
            hit.u = u[pick];
            hit.v = v[pick];
            hit.prim = bvh.prim_order[first + base + pick];
            if (any) return true;
        }
    }
    return false;
}

// A leaf of a non-opaque instance's triangles (slots first .. first+count-1), tested one by one
// in slot order: each triangle hit nearer than the best hit so far is a candidate for the
// any-hit shader (a triangle step, then an any-hit step), which commits it if the alpha mask
// accepts it (ending an any-hit query) and otherwise lets traversal go on. Returns true when an
// any-hit query found its hit. The four-wide test gives the same hits as the scalar one, so the
// candidates are those of testing one triangle at a time.
template <class Sink, class Counters>
inline bool test_leaf_alpha(const Bvh& bvh, const RayPrecomp& rp, const Ray& ray, bool any,
                            uint32_t first, uint32_t count, Hit& hit, Sink& sink, Counters& c,
                            const AlphaMask& alpha) {
    uint32_t block = bvh.leaf_block[first];
    for (uint32_t base = 0; base < count; base += 4, ++block) {
        const int lanes = int(std::min<uint32_t>(4, count - base));
        alignas(16) float t[4], u[4], v[4];
        const int mask = intersect_tri4(rp, bvh.tri4[block], lanes, ray.tmin, hit.t, t, u, v);
        for (int l = 0; l < lanes; ++l) {
            const uint32_t slot = first + base + l;
            sink.tri(bvh.layout, slot);
            c.tri_tests++;
            Hit candidate = hit;
            if (mask < 0) {  // a lane on an edge: the scalar test decides
                const auto& tv = bvh.tri_verts[slot];
                if (!intersect_triangle(rp, tv[0], tv[1], tv[2], ray.tmin, candidate)) continue;
            } else {
                if (!((mask >> l) & 1) || !(t[l] < hit.t)) continue;
                candidate.t = t[l];
                candidate.u = u[l];
                candidate.v = v[l];
            }
            const uint32_t prim = bvh.prim_order[slot];
            sink.any_hit(bvh.layout, slot);
            c.any_hits++;
            if (!alpha.accepts(prim, candidate.u, candidate.v)) continue;
            candidate.prim = prim;
            hit = candidate;
            if (any) return true;
        }
    }
    return false;
}

struct TriangleLeaf {};
struct AlphaLeaf {
    const AlphaMask* alpha;
};

// Counting is compiled out of the fastest path (no counters requested).
struct NoCounters {
    // never read: optimised away
    uint32_t nodes = 0, box_tests = 0, tri_tests = 0, max_stack = 0, any_hits = 0;
};

// Traverses from `start` (the root record, or any subtree) with `hit` holding the best hit so far.
// Reduced: the box unit's reduced-precision datapath (a template argument, so the fp32 path
// carries no test of it).
// Leaves of triangles (the one-level tree, and every BLAS: TriangleLeaf, or AlphaLeaf for a
// non-opaque instance's) are tested in place; any other `leaf` is called as
// leaf(first, count, hit) (a TLAS's instances) and returns true when an any-hit query is done. (In
// place, not through a closure: a closure's references cost the one-level path 2-4% of its speed.)
template <int W, bool Reduced, class Sink, class Counters, class Leaf>
Hit traverse(const Bvh& bvh, const Ray& ray, const RayPrecomp& rp, HitQuery query, Entry start,
             Hit hit, Sink& sink, Counters& c, Leaf& leaf) {
    const bool any = query == HitQuery::Any;
    const auto& nodes = bvh.nodes<W>();
    const BoxRay<W> box_ray(rp);
    const ReducedBoxRay reduced_ray(rp, Reduced ? bvh.options.box_mantissa_bits : kFullMantissaBits,
                                    bvh.options.box_translate_origin);
    // Each node visit pushes at most W-1 entries, once per level of depth.
    Entry stack[(W - 1) * kMaxBvhDepth + 2];
    int sp = 0;
    uint32_t depth_max = 1;
    Entry cur = start;
    bool popped = false;  // whether `cur` came off the stack
    for (;;) {
        sink.at_stack(sp, popped);
        if (cur.count) {
            bool done;
            if constexpr (std::is_same_v<Leaf, TriangleLeaf>)
                done = test_leaf(bvh, rp, ray, any, cur.child, cur.count, hit, sink, c);
            else if constexpr (std::is_same_v<Leaf, AlphaLeaf>)
                done = test_leaf_alpha(bvh, rp, ray, any, cur.child, cur.count, hit, sink, c,
                                       *leaf.alpha);
            else
                done = leaf(cur.child, cur.count, hit);
            if (done) {
                c.max_stack = depth_max;
                return hit;
            }
        } else {
            const WideNode<W>& n = nodes[cur.child];
            sink.node(bvh.layout, cur.child, n.num);
            c.nodes++;
            c.box_tests += n.num;
            float tn[W];
            unsigned mask = Reduced
                                ? box_test_reduced<W>(n, reduced_ray, ray.tmin, hit.t * kCullScale,
                                                      tn, std::max(cur.tnear, ray.tmin))
                                : box_test<W>(n, box_ray, ray.tmin, hit.t * kCullScale, tn);
            if (mask) {
                // Sort hit children far to near; go on with the nearest, push the others.
                int order[W], k = 0;
                for (; mask; mask &= mask - 1) {
                    const int l = __builtin_ctz(mask);
                    int j = k++;
                    while (j > 0 && tn[order[j - 1]] <= tn[l]) {  // ties: lower lane first
                        order[j] = order[j - 1];
                        --j;
                    }
                    order[j] = l;
                }
                for (int i = 0; i < k - 1; ++i)
                    stack[sp++] = {n.child[order[i]], n.count[order[i]], tn[order[i]]};
                depth_max = std::max<uint32_t>(depth_max, sp + 1);
                cur = {n.child[order[k - 1]], n.count[order[k - 1]], tn[order[k - 1]]};
                popped = false;
                continue;
            }
        }
        // Pop the next entry that a closer hit, found after its push, has not culled.
        do {
            if (sp == 0) {
                c.max_stack = depth_max;
                return hit;  // a miss keeps t = the ray's bound; callers report it as inf
            }
            cur = stack[--sp];
        } while (cur.tnear > hit.t * kCullScale);
        popped = true;
    }
}

template <bool Reduced, class Sink, class Counters, class Leaf>
Hit dispatch_width(const Bvh& bvh, const Ray& ray, const RayPrecomp& rp, HitQuery q, Entry start,
                   Hit hit, Sink& sink, Counters& c, Leaf& leaf) {
    switch (bvh.width()) {
        case 2:
            return traverse<2, Reduced>(bvh, ray, rp, q, start, hit, sink, c, leaf);
        case 4:
            return traverse<4, Reduced>(bvh, ray, rp, q, start, hit, sink, c, leaf);
        default:
            return traverse<8, Reduced>(bvh, ray, rp, q, start, hit, sink, c, leaf);
    }
}

// One level: leaves hold triangles.
template <class Sink, class Counters>
Hit dispatch(const Bvh& bvh, const Ray& ray, HitQuery q, Entry start, Hit hit, Sink& sink,
             Counters& c) {
    const RayPrecomp rp(ray);
    TriangleLeaf leaf;
    return bvh.options.box_mantissa_bits < kFullMantissaBits
               ? dispatch_width<true>(bvh, ray, rp, q, start, hit, sink, c, leaf)
               : dispatch_width<false>(bvh, ray, rp, q, start, hit, sink, c, leaf);
}

// Two levels: the TLAS's leaves hold instances, each entered through its transform into its
// BLAS; the hit carries its instance.
template <bool Reduced, class Sink, class Counters>
Hit trace_two_level(const TwoLevelBvh& two, const Ray& ray, const RayPrecomp& rp, HitQuery q,
                    Entry start, Hit hit, uint8_t mask, Sink& sink, Counters& c) {
    const bool any = q == HitQuery::Any;
    auto instances = [&](uint32_t first, uint32_t count, Hit& h) {
        for (uint32_t slot = first; slot < first + count; ++slot) {
            const uint32_t id = two.tlas.prim_order[slot];
            const Instance& inst = two.instances[id];
            if (!(inst.mask & mask)) continue;
            sink.transform(slot);  // the instance record, then the ray moved
            const Affine3x4& w2o = two.world_to_object[id];
            Ray local;
            local.org = w2o.point(ray.org);
            local.dir = w2o.vector(ray.dir);
            local.tmin = ray.tmin;
            local.tmax = h.t;
            const Bvh& blas = two.blas[inst.mesh];
            const RayPrecomp lrp(local);
            float root_t;
            c.box_tests++;  // the BLAS root's box, kept in the instance record
            if (!finite_ray(local) || !intersect_box_bits(lrp, blas.bounds(), local.tmin, h.t,
                                                          root_t, blas.options, local.tmin))
                continue;
            Hit found;
            found.t = h.t;  // the bound: only a nearer hit replaces `h`
            sink.enter_blas(two.blas_node_offset[inst.mesh], two.blas_tri_offset[inst.mesh]);
            const Entry root{0, 0, root_t};
            if (inst.opaque) {
                TriangleLeaf tris;
                found = dispatch_width<Reduced>(blas, local, lrp, q, root, found, sink, c, tris);
            } else {
                AlphaLeaf tris{&two.alpha[inst.mesh]};
                found = dispatch_width<Reduced>(blas, local, lrp, q, root, found, sink, c, tris);
            }
            sink.leave_blas();
            if (!found.valid()) continue;
            h = found;
            h.instance = id;
            if (any) return true;
        }
        return false;
    };
    return dispatch_width<Reduced>(two.tlas, ray, rp, q, start, hit, sink, c, instances);
}

// A two-level trace from the TLAS's root box (kept on chip, as one level's), as trace_ray and
// trace_ray_recorded make it.
template <class Sink, class Counters>
Hit trace_two_level_from_root(const TwoLevelBvh& two, const Ray& ray, HitQuery query, uint8_t mask,
                              Sink& sink, Counters& c) {
    Hit hit;
    hit.t = ray.tmax;
    const RayPrecomp rp(ray);
    float root_t;
    if (!two.instances.empty() && finite_ray(ray) &&
        intersect_box_bits(rp, two.bounds(), ray.tmin, ray.tmax, root_t, two.options, ray.tmin)) {
        const Entry root = {0, 0, root_t};
        hit = two.options.box_mantissa_bits < kFullMantissaBits
                  ? trace_two_level<true>(two, ray, rp, query, root, hit, mask, sink, c)
                  : trace_two_level<false>(two, ray, rp, query, root, hit, mask, sink, c);
    }
    return hit.valid() ? hit : Hit{};
}

}  // namespace

Hit trace_ray(const Bvh& bvh, const Ray& ray, HitQuery query, std::vector<Step>* steps,
              TraceCounters* counters) {
    Hit hit;
    hit.t = ray.tmax;
    float root_t;
    if (!finite_ray(ray) || !intersect_box_bits(RayPrecomp(ray), bvh.bounds(), ray.tmin, ray.tmax,
                                                root_t, bvh.options, ray.tmin)) {
        hit.t = std::numeric_limits<float>::infinity();
        return hit;
    }
    const Entry root = {0, 0, root_t};
    if (steps) {
        VectorSink sink{steps};
        TraceCounters local;
        hit = dispatch(bvh, ray, query, root, hit, sink, counters ? *counters : local);
    } else if (counters) {
        NullSink sink;
        hit = dispatch(bvh, ray, query, root, hit, sink, *counters);
    } else {
        NullSink sink;
        NoCounters none;
        hit = dispatch(bvh, ray, query, root, hit, sink, none);
    }
    if (!hit.valid()) hit.t = std::numeric_limits<float>::infinity();
    return hit;
}

Hit trace_ray_recorded(const Bvh& bvh, const Ray& ray, HitQuery query, std::vector<Step>& steps) {
    thread_local std::vector<Step> scratch;
    scratch.clear();
    const Hit hit = trace_ray(bvh, ray, query, &scratch);
    steps.assign(scratch.begin(), scratch.end());
    return hit;
}

void trace_subtree(const Bvh& bvh, const Ray& ray, HitQuery query, uint32_t child, uint32_t count,
                   Hit& hit, TraceCounters& counters) {
    NullSink sink;
    TraceCounters c;
    hit = dispatch(bvh, ray, query, Entry{child, count, ray.tmin}, hit, sink, c);
    counters.nodes += c.nodes;
    counters.box_tests += c.box_tests;
    counters.tri_tests += c.tri_tests;
}

Hit trace_ray(const TwoLevelBvh& two, const Ray& ray, HitQuery query, uint8_t mask,
              TraceCounters* counters) {
    NullSink sink;
    TraceCounters local;
    return trace_two_level_from_root(two, ray, query, mask, sink, counters ? *counters : local);
}

Hit trace_ray_recorded(const TwoLevelBvh& two, const Ray& ray, HitQuery query,
                       std::vector<Step>& steps, uint8_t mask, TraceCounters* counters) {
    thread_local std::vector<Step> scratch;
    scratch.clear();
    GlobalSink sink{&scratch, &two.layout};
    NoCounters none;  // counting compiled out unless asked for, as one level's fast path
    const Hit hit = counters ? trace_two_level_from_root(two, ray, query, mask, sink, *counters)
                             : trace_two_level_from_root(two, ray, query, mask, sink, none);
    steps.assign(scratch.begin(), scratch.end());
    return hit;
}

}  // namespace rtsim

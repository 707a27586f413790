#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <future>
#include <random>

#include "support/numerics_stress.h"
#include "workloads/bvh.h"
#include "workloads/intersect.h"
#include "workloads/packet.h"
#include "workloads/scene.h"
#include "workloads/tracer.h"

using namespace rtsim;

namespace {

Hit brute_force(const Scene& s, const Ray& r) {
    Hit h;
    h.t = r.tmax;
    const RayPrecomp rp(r);
    for (uint32_t p = 0; p < s.triangle_count(); ++p)
        if (intersect_triangle(rp, s.v(p, 0), s.v(p, 1), s.v(p, 2), r.tmin, h)) h.prim = p;
    if (!h.valid()) h.t = std::numeric_limits<float>::infinity();
    return h;
}

std::vector<Ray> random_rays(const AABB& b, int n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<Ray> rays;
    const Vec3 c = b.center(), e = b.extent();
    for (int i = 0; i < n; ++i) {
        Ray r;
        // Origins around and inside the scene, directions uniform: hits, misses and grazes.
        r.org = c + Vec3((u(rng) - 0.5f) * e.x * 1.5f, (u(rng) - 0.5f) * e.y * 1.5f,
                         (u(rng) - 0.5f) * e.z * 1.5f);
        Vec3 d;
        do d = Vec3(u(rng) * 2 - 1, u(rng) * 2 - 1, u(rng) * 2 - 1);
        while (dot(d, d) > 1.0f || dot(d, d) < 1e-4f);
        r.dir = normalize(d);
        if (i % 7 == 0) r.dir = Vec3(0, 0, (i % 2) ? 1.0f : -1.0f);  // axis-parallel
        if (i % 11 == 0) r.tmax = 0.3f * length(e);                  // bounded
        rays.push_back(r);
    }
    return rays;
}

}  // namespace

TEST(Tracer, ClosestHitMatchesBruteForce) {
    Scene s = load_scene("builtin:cornell");
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    int hits = 0;
    for (const Ray& r : random_rays(s.bounds(), 1000, 7)) {
        const Hit a = trace_ray(bvh, r, HitQuery::Closest);
        const Hit b = brute_force(s, r);
        ASSERT_EQ(a.valid(), b.valid());
        if (!a.valid()) continue;
        ++hits;
        // Same intersector, so the same t; the primitive may differ only on an exact tie.
        ASSERT_EQ(a.t, b.t);
        if (a.prim != b.prim) {
            Hit other;
            const RayPrecomp rp(r);
            ASSERT_TRUE(intersect_triangle(rp, s.v(a.prim, 0), s.v(a.prim, 1), s.v(a.prim, 2),
                                           r.tmin, other));
            ASSERT_EQ(other.t, b.t);
        }
    }
    EXPECT_GT(hits, 300);
}

TEST(Tracer, AnyHitAgreesWithClosestHitOnOcclusion) {
    Scene s = load_scene("builtin:sphere");
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    for (const Ray& r : random_rays(s.bounds(), 500, 3)) {
        const Hit a = trace_ray(bvh, r, HitQuery::Any);
        const Hit c = trace_ray(bvh, r, HitQuery::Closest);
        ASSERT_EQ(a.valid(), c.valid());
        if (a.valid()) {
            EXPECT_GE(a.t, c.t);
        }
    }
}

TEST(Tracer, StepStreamMatchesCountersAndLayout) {
    Scene s = load_scene("builtin:cornell");
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    const BvhLayout& L = bvh.layout;
    for (const Ray& r : random_rays(s.bounds(), 200, 5)) {
        std::vector<Step> steps;
        TraceCounters c;
        const Hit with = trace_ray(bvh, r, HitQuery::Closest, &steps, &c);
        const Hit without = trace_ray(bvh, r, HitQuery::Closest);
        ASSERT_EQ(with.prim, without.prim);
        uint32_t nodes = 0, tris = 0;
        for (const Step& st : steps) {
            if (st.kind == StepKind::Node) {
                ++nodes;
                ASSERT_EQ(st.addr, L.node_addr(st.id));
                ASSERT_LT(st.id, L.inner_node_count);
                ASSERT_EQ(st.size_bytes, L.node_size_bytes);
                ASSERT_EQ(st.count, 2);
            } else {
                ++tris;
                ASSERT_EQ(st.addr, L.tri_addr(st.id));
                ASSERT_LT(st.id, L.triangle_count);
                ASSERT_EQ(st.size_bytes, L.tri_size_bytes);
            }
        }
        ASSERT_EQ(nodes, c.nodes);
        ASSERT_EQ(tris, c.tri_tests);
        ASSERT_EQ(c.box_tests, 2 * c.nodes);
        if (!steps.empty()) {
            ASSERT_EQ(steps.front().kind, StepKind::Node);  // traversal starts at the root record
            ASSERT_EQ(steps.front().id, 0u);
        }
    }
}

// The stack each step records (Step::stack) is the traversal's: a ray starts with an empty stack
// at the root; a step fetched without a pop follows a node that pushed at most its hit children
// but one (the nearest is fetched directly), or is the next triangle of the same leaf; and the
// stack never holds more than the deepest the counters saw.
TEST(Tracer, StepsRecordTheTraversalStack) {
    Scene s = load_scene("builtin:cornell");
    for (int width : {2, 8}) {
        BvhBuildOptions o;
        o.width = width;
        Bvh bvh = build_bvh(s, o);
        uint64_t pops = 0, pushes = 0;
        for (const Ray& r : random_rays(s.bounds(), 300, 9)) {
            std::vector<Step> steps;
            TraceCounters c;
            trace_ray(bvh, r, HitQuery::Closest, &steps, &c);
            if (steps.empty()) continue;
            ASSERT_EQ(steps[0].stack, 0);
            for (size_t k = 0; k + 1 < steps.size(); ++k) {
                const Step &a = steps[k], &b = steps[k + 1];
                const int before_pop = int(stack_depth(b)) + (stack_popped(b) ? 1 : 0);
                ASSERT_LT(unsigned(before_pop), c.max_stack) << width;
                if (!stack_popped(b)) {
                    if (a.kind == StepKind::Node) {
                        const int pushed = int(stack_depth(b)) - int(stack_depth(a));
                        ASSERT_GE(pushed, 0) << width << " step " << k;
                        ASSERT_LE(pushed, int(a.count) - 1) << width << " step " << k;
                        pushes += unsigned(pushed);
                    } else {
                        ASSERT_EQ(b.kind, StepKind::Triangle) << width << " step " << k;
                        ASSERT_EQ(stack_depth(b), stack_depth(a)) << width << " step " << k;
                    }
                } else {
                    ++pops;
                    // A pop takes an entry pushed before: the stack before it was not empty.
                    ASSERT_GE(before_pop, 1);
                }
            }
        }
        EXPECT_GT(pops, 100u) << width;  // the rays did use the stack
        EXPECT_GT(pushes, 100u) << width;
    }
}

TEST(Tracer, RayMissingRootBoxCostsNoStep) {
    Scene s = load_scene("builtin:sphere");
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    Ray r;
    r.org = Vec3(10, 10, 10);
    r.dir = normalize(Vec3(1, 1, 1));
    std::vector<Step> steps;
    const Hit h = trace_ray(bvh, r, HitQuery::Closest, &steps);
    EXPECT_FALSE(h.valid());
    EXPECT_TRUE(steps.empty());
}

// A ray with a NaN origin (from a scene so large its camera overflowed) made
// the scalar box test count every box as hit, and BVH2 traversal never ended. Such a ray is now
// a miss at the root, with no step, for every width, format and builder, single or in packets.
TEST(Tracer, NonFiniteRaysMissAndEnd) {
    Scene s = load_scene("builtin:cornell");
    for (const BvhBuildOptions& o : test::bvh_variants()) {
        const int width = o.width;
        const Bvh bvh = build_bvh(s, o);
        for (float bad : {std::nanf(""), INFINITY}) {
            Ray r;
            r.org = Vec3(bad, bad, bad);
            r.dir = normalize(Vec3(0.3f, -0.2f, -1.0f));
            // Runs in a thread with a deadline: a regression hangs, it must not hang CI.
            auto done = std::async(std::launch::async, [&] {
                std::vector<Step> steps;
                return std::make_pair(trace_ray(bvh, r, HitQuery::Closest, &steps), steps.size());
            });
            if (done.wait_for(std::chrono::seconds(20)) != std::future_status::ready) {
                ADD_FAILURE() << "traversal of a non-finite ray does not end (BVH" << width;
                std::_Exit(1);
            }
            const auto [hit, steps] = done.get();
            EXPECT_FALSE(hit.valid()) << width;
            EXPECT_EQ(steps, 0u) << width;
            // In a packet with a finite ray: the bad lanes miss, the good one is traced.
            Ray rays[3] = {r, r, r};
            rays[1].org = Vec3(0.0f, 0.0f, 5.0f);
            rays[1].dir = Vec3(0.0f, 0.0f, -1.0f);
            Hit hits[3];
            PacketOptions po;
            po.size = 3;
            PacketStats ps;
            trace_packet(bvh, rays, 3, HitQuery::Closest, hits, po, ps);
            EXPECT_FALSE(hits[0].valid() || hits[2].valid()) << width;
            EXPECT_EQ(hits[1].valid(), trace_ray(bvh, rays[1], HitQuery::Closest).valid());
        }
    }
}

TEST(Intersect, WatertightOnSharedEdgesAndVertices) {
    // A fan of triangles around a vertex: rays exactly through the shared vertex and through
    // every shared edge must hit at least one triangle.
    Scene s;
    s.vertices.push_back({0, 0, 0});
    const int n = 7;
    for (int i = 0; i < n; ++i) {
        const float a = 6.2831853f * i / n;
        s.vertices.push_back({std::cos(a), std::sin(a), 0});
    }
    for (int i = 0; i < n; ++i)
        s.triangles.push_back({0, uint32_t(1 + i), uint32_t(1 + (i + 1) % n)});
    auto hits_any = [&](const Ray& r) {
        const RayPrecomp rp(r);
        for (uint32_t p = 0; p < s.triangle_count(); ++p) {
            Hit h;
            if (intersect_triangle(rp, s.v(p, 0), s.v(p, 1), s.v(p, 2), 0.0f, h)) return true;
        }
        return false;
    };
    for (Vec3 o : {Vec3(0, 0, 1), Vec3(0.3f, -0.2f, 2.0f), Vec3(-5, 3, 7)}) {
        Ray r;
        r.org = o;
        r.dir = normalize(Vec3(0, 0, 0) - o);
        EXPECT_TRUE(hits_any(r)) << "through the shared vertex";
        for (int i = 0; i < n; ++i) {
            for (float f : {0.1f, 0.37f, 0.5f, 0.93f}) {
                Ray e;
                e.org = o;
                e.dir = normalize(s.vertices[1 + i] * f - o);
                EXPECT_TRUE(hits_any(e)) << "through edge " << i << " at " << f;
            }
        }
    }
}

TEST(Intersect, SlabTestHandlesAxisParallelRaysOnPlanes) {
    AABB b;
    b.lo = Vec3(0, 0, 0);
    b.hi = Vec3(1, 1, 1);
    Ray r;
    r.org = Vec3(0, 0.5f, -1);  // on the x = 0 plane, parallel to it
    r.dir = Vec3(0, 0, 1);
    float tn;
    EXPECT_TRUE(intersect_box(RayPrecomp(r), b, 0.0f, 100.0f, tn));
    EXPECT_FLOAT_EQ(tn, 1.0f);
    r.org = Vec3(-1e-3f, 0.5f, -1);  // just outside
    EXPECT_FALSE(intersect_box(RayPrecomp(r), b, 0.0f, 100.0f, tn));
    r.org = Vec3(0.5f, 0.5f, 0.5f);  // inside: enters at tmin
    EXPECT_TRUE(intersect_box(RayPrecomp(r), b, 0.0f, 100.0f, tn));
    EXPECT_EQ(tn, 0.0f);
}

// A ray lying exactly in a box's face plane overlaps the (closed) box whatever
// the sign of its zero direction component, on the lower and the upper face, for tmin 0 and > 0.
// (With a clamped reciprocal, 1 of the 4 sign and face pairs culled it once tmin > 0.)
TEST(Intersect, RaysInAFacePlaneOverlapWhateverTheSignOfZero) {
    AABB b;
    b.lo = Vec3(0, 0, 0);
    b.hi = Vec3(1, 1, 1);
    int checked = 0;
    for (int a = 0; a < 3; ++a) {          // the axis whose direction component is zero
        const int m = (a + 1) % 3;         // the axis the ray moves along
        for (float face : {0.0f, 1.0f}) {  // lies in the lower or the upper face plane
            for (float zero : {0.0f, -0.0f}) {
                for (float tmin : {0.0f, 1e-3f}) {
                    Ray r;
                    r.org = Vec3(0.5f, 0.5f, 0.5f);
                    r.org[a] = face;
                    r.org[m] = -1.0f;
                    r.dir = Vec3(0, 0, 0);
                    r.dir[m] = 1.0f;
                    r.dir[a] = zero;
                    float tn = -1;
                    EXPECT_TRUE(intersect_box(RayPrecomp(r), b, tmin, 100.0f, tn))
                        << "axis " << a << " face " << face << " zero " << zero << " tmin " << tmin;
                    EXPECT_FLOAT_EQ(tn, 1.0f);
                    ++checked;
                }
            }
        }
    }
    EXPECT_EQ(checked, 3 * 2 * 2 * 2);
}

namespace {
// A unit quad in the z = 0 plane, as two triangles (flat, axis-aligned geometry: a floor).
Scene flat_quad() {
    Scene s;
    s.name = "flat_quad";
    s.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    s.triangles = {{0, 1, 2}, {0, 2, 3}};
    return s;
}
}  // namespace

// Rays straight down (x and y direction components
// +0 or -0) at every vertex and along every edge and the diagonal of an axis-aligned quad must
// hit, for every BVH width, node format and builder, closest and any hit, single rays and packets.
// (Before: an axis-aligned quad missed 40 of 88 such rays.)
TEST(Tracer, AxisAlignedQuadHitsAtVerticesAndEdgesWithSignedZeros) {
    const Scene s = flat_quad();
    std::vector<Ray> rays;
    for (float x : {0.0f, 0.25f, 0.5f, 1.0f})
        for (float y : {0.0f, 0.5f, 0.75f, 1.0f}) {
            const bool on_edge_or_diagonal = x == 0 || x == 1 || y == 0 || y == 1 || x == y;
            if (!on_edge_or_diagonal) continue;
            for (float zx : {0.0f, -0.0f})
                for (float zy : {0.0f, -0.0f}) {
                    Ray r;
                    r.org = Vec3(x, y, 1.0f);
                    r.dir = Vec3(zx, zy, -1.0f);
                    rays.push_back(r);
                }
        }
    ASSERT_GE(rays.size(), 40u);
    for (const BvhBuildOptions& o : test::bvh_variants()) {
        const Bvh bvh = build_bvh(s, o);
        int misses = 0;
        for (const Ray& r : rays)
            for (HitQuery q : {HitQuery::Closest, HitQuery::Any}) {
                const Hit h = trace_ray(bvh, r, q);
                misses += !h.valid();
                if (h.valid() && q == HitQuery::Closest) {
                    EXPECT_FLOAT_EQ(h.t, 1.0f);
                }
            }
        std::vector<Hit> hits(rays.size());
        PacketOptions po;
        po.size = 8;
        PacketStats ps;
        for (size_t i = 0; i < rays.size(); i += 8) {
            const int n = int(std::min<size_t>(8, rays.size() - i));
            trace_packet(bvh, &rays[i], n, HitQuery::Closest, &hits[i], po, ps);
        }
        for (const Hit& h : hits) misses += !h.valid();
        EXPECT_EQ(misses, 0) << test::variant_name(o) << ", of " << rays.size() * 3 << " rays";
    }
}

// Tiny direction components are not clamped, so far hits stay hits: a ray
// whose only direction component is -1e-30 reaches the quad (at t = 1e30), and rays from 1e18
// away along an axis with tiny sideways components hit it where a double-precision check says.
TEST(Tracer, TinyDirectionComponentsKeepFarHits) {
    const Bvh bvh = build_bvh(flat_quad(), BvhBuildOptions());
    Ray r;
    r.org = Vec3(0.5f, 0.5f, 1.0f);
    r.dir = Vec3(0, 0, -1e-30f);
    const Hit h = trace_ray(bvh, r, HitQuery::Closest);
    ASSERT_TRUE(h.valid());
    EXPECT_NEAR(h.t / 1e30f, 1.0f, 1e-5f);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.05f, 0.95f), side(-1e-19f, 1e-19f);
    int hits = 0, expected = 0;
    for (int i = 0; i < 2000; ++i) {
        Ray far;
        far.org = Vec3(u(rng), u(rng), 1e18f);
        far.dir = Vec3(side(rng), side(rng), -1.0f);
        // Where it crosses z = 0, in double precision: inside the quad's [0, 1]^2?
        const double t = 1e18;
        const double x = double(far.org.x) + t * double(far.dir.x);
        const double y = double(far.org.y) + t * double(far.dir.y);
        const bool inside = x > 1e-3 && x < 1 - 1e-3 && y > 1e-3 && y < 1 - 1e-3;
        const bool outside = x < -1e-3 || x > 1 + 1e-3 || y < -1e-3 || y > 1 + 1e-3;
        if (!inside && !outside) continue;  // too close to an edge to call
        const bool hit = trace_ray(bvh, far, HitQuery::Closest).valid();
        EXPECT_EQ(hit, inside) << x << " " << y;
        hits += hit;
        expected += inside;
    }
    EXPECT_GT(expected, 500);
    EXPECT_EQ(hits, expected);
}

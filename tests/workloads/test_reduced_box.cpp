// The reduced-precision box datapath (workloads/reduced_box.h): its directed rounding against
// hand-computed values, and its promise (no overlapping box is ever missed) against rays built
// to touch a box exactly, in integer arithmetic that needs no rounding at all.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "workloads/error.h"
#include "workloads/reduced_box.h"
#include "workloads/scene.h"
#include "workloads/tracer.h"

using namespace rtsim;

TEST(ReducedBox, RoundingIsDirectedToTheGivenMantissaWidth) {
    using reduced::round_down;
    using reduced::round_up;
    const double x = 1.0 + std::ldexp(1.0, -20);  // between 1 and 1 + 2^-10 at 10 bits
    EXPECT_EQ(round_up(x, 10), 1.0 + std::ldexp(1.0, -10));
    EXPECT_EQ(round_down(x, 10), 1.0);
    EXPECT_EQ(round_up(-x, 10), -1.0);
    EXPECT_EQ(round_down(-x, 10), -(1.0 + std::ldexp(1.0, -10)));
    EXPECT_EQ(round_up(1.5, 1), 1.5);  // representable: unchanged
    EXPECT_EQ(round_down(1.5, 1), 1.5);
    EXPECT_EQ(round_up(2.0 - std::ldexp(1.0, -30), 10), 2.0);  // the carry reaches the exponent
    EXPECT_EQ(round_down(2.0 - std::ldexp(1.0, -30), 10), 2.0 - std::ldexp(1.0, -10));
    EXPECT_EQ(round_up(0.0, 4), 0.0);
    EXPECT_TRUE(std::isinf(round_down(INFINITY, 4)));
    // 1/3 at 7 bits: in [0.25, 0.5) the 7-bit grid steps by 2^-2 * 2^-7 = 1/512, and
    // 512/3 = 170.67, so 1/3 lies between 170/512 and 171/512.
    const reduced::Interval third = reduced::reciprocal(3.0f, 7);
    EXPECT_EQ(third.lo, 170.0 / 512.0);
    EXPECT_EQ(third.hi, 171.0 / 512.0);
    const reduced::Interval neg = reduced::reciprocal(-3.0f, 7);
    EXPECT_EQ(neg.lo, -171.0 / 512.0);
    EXPECT_EQ(neg.hi, -170.0 / 512.0);
    const reduced::Interval half = reduced::reciprocal(2.0f, 3);  // exact: no widening
    EXPECT_EQ(half.lo, 0.5);
    EXPECT_EQ(half.hi, 0.5);
    // 1e30 - 1e-30 is below the double 1e30f, but not by a representable amount.
    const reduced::Interval d = reduced::sub(1e30f, 1e-30f, 23);
    EXPECT_LT(d.lo, double(1e30f));
    EXPECT_EQ(d.hi, double(1e30f));
    const reduced::Interval e = reduced::sub(3.0f, 1.0f, 4);  // exact
    EXPECT_EQ(e.lo, 2.0);
    EXPECT_EQ(e.hi, 2.0);
}

namespace {

// A ray that passes exactly through point q (on the box's surface) at t = k: origin q - k * d
// with integer q, d and k, scaled by a power of two, is exact in float.
struct TouchCase {
    Ray ray;
    AABB box;
};

TouchCase touching_ray(std::mt19937& rng) {
    std::uniform_int_distribution<int> coord(-1000, 1000), dir(-50, 50), steps(1, 64),
        scale_exp(-40, 40), kind(0, 2);
    const float scale = std::ldexp(1.0f, scale_exp(rng));
    int lo[3], hi[3], q[3];
    for (int a = 0; a < 3; ++a) {
        lo[a] = coord(rng);
        hi[a] = lo[a] + std::uniform_int_distribution<int>(0, 500)(rng);  // may be flat
    }
    // q on a corner, an edge or a face: k axes pinned to a plane, the rest inside.
    const int pinned = 3 - kind(rng);
    for (int a = 0; a < 3; ++a)
        q[a] = a < pinned ? (rng() & 1 ? hi[a] : lo[a])
                          : std::uniform_int_distribution<int>(lo[a], hi[a])(rng);
    int d[3];
    do {
        for (int a = 0; a < 3; ++a) d[a] = rng() % 4 == 0 ? 0 : dir(rng);
    } while (d[0] == 0 && d[1] == 0 && d[2] == 0);
    const int k = steps(rng);
    TouchCase c;
    for (int a = 0; a < 3; ++a) {
        c.box.lo[a] = float(lo[a]) * scale;
        c.box.hi[a] = float(hi[a]) * scale;
        c.ray.dir[a] = float(d[a]) * scale;
        c.ray.org[a] = float(q[a] - k * d[a]) * scale;
    }
    c.ray.tmin = 0.0f;
    c.ray.tmax = float(k);  // the touch is the last point the ray may reach
    return c;
}

}  // namespace

TEST(ReducedBox, NeverMissesABoxTheRayTouches) {
    std::mt19937 rng(7);
    int cases = 0;
    for (int i = 0; i < 20000; ++i) {
        const TouchCase c = touching_ray(rng);
        const RayPrecomp rp(c.ray);
        // Translated to a reference distance: any is correct (before, at or past the touch).
        const float t_ref = float(i % 4) * 0.5f * c.ray.tmax;
        for (int bits : {22, 16, 10, 7, 5, 3, 2})
            for (bool translate : {false, true}) {
                float tn = -1;
                ASSERT_TRUE(intersect_box_reduced(ReducedBoxRay(rp, bits, translate), c.box,
                                                  c.ray.tmin, c.ray.tmax, tn, t_ref))
                    << "bits " << bits << " translate " << translate << " case " << i;
                ASSERT_LE(tn, c.ray.tmax);
                ++cases;
            }
        // The fp32 test keeps the same promise (Ize 2013) for a touch inside [tmin, tmax]; at
        // exactly tmax its rounded entry distance may land beyond, which loses nothing: a
        // triangle hit must lie strictly before tmax.
        float tn;
        ASSERT_TRUE(intersect_box(rp, c.box, c.ray.tmin, 2 * c.ray.tmax, tn)) << "fp32 case " << i;
    }
    EXPECT_EQ(cases, 20000 * 7 * 2);
}

// Coarser grids contain finer ones, and each operation's outward rounding is monotone, so a box
// that a wider datapath enters is entered by every narrower one; entry distances only move
// earlier.
TEST(ReducedBox, NarrowerDatapathsEnterEveryBoxWiderOnesDo) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    int entered_at_22 = 0, entered_at_2 = 0;
    for (int i = 0; i < 20000; ++i) {
        AABB b;
        for (int a = 0; a < 3; ++a) {
            const float x = u(rng), y = u(rng);
            b.lo[a] = std::min(x, y);
            b.hi[a] = std::max(x, y);
        }
        Ray r;
        r.org = Vec3(3 * u(rng), 3 * u(rng), 3 * u(rng));
        r.dir = Vec3(1.2f * u(rng), 1.2f * u(rng), 1.2f * u(rng)) - r.org;  // near the box
        if (i % 5 == 0) r.dir[i % 3] = 0.0f;
        const RayPrecomp rp(r);
        const bool translate = i % 2;
        const float t_ref = translate ? 0.5f : 0.0f;
        bool wider = false;
        float wider_tn = 0;
        for (int bits = 22; bits >= 2; --bits) {
            float tn = 0;
            const bool hit = intersect_box_reduced(ReducedBoxRay(rp, bits, translate), b, 0.0f,
                                                   10.0f, tn, t_ref);
            if (wider) {
                ASSERT_TRUE(hit) << "case " << i << " entered at " << bits + 1 << " bits, not "
                                 << bits;
                ASSERT_LE(tn, wider_tn);
            }
            wider = hit;
            wider_tn = tn;
            if (bits == 22) entered_at_22 += hit;
            if (bits == 2) entered_at_2 += hit;
        }
    }
    // Not a vacuous check: both outcomes occur, and narrowing enters more boxes.
    EXPECT_GT(entered_at_22, 1000);
    EXPECT_LT(entered_at_22, 19000);
    EXPECT_GT(entered_at_2, entered_at_22);
}

// Whole traversals: reduced box units only add work, never change an answer; translating the
// origin to the node keeps the extra work small. The built-in
// sphere, primary-like rays from a ring of origins, each width and node format.
TEST(ReducedBox, TraversalFindsTheSameHitsWithMoreWork) {
    const Scene s = make_builtin_scene("sphere");
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<Ray> rays;
    const AABB bounds = s.bounds();
    const Vec3 c = (bounds.lo + bounds.hi) * 0.5f;
    const float size = max_component(bounds.hi - bounds.lo);
    for (int i = 0; i < 3000; ++i) {
        Ray r;
        r.org = c + Vec3(u(rng), u(rng), u(rng)) * (2 * size);
        r.dir = normalize(c + Vec3(u(rng), u(rng), u(rng)) * (0.6f * size) - r.org);
        rays.push_back(r);
    }
    for (int width : {2, 4, 8})
        for (NodeFormat f : {NodeFormat::Full, NodeFormat::Compressed}) {
            BvhBuildOptions o;
            o.width = width;
            o.node_format = f;
            const Bvh full = build_bvh(s, o);
            TraceCounters full_work, narrow_work;
            std::vector<Hit> expect;
            for (const Ray& r : rays)
                expect.push_back(trace_ray(full, r, HitQuery::Closest, nullptr, &full_work));
            for (int bits : {10, 4}) {
                uint32_t translated_tri_tests = 0;
                for (bool translate : {true, false}) {
                    o.box_mantissa_bits = bits;
                    o.box_translate_origin = translate;
                    const Bvh narrow = build_bvh(s, o);
                    narrow_work = TraceCounters();
                    int hits = 0;
                    for (size_t i = 0; i < rays.size(); ++i) {
                        const Hit h =
                            trace_ray(narrow, rays[i], HitQuery::Closest, nullptr, &narrow_work);
                        ASSERT_EQ(h.t, expect[i].t)
                            << "ray " << i << " width " << width << " bits " << bits;
                        ASSERT_EQ(h.prim, expect[i].prim);
                        hits += h.valid();
                    }
                    EXPECT_GT(hits, 500);
                    EXPECT_GE(narrow_work.box_tests, full_work.box_tests);
                    EXPECT_GE(narrow_work.tri_tests, full_work.tri_tests);
                    if (bits == 4) {
                        EXPECT_GT(narrow_work.tri_tests, full_work.tri_tests);
                    }
                    // Short distances from the node's entry point round to much less slack than
                    // long ones from the origin (measured: +0.1% against +12% at 10 bits).
                    if (translate)
                        translated_tri_tests = narrow_work.tri_tests;
                    else
                        EXPECT_LT(translated_tri_tests, narrow_work.tri_tests);
                }
            }
        }
}

TEST(ReducedBox, MantissaWidthOutsideTheDatapathsRangeIsRefused) {
    BvhBuildOptions o;
    for (int bits : {1, 24}) {
        o.box_mantissa_bits = bits;
        try {
            build_bvh(make_builtin_scene("sphere"), o);
            FAIL() << "accepted " << bits;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("box_unit.mantissa_bits"), std::string::npos);
        }
    }
}

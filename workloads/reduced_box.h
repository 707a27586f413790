// Ray-box tests of a reduced-precision datapath with conservative (outward) rounding, as an
// architecture option (box_unit.mantissa_bits). Reduced-precision box units are smaller and
// cheaper (a multiplier's area grows with the square of its mantissa width); the price is extra
// work, because rounded boxes are hit by rays that miss the exact ones. Rounding outwards
// means no ray ever misses a box it overlaps, so hits are never lost (Vaidyanathan,
// Akenine-Moeller & Salvi, HPG 2016; Koskela et al. 2015 measure the extra work).
//
// The modelled datapath, per slab plane: a subtractor takes the plane and the ray origin and
// rounds the difference to `bits` mantissa bits; the ray's reciprocal direction is held in
// `bits`; the multiplier rounds its product to `bits`. Every rounding is directed: down for an
// entry distance, up for an exit distance (interval arithmetic, so the direction is right
// whatever the operands' signs).
//
// Errors scale with the distances the datapath sees. With translate_origin (box_unit.
// translate_origin, Vaidyanathan et al.'s key step), the origin is first moved, in full
// precision and once per node for all its children, to the point where the ray enters the node:
// the reduced part then computes only the short distance from there to each child plane, and a
// full-precision adder puts the entry distance back. Without it, distances run from the ray's
// own origin, so a box far from the camera is inflated by about 2^-bits of its distance.
// The exponent range is double's: fp16's narrow exponent is not modelled. With bits = 23
// (fp32) the tracer uses the round-to-nearest test of intersect.h instead.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "workloads/bvh.h"
#include "workloads/geometry.h"
#include "workloads/intersect.h"

namespace rtsim {

constexpr int kFullMantissaBits = 23;  // fp32: the default box datapath
constexpr int kMinMantissaBits = 2;

namespace reduced {

// x rounded to a float of `bits` explicit mantissa bits (bits <= 52), towards -inf (up = false)
// or +inf (up = true). Zeros, infinities and NaN are returned as they are.
inline double round_bits(double x, int bits, bool up) {
    if (x == 0.0 || !std::isfinite(x)) return x;
    uint64_t u;
    std::memcpy(&u, &x, sizeof u);
    const uint64_t ulp = uint64_t(1) << (52 - bits);
    if ((u & (ulp - 1)) == 0) return x;  // already representable
    u &= ~(ulp - 1);                     // towards zero
    const bool negative = x < 0.0;
    if (up != negative) u += ulp;  // away from zero; a carry moves into the exponent correctly
    double r;
    std::memcpy(&r, &u, sizeof r);
    return r;
}
inline double round_down(double x, int bits) {
    return round_bits(x, bits, false);
}
inline double round_up(double x, int bits) {
    return round_bits(x, bits, true);
}

struct Interval {
    double lo, hi;
};

// a - b for fp32 inputs, rounded outwards to `bits`. The double difference can itself be
// inexact (operands far apart in magnitude); TwoSum's error term says on which side.
inline Interval sub(float a, float b, int bits) {
    const double x = a, y = -double(b);
    const double s = x + y;
    const double yy = s - x;
    const double err = (x - (s - yy)) + (y - yy);
    const double inf = std::numeric_limits<double>::infinity();
    const double lo = err < 0.0 ? std::nextafter(s, -inf) : s;
    const double hi = err > 0.0 ? std::nextafter(s, inf) : s;
    return {round_down(lo, bits), round_up(hi, bits)};
}

// plane - (org + t_ref * dir): the distance along one axis from the translated origin, with the
// error of the double evaluation bounded (a few roundings of 2^-53 relative to the operands),
// rounded outwards to `bits`.
inline Interval sub_translated(float plane, float org, double t_ref, float dir, int bits) {
    const double a = double(plane) - double(org);
    const double p = t_ref * double(dir);
    const double v = a - p;
    const double err = (std::fabs(a) + std::fabs(p)) * 0x1p-51;  // 4 * 2^-53, generous
    return {round_down(v - err, bits), round_up(v + err, bits)};
}

// 1 / d for a nonzero fp32 d, rounded outwards to `bits`; the residual of the double quotient
// (exact by fma) says on which side the true value lies.
inline Interval reciprocal(float d, int bits) {
    const double r = 1.0 / double(d);
    const double residual = std::fma(r, double(d), -1.0);  // r*d - 1, exact
    const double inf = std::numeric_limits<double>::infinity();
    // r is above 1/d when r*d - 1 has the sign of d.
    const bool above = residual != 0.0 && ((residual > 0.0) == (d > 0.0f));
    const bool below = residual != 0.0 && !above;
    const double lo = above ? std::nextafter(r, -inf) : r;
    const double hi = below ? std::nextafter(r, inf) : r;
    return {round_down(lo, bits), round_up(hi, bits)};
}

// a * b rounded outwards to `bits`. Operands of at most 24 significant bits multiply exactly in
// double, so only the final rounding widens the interval.
inline Interval mul(const Interval& a, const Interval& b, int bits) {
    const double p0 = a.lo * b.lo, p1 = a.lo * b.hi, p2 = a.hi * b.lo, p3 = a.hi * b.hi;
    return {round_down(std::min(std::min(p0, p1), std::min(p2, p3)), bits),
            round_up(std::max(std::max(p0, p1), std::max(p2, p3)), bits)};
}

// The largest float not above x: entry distances leave the datapath rounded down.
inline float float_down(double x) {
    float f = float(x);
    if (double(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
    return f;
}

// The full-precision adder that puts the entry distance back: t_ref + local, rounded outwards
// to fp32's mantissa (the double sum itself may round, so it is first widened by an ulp).
inline Interval add_full(double t_ref, const Interval& local) {
    const double inf = std::numeric_limits<double>::infinity();
    return {round_down(std::nextafter(t_ref + local.lo, -inf), 23),
            round_up(std::nextafter(t_ref + local.hi, inf), 23)};
}

}  // namespace reduced

// Per-ray constants of the reduced datapath: the reciprocal direction as an interval, and
// which axes the ray does not move along.
struct ReducedBoxRay {
    Vec3 org, dir;
    reduced::Interval inv[3];
    bool flat[3];      // direction component zero: the ray stays in one plane of this axis
    bool negative[3];  // which plane is near, from the direction's sign
    int bits;
    bool translate;  // distances from the node's entry point (t_ref) rather than the origin
    ReducedBoxRay(const RayPrecomp& r, int mantissa_bits, bool translate_origin)
        : org(r.org), dir(r.dir), bits(mantissa_bits), translate(translate_origin) {
        for (int a = 0; a < 3; ++a) {
            flat[a] = r.dir[a] == 0.0f;
            negative[a] = std::signbit(r.inv_dir[a]);
            inv[a] = flat[a] ? reduced::Interval{0.0, 0.0} : reduced::reciprocal(r.dir[a], bits);
        }
    }
};

// The reduced-precision counterpart of intersect_box: true if the ray overlaps the box within
// [tmin, tmax] as the rounded datapath sees it, which includes every box it really overlaps.
// tnear gets the entry distance, rounded down (it orders and culls children: never too late).
// t_ref: where the origin is translated to (the parent node's entry distance) when r.translate;
// any value is correct, a nearer one is tighter.
inline bool intersect_box_reduced(const ReducedBoxRay& r, const AABB& b, float tmin, float tmax,
                                  float& tnear, float t_ref = 0.0f) {
    double tn = tmin, tf = tmax;
    for (int a = 0; a < 3; ++a) {
        if (r.flat[a]) {
            // A ray along a slab's planes overlaps the closed slab iff its origin is in it (the
            // same answer as the fp32 test's ignored NaN and infinite distances).
            if (r.org[a] < b.lo[a] || r.org[a] > b.hi[a]) return false;
            continue;
        }
        const float near_plane = r.negative[a] ? b.hi[a] : b.lo[a];
        const float far_plane = r.negative[a] ? b.lo[a] : b.hi[a];
        reduced::Interval t0, t1;
        if (r.translate) {
            t0 = reduced::add_full(
                t_ref,
                reduced::mul(reduced::sub_translated(near_plane, r.org[a], t_ref, r.dir[a], r.bits),
                             r.inv[a], r.bits));
            t1 = reduced::add_full(
                t_ref,
                reduced::mul(reduced::sub_translated(far_plane, r.org[a], t_ref, r.dir[a], r.bits),
                             r.inv[a], r.bits));
        } else {
            t0 = reduced::mul(reduced::sub(near_plane, r.org[a], r.bits), r.inv[a], r.bits);
            t1 = reduced::mul(reduced::sub(far_plane, r.org[a], r.bits), r.inv[a], r.bits);
        }
        tn = std::max(tn, t0.lo);
        tf = std::min(tf, t1.hi);
        if (tn > tf) return false;
    }
    tnear = reduced::float_down(tn);
    return true;
}

// The box test a traversal uses: fp32 (intersect.h) or the reduced datapath of `o`.
inline bool intersect_box_bits(const RayPrecomp& rp, const AABB& b, float tmin, float tmax,
                               float& tnear, const BvhBuildOptions& o, float t_ref) {
    if (o.box_mantissa_bits >= kFullMantissaBits) return intersect_box(rp, b, tmin, tmax, tnear);
    return intersect_box_reduced(ReducedBoxRay(rp, o.box_mantissa_bits, o.box_translate_origin), b,
                                 tmin, tmax, tnear, t_ref);
}

}  // namespace rtsim

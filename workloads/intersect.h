// Robust ray-box (Ize 2013) and watertight ray-triangle (Woop, Benthin, Wald 2013) tests.
#pragma once

#include <cmath>
#include <utility>

#include "workloads/geometry.h"

namespace rtsim {

// Per-ray constants shared by all box and triangle tests of one traversal.
struct RayPrecomp {
    Vec3 org, dir, inv_dir;
    int kx, ky, kz;    // watertight test: kz is the dominant direction axis
    int perm;          // 2 * kz + (kx and ky swapped): selects the specialised test
    float sx, sy, sz;  // shear constants
    explicit RayPrecomp(const Ray& r) : org(r.org), dir(r.dir) {
        // The exact reciprocal: a zero component gives an infinity of its sign, a tiny one a
        // huge value (a clamp, as Embree's rcp_safe, moved far hits: a 1e-30 component read as
        // 1e-18). An origin lying in a slab plane along such an axis then gives 0 * inf = NaN
        // for that plane's distance, which the box tests ignore (their min and max keep the
        // other operand): the ray runs inside the closed slab. Which plane is near comes from
        // the reciprocal's sign bit, so +0 and -0 behave the same.
        for (int a = 0; a < 3; ++a) inv_dir[a] = 1.0f / r.dir[a];
        kz = max_axis(vabs(r.dir));
        kx = (kz + 1) % 3;
        ky = (kx + 1) % 3;
        const bool swapped = r.dir[kz] < 0.0f;
        if (swapped) std::swap(kx, ky);  // keep winding, so the sign test stays valid
        perm = 2 * kz + (swapped ? 1 : 0);
        sx = r.dir[kx] / r.dir[kz];
        sy = r.dir[ky] / r.dir[kz];
        sz = 1.0f / r.dir[kz];
    }
};

// Ize 2013: scaling the far slab distance by 1 + 2*gamma(3) makes the float test conservative.
constexpr float kSlabFarScale =
    1.0f + 2.0f * (3.0f * 0.5f * 1.1920929e-7f) / (1.0f - 3.0f * 0.5f * 1.1920929e-7f);

// A box's entry distance and a triangle's hit distance on the box's face are two roundings of
// one number and may differ by a few ulps. Culling boxes strictly beyond the current hit could
// then drop a triangle that is nearer than the one found: traversals keep boxes within this margin.
constexpr float kCullScale = 1.0f + 1.0f / 65536.0f;

// A ray traversal can follow: finite origin and direction. A non-finite one (from a scene so
// large its camera overflowed) would make every slab distance NaN, which the box tests ignore
// rather than treat as a miss; traversals reject such a ray at the root instead (one check per
// ray, not per box).
inline bool finite_ray(const Ray& r) {
    return std::isfinite(r.org.x) && std::isfinite(r.org.y) && std::isfinite(r.org.z) &&
           std::isfinite(r.dir.x) && std::isfinite(r.dir.y) && std::isfinite(r.dir.z);
}

// Returns true if the ray overlaps box within [tmin, tmax]; tnear gets the entry distance.
// Boxes are closed: a ray grazing a face or running inside a face's plane overlaps it, whatever
// the sign of its zero direction component. A NaN slab distance (an origin in a plane the ray
// runs along) fails both compares, so it leaves the interval as it was.
inline bool intersect_box(const RayPrecomp& r, const AABB& b, float tmin, float tmax,
                          float& tnear) {
    for (int a = 0; a < 3; ++a) {
        const bool negative = std::signbit(r.inv_dir[a]);
        const float t0 = ((negative ? b.hi[a] : b.lo[a]) - r.org[a]) * r.inv_dir[a];
        const float t1 = ((negative ? b.lo[a] : b.hi[a]) - r.org[a]) * r.inv_dir[a] * kSlabFarScale;
        tmin = t0 > tmin ? t0 : tmin;
        tmax = t1 < tmax ? t1 : tmax;
        if (tmin > tmax) return false;
    }
    tnear = tmin;
    return true;
}

// Watertight test with the axis permutation as template arguments, so that every component
// access is a fixed field rather than a run-time index.
template <int KX, int KY, int KZ>
inline bool intersect_triangle_perm(const RayPrecomp& r, const Vec3& v0, const Vec3& v1,
                                    const Vec3& v2, float tmin, Hit& hit) {
    const Vec3 A = v0 - r.org, B = v1 - r.org, C = v2 - r.org;
    const float ax = A[KX] - r.sx * A[KZ], ay = A[KY] - r.sy * A[KZ];
    const float bx = B[KX] - r.sx * B[KZ], by = B[KY] - r.sy * B[KZ];
    const float cx = C[KX] - r.sx * C[KZ], cy = C[KY] - r.sy * C[KZ];
    float U = cx * by - cy * bx;
    float V = ax * cy - ay * cx;
    float W = bx * ay - by * ax;
    if (U == 0.0f || V == 0.0f || W == 0.0f) {
        // On an edge in float: decide in double so that neighbours agree.
        U = float(double(cx) * by - double(cy) * bx);
        V = float(double(ax) * cy - double(ay) * cx);
        W = float(double(bx) * ay - double(by) * ax);
    }
    if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f)) return false;
    const float det = U + V + W;
    if (det == 0.0f) return false;
    const float T = U * (r.sz * A[KZ]) + V * (r.sz * B[KZ]) + W * (r.sz * C[KZ]);
    // Decide on the divided t alone: a pre-division test in scaled space rounds differently and
    // would make the nearer of two almost-equal hits depend on the order they are tested in.
    const float inv = 1.0f / det;
    const float t = T * inv;
    if (!(t >= tmin && t < hit.t)) return false;
    hit.t = t;
    hit.u = V * inv;
    hit.v = W * inv;
    return true;
}

// Watertight test. On a hit with t in [tmin, hit.t) updates hit (t, u, v; u and v weight
// vertices 1 and 2, as in Embree) and returns true. Edges shared by two triangles are never
// both missed: a ray through an edge or vertex hits at least one of its triangles.
inline bool intersect_triangle(const RayPrecomp& r, const Vec3& v0, const Vec3& v1, const Vec3& v2,
                               float tmin, Hit& hit) {
    switch (r.perm) {  // the same branch for every triangle of a ray: predicted
        case 0:
            return intersect_triangle_perm<1, 2, 0>(r, v0, v1, v2, tmin, hit);
        case 1:
            return intersect_triangle_perm<2, 1, 0>(r, v0, v1, v2, tmin, hit);
        case 2:
            return intersect_triangle_perm<2, 0, 1>(r, v0, v1, v2, tmin, hit);
        case 3:
            return intersect_triangle_perm<0, 2, 1>(r, v0, v1, v2, tmin, hit);
        case 4:
            return intersect_triangle_perm<0, 1, 2>(r, v0, v1, v2, tmin, hit);
        default:
            return intersect_triangle_perm<1, 0, 2>(r, v0, v1, v2, tmin, hit);
    }
}

}  // namespace rtsim

// Basic geometry: vectors, boxes, rays and hits shared by the functional side.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace rtsim {

struct Vec3 {
    float x = 0, y = 0, z = 0;
    Vec3() = default;
    constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
    float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

inline Vec3 operator+(Vec3 a, Vec3 b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline Vec3 operator-(Vec3 a, Vec3 b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline Vec3 operator-(Vec3 a) {
    return {-a.x, -a.y, -a.z};
}
inline Vec3 operator*(Vec3 a, float s) {
    return {a.x * s, a.y * s, a.z * s};
}
inline Vec3 operator*(float s, Vec3 a) {
    return a * s;
}
inline Vec3 operator/(Vec3 a, float s) {
    return a * (1.0f / s);
}
inline float dot(Vec3 a, Vec3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline Vec3 cross(Vec3 a, Vec3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(Vec3 a) {
    return std::sqrt(dot(a, a));
}
inline Vec3 normalize(Vec3 a) {
    return a / length(a);
}
inline Vec3 vmin(Vec3 a, Vec3 b) {
    return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
inline Vec3 vmax(Vec3 a, Vec3 b) {
    return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
inline Vec3 vabs(Vec3 a) {
    return {std::fabs(a.x), std::fabs(a.y), std::fabs(a.z)};
}
inline float max_component(Vec3 a) {
    return std::max(a.x, std::max(a.y, a.z));
}
inline int max_axis(Vec3 a) {
    return a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
}

struct AABB {
    Vec3 lo{std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
            std::numeric_limits<float>::infinity()};
    Vec3 hi{-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
            -std::numeric_limits<float>::infinity()};

    bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
    // The largest coordinate magnitude of the box's corners.
    float largest_coordinate() const { return max_component(vmax(vabs(lo), vabs(hi))); }
    void grow(Vec3 p) {
        lo = vmin(lo, p);
        hi = vmax(hi, p);
    }
    void grow(const AABB& b) {
        lo = vmin(lo, b.lo);
        hi = vmax(hi, b.hi);
    }
    Vec3 extent() const { return hi - lo; }
    Vec3 center() const { return (lo + hi) * 0.5f; }
    float surface_area() const {
        if (empty()) return 0.0f;
        Vec3 e = extent();
        return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
    }
    bool contains(const AABB& b) const {
        return b.lo.x >= lo.x && b.lo.y >= lo.y && b.lo.z >= lo.z && b.hi.x <= hi.x &&
               b.hi.y <= hi.y && b.hi.z <= hi.z;
    }
};

struct Ray {
    Vec3 org;
    float tmin = 0.0f;
    Vec3 dir;
    float tmax = std::numeric_limits<float>::infinity();
};

constexpr uint32_t kInvalidPrim = 0xFFFFFFFFu;

struct Hit {
    float t = std::numeric_limits<float>::infinity();
    float u = 0.0f, v = 0.0f;
    uint32_t prim = kInvalidPrim;
    uint32_t instance = kInvalidPrim;  // the instance hit in a two-level scene (else none)
    bool valid() const { return prim != kInvalidPrim; }
};

}  // namespace rtsim

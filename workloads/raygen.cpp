#include "workloads/raygen.h"

#include <fmt/format.h>
#include <cmath>
#include <cstring>
#include <sstream>

#include "workloads/error.h"

namespace rtsim {

const char* ray_kind_name(RayKind k) {
    switch (k) {
        case RayKind::Primary:
            return "primary";
        case RayKind::Shadow:
            return "shadow";
        case RayKind::AO:
            return "ao";
    }
    return "unknown";
}

std::array<bool, kRayKindCount> parse_ray_kinds(const std::string& list, const std::string& what) {
    std::array<bool, kRayKindCount> kinds{};
    std::stringstream ss(list);
    std::string item;
    bool any = false;
    while (std::getline(ss, item, ',')) {
        bool found = false;
        for (int k = 0; k < kRayKindCount; ++k)
            if (item == ray_kind_name(RayKind(k))) {
                kinds[k] = true;
                found = any = true;
            }
        if (!found)
            throw InputError(
                fmt::format("{}: unknown ray kind '{}' (expected a comma list of "
                            "primary, shadow, ao)",
                            what, item));
    }
    if (!any) throw InputError(fmt::format("{}: no ray kind given", what));
    return kinds;
}

std::string ray_kinds_to_string(const std::array<bool, kRayKindCount>& kinds) {
    std::string s;
    for (int k = 0; k < kRayKindCount; ++k)
        if (kinds[k]) s += (s.empty() ? "" : ",") + std::string(ray_kind_name(RayKind(k)));
    return s;
}

Camera Camera::frame(const AABB& bounds, int width, int height) {
    Camera c;
    c.aspect = float(width) / float(height);
    const Vec3 center = bounds.center();
    const float radius = std::max(0.5f * length(bounds.extent()), 1e-6f);
    c.forward = normalize(Vec3(0.0f, -0.25f, -1.0f));
    const float half_fov = std::atan(c.tan_half_fov_y * std::min(1.0f, c.aspect));
    const float dist = radius / std::sin(half_fov);
    c.eye = center - c.forward * dist;
    c.right = normalize(cross(c.forward, Vec3(0, 1, 0)));
    c.up = cross(c.right, c.forward);
    return c;
}

Ray Camera::generate(float px, float py, int width, int height) const {
    const float sx = (2.0f * px / width - 1.0f) * tan_half_fov_y * aspect;
    const float sy = (1.0f - 2.0f * py / height) * tan_half_fov_y;
    Ray r;
    r.org = eye;
    r.dir = normalize(forward + right * sx + up * sy);
    return r;
}

Vec3 offset_ray_origin(Vec3 p, Vec3 n) {
    constexpr float kOrigin = 1.0f / 32.0f, kFloatScale = 1.0f / 65536.0f, kIntScale = 256.0f;
    Vec3 out;
    for (int a = 0; a < 3; ++a) {
        const auto of = static_cast<int32_t>(kIntScale * n[a]);
        int32_t bits;
        std::memcpy(&bits, &p[a], 4);
        bits += p[a] < 0 ? -of : of;  // step whole ulps away from the surface
        float moved;
        std::memcpy(&moved, &bits, 4);
        out[a] = std::fabs(p[a]) < kOrigin ? p[a] + kFloatScale * n[a] : moved;
    }
    return out;
}

namespace {

// Counter-based random numbers: the same (seed, ray, sample) always gives the same value,
// whatever order or thread generates it.
uint64_t splitmix64(uint64_t x) {
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}
float uniform01(uint64_t h) {
    return float(h >> 40) * (1.0f / 16777216.0f);
}

void orthonormal_basis(Vec3 n, Vec3& t, Vec3& b) {
    // Duff et al. 2017, branchless basis from one vector.
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float c = n.x * n.y * a;
    t = Vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    b = Vec3(c, sign + n.y * n.y * a, -n.y);
}

}  // namespace

RayGenerator::RayGenerator(const Scene& scene, const Bvh& bvh, const RayGenOptions& options)
    : scene_(scene), bvh_(bvh), opt_(options) {
    if (opt_.width <= 0 || opt_.height <= 0)
        throw InputError(
            fmt::format("--res: resolution must be positive, got {}x{}", opt_.width, opt_.height));
    const AABB b = bvh.bounds();
    camera_ = Camera::frame(b, opt_.width, opt_.height);
    // A point light just under the top centre of the scene's bounds (inside a closed room).
    const Vec3 c = b.center(), e = b.extent();
    light_ = Vec3(c.x, b.hi.y - 0.05f * e.y, c.z);
    ao_length_ = opt_.ao_length_fraction * length(e);
    tiles_x_ = (opt_.width + opt_.tile_size - 1) / opt_.tile_size;
    tiles_y_ = (opt_.height + opt_.tile_size - 1) / opt_.tile_size;
}

bool RayGenerator::next_tile(std::vector<GeneratedRay>& out) {
    if (next_tile_ >= tiles_x_ * tiles_y_) return false;
    const int tx = next_tile_ % tiles_x_, ty = next_tile_ / tiles_x_;
    ++next_tile_;
    const int x0 = tx * opt_.tile_size, y0 = ty * opt_.tile_size;
    const int x1 = std::min(x0 + opt_.tile_size, opt_.width);
    const int y1 = std::min(y0 + opt_.tile_size, opt_.height);
    const bool need_hits = opt_.wants(RayKind::Shadow) || opt_.wants(RayKind::AO);

    struct SurfacePoint {
        Vec3 p, n;  // n faces the camera
        uint64_t pixel;
    };
    std::vector<SurfacePoint> hits;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
            const Ray r = camera_.generate(x + 0.5f, y + 0.5f, opt_.width, opt_.height);
            if (opt_.wants(RayKind::Primary))
                out.push_back({r, next_id_++, RayKind::Primary, HitQuery::Closest});
            if (!need_hits) continue;
            const Hit h = trace_ray(scene_, bvh_, r, HitQuery::Closest);
            if (!h.valid()) continue;
            const Vec3 v0 = scene_.v(h.prim, 0), v1 = scene_.v(h.prim, 1), v2 = scene_.v(h.prim, 2);
            Vec3 ng = cross(v1 - v0, v2 - v0);
            const float len = length(ng);
            if (!(len > 0.0f)) continue;  // degenerate triangle: no defined surface
            ng = ng / len;
            if (dot(ng, r.dir) > 0.0f) ng = -ng;
            const Vec3 p = v0 * (1.0f - h.u - h.v) + v1 * h.u + v2 * h.v;
            hits.push_back({offset_ray_origin(p, ng), ng, uint64_t(y) * opt_.width + x});
        }
    if (opt_.wants(RayKind::Shadow))
        for (const SurfacePoint& s : hits) {
            Vec3 to_light = light_ - s.p;
            const float dist = length(to_light);
            if (!(dist > 0.0f) || dot(to_light, s.n) <= 0.0f) continue;  // light behind surface
            Ray r;
            r.org = s.p;
            r.dir = to_light / dist;
            r.tmax = dist * (1.0f - 1e-4f);
            out.push_back({r, next_id_++, RayKind::Shadow, HitQuery::Any});
        }
    if (opt_.wants(RayKind::AO))
        for (const SurfacePoint& s : hits) {
            Vec3 t, b;
            orthonormal_basis(s.n, t, b);
            for (int k = 0; k < opt_.ao_samples; ++k) {
                const uint64_t h = splitmix64(opt_.seed ^ splitmix64(s.pixel * 64 + uint64_t(k)));
                const float u1 = uniform01(h), u2 = uniform01(splitmix64(h));
                // Cosine-weighted hemisphere (Malley's method).
                const float r = std::sqrt(u1), phi = 6.2831853f * u2;
                const float lx = r * std::cos(phi), ly = r * std::sin(phi);
                const float lz = std::sqrt(std::max(0.0f, 1.0f - u1));
                Ray ray;
                ray.org = s.p;
                ray.dir = normalize(t * lx + b * ly + s.n * lz);
                ray.tmax = ao_length_;
                out.push_back({ray, next_id_++, RayKind::AO, HitQuery::Any});
            }
        }
    return true;
}

}  // namespace rtsim

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
        case RayKind::Diffuse:
            return "diffuse";
        case RayKind::Reflection:
            return "reflection";
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
            throw InputError(fmt::format(
                "{}: unknown ray kind '{}' (expected a comma list of primary, shadow, ao, diffuse, "
                "reflection)",
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

const char* light_kind_name(LightKind k) {
    return k == LightKind::Point ? "point" : "area";
}

LightKind parse_light_kind(const std::string& text, const std::string& what) {
    if (text == "point") return LightKind::Point;
    if (text == "area") return LightKind::Area;
    throw InputError(fmt::format("{}: unknown light '{}' (expected point or area)", what, text));
}

void RayGenOptions::validate() const {
    if (width <= 0 || height <= 0 || width > 65536 || height > 65536)
        throw InputError(
            fmt::format("--res: expected 1..65536 per side, got {}x{}", width, height));
    if (spp < 1 || spp > 4096)
        throw InputError(fmt::format("--spp: expected 1..4096, got {}", spp));
    if (ao_samples < 1 || ao_samples > 1024)
        throw InputError(fmt::format("--ao-samples: expected 1..1024, got {}", ao_samples));
    if (!(ao_length_fraction > 0.0f) || !std::isfinite(ao_length_fraction))
        throw InputError(
            fmt::format("--ao-length: expected a positive fraction of the scene diagonal, got {}",
                        ao_length_fraction));
    if (diffuse_depth < 1 || diffuse_depth > 64)
        throw InputError(fmt::format("--diffuse-depth: expected 1..64, got {}", diffuse_depth));
    if (tile_size < 1)
        throw InputError(fmt::format("tile size must be positive, got {}", tile_size));
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

Vec3 offset_ray_origin(Vec3 p, Vec3 n, float scene_scale) {
    const float kOrigin = scene_scale / 32.0f, kFloatScale = scene_scale / 65536.0f;
    constexpr float kIntScale = 256.0f;
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

// Counter-based random numbers: the same (seed, stream, purpose, index) always gives the same
// value, whatever order or thread generates it.
uint64_t splitmix64(uint64_t x) {
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

enum Purpose : uint64_t { kPixelJitter = 1, kAo = 2, kLight = 3, kDiffuse = 4 };

struct Rng2 {
    float u1, u2;
};
Rng2 random2(uint64_t seed, uint64_t stream, Purpose purpose, uint64_t index) {
    const uint64_t h =
        splitmix64(seed ^ splitmix64(stream ^ splitmix64((uint64_t(purpose) << 56) ^ index)));
    const uint64_t h2 = splitmix64(h);
    return {float(h >> 40) * (1.0f / 16777216.0f), float(h2 >> 40) * (1.0f / 16777216.0f)};
}

void orthonormal_basis(Vec3 n, Vec3& t, Vec3& b) {
    // Duff et al. 2017, branchless basis from one vector.
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float c = n.x * n.y * a;
    t = Vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    b = Vec3(c, sign + n.y * n.y * a, -n.y);
}

// Cosine-weighted direction about n (Malley's method).
Vec3 cosine_direction(Vec3 n, Rng2 r) {
    Vec3 t, b;
    orthonormal_basis(n, t, b);
    const float radius = std::sqrt(r.u1), phi = 6.2831853f * r.u2;
    const float lz = std::sqrt(std::max(0.0f, 1.0f - r.u1));
    return normalize(t * (radius * std::cos(phi)) + b * (radius * std::sin(phi)) + n * lz);
}

}  // namespace

void check_scene_range(const std::string& scene_name, const AABB& b) {
    const Vec3 e0 = b.extent();
    if (!std::isfinite(length(e0)))
        throw InputError(fmt::format(
            "{}: scene bounds ({:g}, {:g}, {:g}) to ({:g}, {:g}, {:g}) are too large for "
            "single-precision rays (their extent overflows a float); scale the scene down",
            scene_name, b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z));
    // Outside the range the stress suite checks, say so: too large a scene overflows the
    // triangle test's products (every ray misses), too small or too far from the origin a one
    // loses hit precision.
    const float magnitude = b.largest_coordinate();
    const float extent = std::max({e0.x, e0.y, e0.z});
    if (extent > kMaxSceneExtent)
        throw InputError(fmt::format(
            "{}: scene extent {:g} is above {:g}, where single-precision triangle tests overflow "
            "and rays miss; scale the scene down",
            scene_name, extent, kMaxSceneExtent));
    if (extent > 0 && extent < kMinSceneExtent)
        warn(
            fmt::format("{}: scene extent {:g} is below {:g}: hit distances may lose precision; "
                        "scale the scene up",
                        scene_name, extent, kMinSceneExtent));
    if (extent > 0 && magnitude > kMaxOffsetOverExtent * extent)
        warn(
            fmt::format("{}: coordinates reach {:g}, over {:g} times the scene's extent {:g}: "
                        "hits may be missed or off; move the scene nearer the origin",
                        scene_name, magnitude, kMaxOffsetOverExtent, extent));
}

RayGenerator::RayGenerator(const Scene& scene, const Bvh& bvh, const RayGenOptions& options)
    : scene_(&scene), bvh_(&bvh), opt_(options) {
    init(scene.name, bvh.bounds());
}

RayGenerator::RayGenerator(const InstancedScene& scene, const TwoLevelBvh& bvh,
                           const RayGenOptions& options)
    : instanced_(&scene), two_(&bvh), opt_(options) {
    init(scene.name, bvh.bounds());
}

void RayGenerator::init(const std::string& name, const AABB& b) {
    opt_.validate();
    camera_ = Camera::frame(b, opt_.width, opt_.height);
    check_scene_range(name, b);
    // A finite extent can still put the camera out of float range: refuse it the same way.
    if (!std::isfinite(camera_.eye.x) || !std::isfinite(camera_.eye.y) ||
        !std::isfinite(camera_.eye.z))
        throw InputError(fmt::format(
            "{}: scene bounds ({:g}, {:g}, {:g}) to ({:g}, {:g}, {:g}) are too large for "
            "single-precision rays (the camera overflows a float); scale the scene down",
            name, b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z));
    const float magnitude = b.largest_coordinate();
    scene_scale_ = magnitude > 0 ? magnitude : 1.0f;
    // Lights just under the top of the scene's bounds (inside a closed room): a point at the
    // centre, or a horizontal quad a quarter of the bounds' width and depth around it.
    const Vec3 c = b.center(), e = b.extent();
    const Vec3 top(c.x, b.hi.y - 0.05f * e.y, c.z);
    if (opt_.light == LightKind::Point) {
        light_ = top;
    } else {
        light_u_ = Vec3(0.25f * e.x, 0, 0);
        light_v_ = Vec3(0, 0, 0.25f * e.z);
        light_ = top - (light_u_ + light_v_) * 0.5f;
    }
    ao_length_ = opt_.ao_length_fraction * length(e);
    tiles_x_ = (opt_.width + opt_.tile_size - 1) / opt_.tile_size;
    tiles_y_ = (opt_.height + opt_.tile_size - 1) / opt_.tile_size;
}

bool RayGenerator::surface_point(const Ray& r, const Hit& h, uint64_t stream,
                                 SurfacePoint& out) const {
    Vec3 v0, v1, v2;
    if (instanced_) {  // the triangle in world space, through its instance's transform
        const Instance& inst = instanced_->instances[h.instance];
        const Scene& mesh = instanced_->meshes[inst.mesh];
        v0 = inst.object_to_world.point(mesh.v(h.prim, 0));
        v1 = inst.object_to_world.point(mesh.v(h.prim, 1));
        v2 = inst.object_to_world.point(mesh.v(h.prim, 2));
    } else {
        v0 = scene_->v(h.prim, 0);
        v1 = scene_->v(h.prim, 1);
        v2 = scene_->v(h.prim, 2);
    }
    Vec3 ng = cross(v1 - v0, v2 - v0);
    const float len = length(ng);
    if (!(len > 0.0f)) return false;  // degenerate triangle: no defined surface
    ng = ng / len;
    if (dot(ng, r.dir) > 0.0f) ng = -ng;
    const Vec3 p = v0 * (1.0f - h.u - h.v) + v1 * h.u + v2 * h.v;
    out = {offset_ray_origin(p, ng, scene_scale_), ng, r.dir, stream};
    return true;
}

uint32_t RayGenerator::generate_tile(int index, std::vector<GeneratedRay>& out) const {
    const size_t first = out.size();
    const int tx = index % tiles_x_, ty = index / tiles_x_;
    const int x0 = tx * opt_.tile_size, y0 = ty * opt_.tile_size;
    const int x1 = std::min(x0 + opt_.tile_size, opt_.width);
    const int y1 = std::min(y0 + opt_.tile_size, opt_.height);
    const bool need_hits = opt_.wants(RayKind::Shadow) || opt_.wants(RayKind::AO) ||
                           opt_.wants(RayKind::Diffuse) || opt_.wants(RayKind::Reflection);
    auto emit = [&](const Ray& r, RayKind kind, HitQuery q) {
        GeneratedRay& g = out.emplace_back();
        g.ray = r;
        g.id = uint32_t(out.size() - 1 - first);
        g.kind = kind;
        g.query = q;
    };
    // Traces a ray whose hit starts further rays; an emitted one keeps the trace when asked.
    auto trace_for_hit = [&](const Ray& r, bool emitted) {
        GeneratedRay* g = emitted && record_steps_ ? &out.back() : nullptr;
        const Hit h = two_ ? (g ? trace_ray_recorded(*two_, r, HitQuery::Closest, g->steps)
                                : trace_ray(*two_, r, HitQuery::Closest))
                           : (g ? trace_ray_recorded(*bvh_, r, HitQuery::Closest, g->steps)
                                : trace_ray(*bvh_, r, HitQuery::Closest));
        if (g) {
            g->traced = true;
            g->prim = h.prim;
        }
        return h;
    };

    std::vector<SurfacePoint> hits;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x)
            for (int s = 0; s < opt_.spp; ++s) {
                const uint64_t stream = (uint64_t(y) * opt_.width + x) * uint64_t(opt_.spp) + s;
                float jx = 0.5f, jy = 0.5f;
                if (opt_.spp > 1) {
                    const Rng2 j = random2(opt_.seed, stream, kPixelJitter, 0);
                    jx = j.u1;
                    jy = j.u2;
                }
                const Ray r = camera_.generate(x + jx, y + jy, opt_.width, opt_.height);
                if (opt_.wants(RayKind::Primary)) emit(r, RayKind::Primary, HitQuery::Closest);
                if (!need_hits) continue;
                const Hit h = trace_for_hit(r, opt_.wants(RayKind::Primary));
                SurfacePoint sp;
                if (h.valid() && surface_point(r, h, stream, sp)) hits.push_back(sp);
            }

    if (opt_.wants(RayKind::Shadow))
        for (const SurfacePoint& s : hits) {
            Vec3 target = light_;
            if (opt_.light == LightKind::Area) {
                const Rng2 u = random2(opt_.seed, s.stream, kLight, 0);
                target = light_ + light_u_ * u.u1 + light_v_ * u.u2;
            }
            const Vec3 to_light = target - s.p;
            const float dist = length(to_light);
            if (!(dist > 0.0f) || dot(to_light, s.n) <= 0.0f) continue;  // light behind surface
            Ray r;
            r.org = s.p;
            r.dir = to_light / dist;
            r.tmax = dist * (1.0f - 1e-4f);  // stop short of the light itself
            emit(r, RayKind::Shadow, HitQuery::Any);
        }
    if (opt_.wants(RayKind::AO))
        for (const SurfacePoint& s : hits)
            for (int k = 0; k < opt_.ao_samples; ++k) {
                Ray r;
                r.org = s.p;
                r.dir = cosine_direction(s.n, random2(opt_.seed, s.stream, kAo, k));
                r.tmax = ao_length_;
                emit(r, RayKind::AO, HitQuery::Any);
            }
    if (opt_.wants(RayKind::Reflection))
        for (const SurfacePoint& s : hits) {
            Ray r;
            r.org = s.p;
            r.dir = normalize(s.incoming - s.n * (2.0f * dot(s.incoming, s.n)));
            emit(r, RayKind::Reflection, HitQuery::Closest);
        }
    if (opt_.wants(RayKind::Diffuse)) {
        std::vector<SurfacePoint> current = hits, next;
        for (int depth = 0; depth < opt_.diffuse_depth && !current.empty(); ++depth) {
            next.clear();
            for (const SurfacePoint& s : current) {
                Ray r;
                r.org = s.p;
                r.dir = cosine_direction(s.n, random2(opt_.seed, s.stream, kDiffuse, depth));
                emit(r, RayKind::Diffuse, HitQuery::Closest);
                if (depth + 1 == opt_.diffuse_depth) continue;  // the last bounce needs no hit
                const Hit h = trace_for_hit(r, true);
                SurfacePoint sp;
                if (h.valid() && surface_point(r, h, s.stream, sp)) next.push_back(sp);
            }
            current.swap(next);
        }
    }
    return uint32_t(out.size() - first);
}

}  // namespace rtsim

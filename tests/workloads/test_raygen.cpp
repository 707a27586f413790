#include <gtest/gtest.h>

#include "workloads/error.h"
#include "workloads/raygen.h"
#include "workloads/tile_queue.h"

using namespace rtsim;

namespace {
std::vector<GeneratedRay> all_rays(const Scene& s, const Bvh& bvh, const RayGenOptions& o) {
    RayGenerator g(s, bvh, o);
    std::vector<GeneratedRay> out;
    TileQueue tiles(g, 1);
    while (tiles.next(out)) {
    }
    return out;
}
}  // namespace

TEST(RayGen, ParsesKinds) {
    auto k = parse_ray_kinds("primary,ao", "--rays");
    EXPECT_TRUE(k[0]);
    EXPECT_FALSE(k[1]);
    EXPECT_TRUE(k[2]);
    EXPECT_EQ(ray_kinds_to_string(k), "primary,ao");
    EXPECT_THROW(parse_ray_kinds("primary,bogus", "--rays"), InputError);
    EXPECT_EQ(ray_kinds_to_string(parse_ray_kinds("reflection,diffuse", "x")),
              "diffuse,reflection");
    EXPECT_THROW(parse_ray_kinds("", "--rays"), InputError);
}

TEST(RayGen, CameraFramesTheWholeScene) {
    Scene s = load_scene("builtin:cornell");
    const AABB b = s.bounds();
    for (auto [w, h] : {std::pair{64, 64}, std::pair{160, 90}, std::pair{90, 160}}) {
        Camera c = Camera::frame(b, w, h);
        for (int i = 0; i < 8; ++i) {
            const Vec3 p((i & 1) ? b.hi.x : b.lo.x, (i & 2) ? b.hi.y : b.lo.y,
                         (i & 4) ? b.hi.z : b.lo.z);
            const Vec3 d = p - c.eye;
            const float z = dot(d, c.forward);
            ASSERT_GT(z, 0.0f);
            EXPECT_LE(std::fabs(dot(d, c.right) / z), c.tan_half_fov_y * c.aspect * 1.0001f);
            EXPECT_LE(std::fabs(dot(d, c.up) / z), c.tan_half_fov_y * 1.0001f);
        }
    }
}

TEST(RayGen, EmitsOnePrimaryPerPixelAndSecondariesFromHits) {
    Scene s = load_scene("builtin:cornell");
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    RayGenOptions o;
    o.width = 37;  // not a multiple of the tile size
    o.height = 21;
    o.kinds = parse_ray_kinds("primary,shadow,ao", "test");
    o.ao_samples = 3;
    auto rays = all_rays(s, bvh, o);
    size_t prim = 0, shadow = 0, ao = 0, hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        EXPECT_EQ(rays[i].id, i);
        if (rays[i].kind == RayKind::Primary) {
            ++prim;
            hits += trace_ray(bvh, rays[i].ray, HitQuery::Closest).valid();
        }
        shadow += rays[i].kind == RayKind::Shadow;
        ao += rays[i].kind == RayKind::AO;
    }
    EXPECT_EQ(prim, 37u * 21u);
    EXPECT_EQ(ao, 3 * hits);
    EXPECT_GT(shadow, 0u);
    EXPECT_LE(shadow, hits);
}

TEST(RayGen, SecondaryOriginsDoNotSelfIntersect) {
    // A single large plane seen from above: no AO or shadow ray may hit it.
    Scene s;
    s.vertices = {{-10, 0, -10}, {10, 0, -10},  {10, 0, 10},  {-10, 0, 10},
                  {0, 5, 0},     {0.01f, 5, 0}, {0, 5, 0.01f}};
    s.triangles = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}};  // the tiny triangle lifts the bounds
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    RayGenOptions o;
    o.width = o.height = 48;
    o.kinds = parse_ray_kinds("ao", "test");
    o.ao_samples = 4;
    o.ao_length_fraction = 0.05f;
    int checked = 0;
    for (const GeneratedRay& r : all_rays(s, bvh, o)) {
        const Hit h = trace_ray(bvh, r.ray, HitQuery::Closest);
        EXPECT_FALSE(h.valid() && h.prim != 2)
            << "AO ray " << r.id << " re-hit the plane at t=" << h.t;
        ++checked;
    }
    EXPECT_GT(checked, 1000);
}

TEST(RayGen, SeedChangesAoDirectionsDeterministically) {
    Scene s = load_scene("builtin:sphere");
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    RayGenOptions o;
    o.width = o.height = 16;
    o.kinds = parse_ray_kinds("ao", "test");
    auto a = all_rays(s, bvh, o), b = all_rays(s, bvh, o);
    o.seed = 2;
    auto c = all_rays(s, bvh, o);
    ASSERT_EQ(a.size(), b.size());
    ASSERT_EQ(a.size(), c.size());
    int differ = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        EXPECT_EQ(a[i].ray.dir.x, b[i].ray.dir.x);
        differ += a[i].ray.dir.x != c[i].ray.dir.x;
    }
    EXPECT_GT(differ, int(a.size()) / 2);
}

TEST(RayGen, DiffusePathsReflectionsAndSamplesPerPixel) {
    Scene s = load_scene("builtin:cornell");
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    RayGenOptions o;
    o.width = 24;
    o.height = 16;
    o.spp = 3;
    o.diffuse_depth = 3;
    o.kinds = parse_ray_kinds("primary,diffuse,reflection", "test");
    auto rays = all_rays(s, bvh, o);
    size_t prim = 0, hits = 0, refl = 0, diffuse = 0;
    for (const auto& r : rays) {
        if (r.kind == RayKind::Primary) {
            ++prim;
            hits += trace_ray(bvh, r.ray, HitQuery::Closest).valid();
        }
        refl += r.kind == RayKind::Reflection;
        diffuse += r.kind == RayKind::Diffuse;
        if (r.kind == RayKind::Diffuse || r.kind == RayKind::Reflection) {
            EXPECT_EQ(r.query, HitQuery::Closest);
            EXPECT_NEAR(length(r.ray.dir), 1.0f, 1e-5f);
        }
    }
    EXPECT_EQ(prim, 24u * 16u * 3u);
    EXPECT_EQ(refl, hits);  // one mirror ray per primary hit
    // Bounce 1 leaves every primary hit; later bounces only from the hits of the one before.
    EXPECT_GE(diffuse, hits);
    EXPECT_LE(diffuse, 3 * hits);
    // Inside a closed room most bounces hit again, so paths mostly continue.
    EXPECT_GT(diffuse, 2 * hits);
}

TEST(RayGen, AreaLightSpreadsShadowRays) {
    Scene s = load_scene("builtin:cornell");
    Bvh bvh = build_bvh(s, BvhBuildOptions());
    RayGenOptions o;
    o.width = o.height = 16;
    o.kinds = parse_ray_kinds("shadow", "test");
    o.light = LightKind::Area;
    RayGenerator g(s, bvh, o);
    std::vector<GeneratedRay> rays;
    TileQueue tiles(g, 1);
    while (tiles.next(rays)) {
    }
    ASSERT_GT(rays.size(), 50u);
    float min_x = 1e30f, max_x = -1e30f;
    for (const auto& r : rays) {
        ASSERT_EQ(r.kind, RayKind::Shadow);
        const Vec3 end = r.ray.org + r.ray.dir * (r.ray.tmax / (1.0f - 1e-4f));
        // Every shadow ray ends on the light quad.
        EXPECT_NEAR(end.y, g.light_position().y, 1e-3f);
        min_x = std::min(min_x, end.x);
        max_x = std::max(max_x, end.x);
    }
    EXPECT_GT(max_x - min_x, 0.5f * g.light_edge_u().x);
}

TEST(RayGen, BadOptionsAreInputErrors) {
    RayGenOptions o;
    o.spp = 0;
    EXPECT_THROW(o.validate(), InputError);
    o = RayGenOptions();
    o.diffuse_depth = 0;
    EXPECT_THROW(o.validate(), InputError);
    o = RayGenOptions();
    o.ao_length_fraction = -1;
    EXPECT_THROW(o.validate(), InputError);
    EXPECT_THROW(parse_light_kind("sun", "--light"), InputError);
}

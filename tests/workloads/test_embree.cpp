// Embree (libembree-dev) is the oracle: our tracer must agree with it on the same rays.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "support/embree_scene.h"
#include "workloads/bvh.h"
#include "workloads/instances.h"
#include "workloads/intersect.h"
#include "workloads/raygen.h"
#include "workloads/scene.h"
#include "workloads/tile_queue.h"
#include "workloads/tracer.h"

using namespace rtsim;
using rtsim::test::EmbreeInstancedScene;
using rtsim::test::EmbreeScene;

namespace {

// Distance of the hit point to the triangle's nearest edge, in barycentric units.
float edge_distance(const Scene& s, uint32_t prim, const Ray& r) {
    Hit h;
    if (!intersect_triangle(RayPrecomp(r), s.v(prim, 0), s.v(prim, 1), s.v(prim, 2), r.tmin, h))
        return 0.0f;
    return std::min({h.u, h.v, 1.0f - h.u - h.v});
}

struct Agreement {
    size_t rays = 0, hits = 0, same_prim = 0, ties = 0, edge_cases = 0;
};

// Compares every ray of the workload. Allowed exceptions, each checked rather than assumed:
//  - a different primitive at the same t (within 1e-4 relative): an exact tie between
//    triangles sharing the hit point (an edge or vertex, or coincident faces);
//  - hit vs. miss, or a farther Embree hit, only where our hit lies within 1e-4 (barycentric) of
//    an edge: the crack between neighbours that Embree's non-watertight test can let a ray
//    through, and that the watertight test closes.
Agreement compare(const Scene& s, EmbreeScene& e, const BvhBuildOptions& bo,
                  const std::string& kinds, int res) {
    Bvh bvh = build_bvh(s, bo);
    RayGenOptions o;
    o.width = o.height = res;
    o.kinds = parse_ray_kinds(kinds, "test");
    RayGenerator gen(s, bvh, o);
    std::vector<GeneratedRay> rays;
    Agreement a;
    TileQueue tiles(gen, 1);
    while (tiles.next(rays)) {
        for (const GeneratedRay& g : rays) {
            ++a.rays;
            const Hit ours = trace_ray(bvh, g.ray, g.query);
            if (g.query == HitQuery::Any) {
                const bool theirs = e.occluded(g.ray);
                if (ours.valid() != theirs) {
                    const float d = ours.valid() ? edge_distance(s, ours.prim, g.ray) : 0.0f;
                    EXPECT_TRUE(ours.valid() && d < 1e-4f)
                        << "occlusion differs for " << ray_kind_name(g.kind) << " ray " << g.id;
                    ++a.edge_cases;
                }
                a.hits += ours.valid();
                continue;
            }
            const Hit theirs = e.intersect(g.ray);
            if (ours.valid() != theirs.valid()) {
                const Hit& h = ours.valid() ? ours : theirs;
                EXPECT_LT(edge_distance(s, h.prim, g.ray), 1e-4f)
                    << "hit/miss differs away from an edge, ray " << g.id << " ours " << ours.prim
                    << " embree " << theirs.prim;
                ++a.edge_cases;
                continue;
            }
            if (!ours.valid()) continue;
            ++a.hits;
            if (std::fabs(ours.t - theirs.t) > 1e-4f * std::max(1.0f, std::fabs(theirs.t))) {
                // Both hit, at different depths: only acceptable where our nearer hit is on an edge
                // that Embree's test let the ray slip through.
                EXPECT_TRUE(ours.t < theirs.t && edge_distance(s, ours.prim, g.ray) < 1e-4f)
                    << "ray " << g.id << ": ours t=" << ours.t << " prim " << ours.prim
                    << ", embree t=" << theirs.t << " prim " << theirs.prim;
                ++a.edge_cases;
                continue;
            }
            if (ours.prim == theirs.prim) {
                ++a.same_prim;
                EXPECT_NEAR(ours.u, theirs.u, 1e-3f);
                EXPECT_NEAR(ours.v, theirs.v, 1e-3f);
            } else {
                ++a.ties;
            }
        }
        rays.clear();
    }
    return a;
}

void report(const char* what, const Agreement& a) {
    std::printf("%s: %zu rays, %zu hits, %zu same primitive, %zu ties, %zu edge cases\n", what,
                a.rays, a.hits, a.same_prim, a.ties, a.edge_cases);
}

// Every builder at every width, every ray kind.
void compare_all_variants(const Scene& s, const std::string& label, const std::string& kinds,
                          int res, size_t min_hits) {
    EmbreeScene e(s);
    struct Build {
        BvhBuilder builder;
        int restructure_passes;
        NodeFormat format = NodeFormat::Full;
    };
    for (Build b : {Build{BvhBuilder::Sah, 0}, Build{BvhBuilder::Lbvh, 0},
                    Build{BvhBuilder::Lbvh, 2}, Build{BvhBuilder::Sah, 0, NodeFormat::Compressed}})
        for (int w : {2, 4, 8}) {
            BvhBuildOptions bo;
            bo.builder = b.builder;
            bo.restructure_passes = b.restructure_passes;
            bo.node_format = b.format;
            bo.width = w;
            const std::string what = label + " " + bvh_builder_name(b.builder) +
                                     (b.restructure_passes ? "+treelets" : "") + " BVH" +
                                     std::to_string(w) + " " + node_format_name(b.format);
            SCOPED_TRACE(what);
            const Agreement a = compare(s, e, bo, kinds, res);
            report(what.c_str(), a);
            EXPECT_GT(a.hits, min_hits);
            EXPECT_LE(a.ties + a.edge_cases, a.rays / 500);  // exceptions stay rare
        }
}

const char* kAllKinds = "primary,shadow,ao,diffuse,reflection";

}  // namespace

TEST(EmbreeOracle, Cornell) {
    compare_all_variants(load_scene("builtin:cornell"), "cornell", kAllKinds, 96, 5000);
}

TEST(EmbreeOracle, Bunny) {
    ASSERT_TRUE(std::filesystem::exists(RTSIM_BUNNY_OBJ)) << "run scripts/setup.sh";
    compare_all_variants(load_scene(RTSIM_BUNNY_OBJ), "bunny", kAllKinds, 128, 4000);
}

TEST(EmbreeOracle, CgalMeshes) {
    const std::filesystem::path dir = RTSIM_CGAL_MESH_DIR;
    ASSERT_TRUE(std::filesystem::is_directory(dir)) << "run scripts/setup.sh";
    for (const char* name : {"armadillo.off", "refined_elephant.off", "mech-holes-shark.off"})
        compare_all_variants(load_scene((dir / name).string()), name, kAllKinds, 64, 400);
}

namespace {

// Meshes placed at random over a 20-unit cube, overlapping: each one's own size first brought to
// about 2 units, then rotated (a uniform random rotation), scaled uniformly, non-uniformly or
// mirrored (one negative axis), and given a mask of one of eight bits.
// The meshes the instancing checks place: the bunny, the armadillo and the Cornell box (whose
// coincident faces make ties).
std::vector<Scene> instanced_meshes() {
    std::vector<Scene> meshes;
    meshes.push_back(load_scene(RTSIM_BUNNY_OBJ));
    meshes.push_back(load_scene(std::string(RTSIM_CGAL_MESH_DIR) + "/armadillo.off"));
    meshes.push_back(load_scene("builtin:cornell"));
    return meshes;
}

InstancedScene random_instances(std::vector<Scene> meshes, int count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    InstancedScene s;
    s.name = "random instances";
    s.meshes = std::move(meshes);
    for (int k = 0; k < count; ++k) {
        Instance inst;
        inst.mesh = uint32_t(k % int(s.meshes.size()));
        inst.mask = uint8_t(1u << (k % 8));
        const AABB b = s.meshes[inst.mesh].bounds();
        const Vec3 e = b.extent(), c = b.center();
        const float fit = 2.0f / std::max({e.x, e.y, e.z});
        Affine3x4 norm;
        norm.m = {fit, 0, 0, -fit * c.x, 0, fit, 0, -fit * c.y, 0, 0, fit, -fit * c.z};
        // A unit quaternion drawn uniformly (Shoemake), as a rotation matrix.
        const float u1 = u01(rng), u2 = 6.2831853f * u01(rng), u3 = 6.2831853f * u01(rng);
        const float qx = std::sqrt(1 - u1) * std::sin(u2), qy = std::sqrt(1 - u1) * std::cos(u2),
                    qz = std::sqrt(u1) * std::sin(u3), qw = std::sqrt(u1) * std::cos(u3);
        float sx = 0.5f + 1.5f * u01(rng), sy = sx, sz = sx;
        if (k % 3 == 1) {
            sy = 0.3f + 2.0f * u01(rng);
            sz = 0.3f + 2.0f * u01(rng);
        } else if (k % 3 == 2) {
            sy = -sy;  // mirrored: a negative determinant flips the winding
        }
        const float R[3][3] = {
            {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)},
            {2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)},
            {2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)}};
        const float S[3] = {sx, sy, sz};
        Affine3x4 place;
        for (int r = 0; r < 3; ++r) {
            for (int col = 0; col < 3; ++col) place.m[size_t(r * 4 + col)] = R[r][col] * S[col];
            place.m[size_t(r * 4 + 3)] = -10.0f + 20.0f * u01(rng);
        }
        inst.object_to_world = compose(place, norm);
        s.instances.push_back(inst);
    }
    return s;
}

// Distance of our hit to its triangle's nearest edge (barycentric), in the instance's object
// space as our traversal tested it.
float instanced_edge_distance(const InstancedScene& s, const TwoLevelBvh& two, uint32_t inst,
                              uint32_t prim, const Ray& r) {
    const Affine3x4& w2o = two.world_to_object[inst];
    Ray local = r;
    local.org = w2o.point(r.org);
    local.dir = w2o.vector(r.dir);
    return edge_distance(s.meshes[s.instances[inst].mesh], prim, local);
}

struct InstancedAgreement {
    size_t rays = 0, hits = 0, same = 0, ties = 0, edge_cases = 0;
};

// As compare() above, on rays aimed at random instances (and as many at random through the
// scene), closest-hit and any-hit, under the ray mask `mask`. A tie (another triangle, or
// instance, at the same t) is accepted only where our test of Embree's triangle confirms it.
InstancedAgreement compare_instanced(const InstancedScene& s, const EmbreeInstancedScene& e,
                                     const TwoLevelBvh& two, uint8_t mask, uint32_t seed,
                                     int ray_count) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    InstancedAgreement a;
    const AABB b = s.bounds();
    for (int i = 0; i < ray_count; ++i) {
        Ray r;
        r.org = b.center() + Vec3(u(rng), u(rng), u(rng)) * 20.0f;
        Vec3 target = b.center() + Vec3(u(rng), u(rng), u(rng)) * 10.0f;
        if (i % 2 == 0) {  // at an instance's box
            const Instance& inst = s.instances[size_t(rng() % s.instances.size())];
            const AABB ib = transform_box(inst.object_to_world, two.blas[inst.mesh].bounds());
            target = ib.center() + Vec3(u(rng), u(rng), u(rng)) * 0.4f * length(ib.extent());
        }
        r.dir = normalize(target - r.org);
        const bool any = i % 4 == 3;
        if (any) r.tmax = 30.0f * (0.1f + 0.9f * (u(rng) * 0.5f + 0.5f));
        ++a.rays;
        uint32_t ti;
        const Hit ours = trace_ray(two, r, any ? HitQuery::Any : HitQuery::Closest, mask);
        const uint32_t oi = ours.instance;
        if (any) {
            const bool theirs = e.occluded(r, mask);
            if (ours.valid() != theirs) {
                EXPECT_TRUE(ours.valid() &&
                            instanced_edge_distance(s, two, oi, ours.prim, r) < 1e-4f)
                    << "occlusion differs, ray " << i;
                ++a.edge_cases;
            }
            a.hits += ours.valid();
            continue;
        }
        const Hit theirs = e.intersect(r, ti, mask);
        if (ours.valid() != theirs.valid()) {
            const float d = ours.valid() ? instanced_edge_distance(s, two, oi, ours.prim, r)
                                         : instanced_edge_distance(s, two, ti, theirs.prim, r);
            EXPECT_LT(d, 1e-4f) << "hit/miss differs away from an edge, ray " << i;
            ++a.edge_cases;
            continue;
        }
        if (!ours.valid()) continue;
        ++a.hits;
        EXPECT_EQ(s.instances[oi].mask & mask, s.instances[oi].mask) << "a masked instance hit";
        if (std::fabs(ours.t - theirs.t) > 1e-4f * std::max(1.0f, std::fabs(theirs.t))) {
            EXPECT_TRUE(ours.t < theirs.t &&
                        instanced_edge_distance(s, two, oi, ours.prim, r) < 1e-4f)
                << "ray " << i << ": ours t=" << ours.t << " instance " << oi << " prim "
                << ours.prim << ", embree t=" << theirs.t << " instance " << ti << " prim "
                << theirs.prim;
            ++a.edge_cases;
            continue;
        }
        if (ours.prim == theirs.prim && oi == ti) {
            ++a.same;
            // Barycentrics agree to the rounding of the two transforms of the ray into object
            // space: a 2-unit instance of a mesh 0.15 units across puts the origin ~100 object
            // units from a 1e-3 triangle, where float rounding moves the point ~1e-2 of it.
            EXPECT_NEAR(ours.u, theirs.u, 2e-2f);
            EXPECT_NEAR(ours.v, theirs.v, 2e-2f);
        } else {
            // Another triangle at the same distance: a real tie only if our test of Embree's
            // triangle, in its instance's space, hits it at that distance too (coincident faces:
            // the Cornell box's blocks stand on its floor).
            const Affine3x4& w2o = two.world_to_object[ti];
            Ray local = r;
            local.org = w2o.point(r.org);
            local.dir = w2o.vector(r.dir);
            const Scene& m = s.meshes[s.instances[ti].mesh];
            Hit h;
            const bool hit =
                intersect_triangle(RayPrecomp(local), m.v(theirs.prim, 0), m.v(theirs.prim, 1),
                                   m.v(theirs.prim, 2), local.tmin, h);
            EXPECT_TRUE(hit && std::fabs(h.t - ours.t) <= 1e-4f * std::max(1.0f, ours.t))
                << "ray " << i << ": embree's instance " << ti << " prim " << theirs.prim
                << " is not hit at t=" << ours.t;
            ++a.ties;
        }
    }
    return a;
}

}  // namespace

TEST(EmbreeOracle, InstancesWithRotationsScalesAndMirrors) {
    ASSERT_TRUE(std::filesystem::is_directory(RTSIM_CGAL_MESH_DIR)) << "run scripts/setup.sh";
    const InstancedScene s = random_instances(instanced_meshes(), 60, 7);
    const EmbreeInstancedScene e(s);
    for (BvhBuilder builder : {BvhBuilder::Sah, BvhBuilder::Lbvh})
        for (NodeFormat format : {NodeFormat::Full, NodeFormat::Compressed})
            for (int w : {2, 4, 8}) {
                BvhBuildOptions bo;
                bo.builder = builder;
                bo.node_format = format;
                bo.width = w;
                const TwoLevelBvh two = build_two_level(s, bo);
                for (uint8_t mask : {uint8_t(0xff), uint8_t(0x0f)}) {
                    const std::string what = std::string(bvh_builder_name(builder)) + " BVH" +
                                             std::to_string(w) + " " + node_format_name(format) +
                                             " mask " + std::to_string(mask);
                    SCOPED_TRACE(what);
                    const InstancedAgreement a = compare_instanced(s, e, two, mask, 11, 6000);
                    std::printf("instances %s: %zu rays, %zu hits, %zu same, %zu ties, %zu edge\n",
                                what.c_str(), a.rays, a.hits, a.same, a.ties, a.edge_cases);
                    EXPECT_GT(a.hits, a.rays / 4);
                    EXPECT_LE(a.edge_cases, a.rays / 500);  // ties are checked one by one
                }
            }
}

// Non-opaque instances against Embree's intersection filter (its any-hit callback) on the same
// scene: per-triangle cut-outs on the bunny (60% of triangles solid) and the armadillo (30%),
// and the Cornell box non-opaque with no mask (every candidate accepted after the call). Half
// the instances of each mesh are opaque (the filter skipped, as our shader). The masks decide
// per triangle, so both sides must agree exactly outside geometric ties; the texture-space
// checker is checked against a brute-force model in test_alpha.cpp, as Embree's barycentrics
// differ from ours by up to ~1e-2 on these instances.
TEST(EmbreeOracle, NonOpaqueInstancesMatchAnIntersectionFilter) {
    ASSERT_TRUE(std::filesystem::is_directory(RTSIM_CGAL_MESH_DIR)) << "run scripts/setup.sh";
    InstancedScene s = random_instances(instanced_meshes(), 60, 23);
    AlphaMask bunny, armadillo;
    bunny.pattern = armadillo.pattern = AlphaPattern::Triangles;
    bunny.keep = 0.6;
    armadillo.keep = 0.3;
    armadillo.seed = 5;
    s.alpha = {bunny, armadillo, AlphaMask()};
    for (size_t k = 0; k < s.instances.size(); ++k) s.instances[k].opaque = (k / 3) % 2 == 1;
    const EmbreeInstancedScene e(s);
    for (NodeFormat format : {NodeFormat::Full, NodeFormat::Compressed})
        for (int w : {2, 4, 8}) {
            BvhBuildOptions bo;
            bo.node_format = format;
            bo.width = w;
            const TwoLevelBvh two = build_two_level(s, bo);
            const std::string what =
                "BVH" + std::to_string(w) + " " + std::string(node_format_name(format));
            SCOPED_TRACE(what);
            const InstancedAgreement a = compare_instanced(s, e, two, 0xff, 13, 6000);
            std::printf("non-opaque %s: %zu rays, %zu hits, %zu same, %zu ties, %zu edge\n",
                        what.c_str(), a.rays, a.hits, a.same, a.ties, a.edge_cases);
            EXPECT_GT(a.hits, a.rays / 4);
            EXPECT_LE(a.edge_cases, a.rays / 500);
        }
    // The masks matter: with every instance opaque, hits differ (on 94 of these 2,000 rays, most
    // of which miss every instance or hit an opaque one).
    InstancedScene solid = s;
    for (Instance& inst : solid.instances) inst.opaque = true;
    const TwoLevelBvh a = build_two_level(s, BvhBuildOptions());
    const TwoLevelBvh b = build_two_level(solid, BvhBuildOptions());
    std::mt19937 rng(13);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    int differ = 0;
    for (int i = 0; i < 2000; ++i) {
        Ray r;
        r.org = s.bounds().center() + Vec3(u(rng), u(rng), u(rng)) * 20.0f;
        r.dir = normalize(s.bounds().center() + Vec3(u(rng), u(rng), u(rng)) * 10.0f - r.org);
        const Hit x = trace_ray(a, r, HitQuery::Closest), y = trace_ray(b, r, HitQuery::Closest);
        differ += x.valid() != y.valid() || x.t != y.t;
    }
    EXPECT_GT(differ, 20);
}

// Real assets whose nodes share meshes (assimp-testmodels' milk truck and two-cylinder engine,
// kept as instances by the reader) against Embree's instancing API on the same instances.
TEST(EmbreeOracle, GltfAssetsKeptAsInstances) {
    const std::filesystem::path dir = RTSIM_ASSIMP_MODEL_DIR;
    ASSERT_TRUE(std::filesystem::exists(dir / "CesiumMilkTruck.gltf")) << "run scripts/setup.sh";
    for (const char* name : {"CesiumMilkTruck.gltf", "2CylinderEngine.glb"}) {
        SCOPED_TRACE(name);
        InstancedScene s;
        bool shared = false;
        load_scene((dir / name).string(), &s, &shared);
        ASSERT_TRUE(shared);
        const EmbreeInstancedScene e(s);
        for (int w : {2, 8}) {
            BvhBuildOptions bo;
            bo.width = w;
            const TwoLevelBvh two = build_two_level(s, bo);
            const InstancedAgreement a = compare_instanced(s, e, two, 0xff, 19, 4000);
            std::printf("%s BVH%d: %zu rays, %zu hits, %zu same, %zu ties, %zu edge\n", name, w,
                        a.rays, a.hits, a.same, a.ties, a.edge_cases);
            EXPECT_GT(a.hits, a.rays / 4);
            EXPECT_LE(a.edge_cases, a.rays / 500);
        }
    }
}

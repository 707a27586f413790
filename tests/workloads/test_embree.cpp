// Embree (libembree-dev) is the oracle: our tracer must agree with it on the same rays.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "support/embree_scene.h"
#include "workloads/bvh.h"
#include "workloads/intersect.h"
#include "workloads/raygen.h"
#include "workloads/scene.h"
#include "workloads/tile_queue.h"
#include "workloads/tracer.h"

using namespace rtsim;
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

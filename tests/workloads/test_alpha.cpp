// Any-hit geometry (workloads/alpha.h): the masks' decisions worked out by hand, and two-level
// traversal of non-opaque instances against a brute-force model that tests every triangle of
// every instance and keeps the nearest candidate its mask accepts.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "workloads/alpha.h"
#include "workloads/instances.h"
#include "workloads/intersect.h"
#include "workloads/scene.h"

using namespace rtsim;

TEST(Alpha, CheckerSquaresAlternateInBarycentricSpace) {
    AlphaMask m;
    m.pattern = AlphaPattern::Checker;
    m.cells = 4;                              // squares of 0.25
    EXPECT_TRUE(m.accepts(0, 0.1f, 0.1f));    // square (0, 0): solid
    EXPECT_FALSE(m.accepts(0, 0.3f, 0.1f));   // (1, 0): cut out
    EXPECT_TRUE(m.accepts(7, 0.1f, 0.6f));    // (0, 2)
    EXPECT_TRUE(m.accepts(7, 0.3f, 0.3f));    // (1, 1)
    EXPECT_FALSE(m.accepts(7, 0.6f, 0.3f));   // (2, 1)
    EXPECT_FALSE(m.accepts(7, 0.1f, 0.26f));  // (0, 1)
    EXPECT_TRUE(m.accepts(3, 0.25f, 0.25f));  // on a corner: square (1, 1)
    EXPECT_FALSE(m.accepts(3, 0.25f, 0.0f));  // on an edge: square (1, 0)
    m.cells = 1;                              // one square: the whole triangle solid
    EXPECT_TRUE(m.accepts(0, 0.9f, 0.05f));
}

TEST(Alpha, TrianglePatternKeepsItsFractionWhateverTheSeed) {
    AlphaMask m;
    m.pattern = AlphaPattern::Triangles;
    for (const double keep : {0.0, 0.25, 0.7, 1.0})
        for (const uint32_t seed : {1u, 99u}) {
            m.keep = keep;
            m.seed = seed;
            int kept = 0;
            const int n = 100000;
            for (int p = 0; p < n; ++p) kept += m.accepts(uint32_t(p), 0.3f, 0.3f);
            // Binomial: sd = sqrt(n k (1 - k)) <= 158; 5 sd.
            EXPECT_NEAR(kept, keep * n, 800) << "keep " << keep << " seed " << seed;
            // The decision is the triangle's, not the point's.
            EXPECT_EQ(m.accepts(12345, 0.1f, 0.1f), m.accepts(12345, 0.8f, 0.1f));
        }
    m.keep = 0.5;
    m.seed = 1;
    AlphaMask other = m;
    other.seed = 2;
    int differ = 0;
    for (uint32_t p = 0; p < 1000; ++p) differ += m.accepts(p, 0, 0) != other.accepts(p, 0, 0);
    EXPECT_GT(differ, 400);  // another seed cuts out other triangles
}

namespace {

struct BruteResult {
    float t = std::numeric_limits<float>::infinity();
    uint32_t prim = kInvalidPrim, instance = kNoInstance;
    // Candidates on non-opaque instances: all of them, and those nearer than the accepted hit.
    uint32_t candidates = 0, nearer_candidates = 0;
    std::vector<std::pair<uint32_t, uint32_t>> at_best;  // accepted (instance, prim) at t
};

// Every triangle of every instance the mask admits, in the world-to-object transform traversal
// uses; a hit on a non-opaque instance counts only if its mesh's mask accepts it.
BruteResult brute_force(const InstancedScene& s, const TwoLevelBvh& two, const Ray& r,
                        uint8_t ray_mask) {
    struct Candidate {
        float t;
        uint32_t inst, prim;
        bool accepted, shaded;
    };
    std::vector<Candidate> all;
    for (uint32_t k = 0; k < s.instances.size(); ++k) {
        const Instance& inst = s.instances[k];
        if (!(inst.mask & ray_mask)) continue;
        Ray local = r;
        local.org = two.world_to_object[k].point(r.org);
        local.dir = two.world_to_object[k].vector(r.dir);
        const RayPrecomp rp(local);
        const Scene& m = s.meshes[inst.mesh];
        for (uint32_t p = 0; p < m.triangles.size(); ++p) {
            Hit h;
            h.t = r.tmax;
            if (!intersect_triangle(rp, m.v(p, 0), m.v(p, 1), m.v(p, 2), r.tmin, h)) continue;
            const bool accepted = inst.opaque || s.mesh_alpha(inst.mesh).accepts(p, h.u, h.v);
            all.push_back({h.t, k, p, accepted, !inst.opaque});
        }
    }
    BruteResult b;
    for (const Candidate& c : all)
        if (c.accepted && c.t < b.t) b.t = c.t;
    for (const Candidate& c : all) {
        b.candidates += c.shaded;
        b.nearer_candidates += c.shaded && c.t < b.t;
        if (c.accepted && c.t == b.t) b.at_best.push_back({c.inst, c.prim});
    }
    return b;
}

// Random placements (rotations, non-uniform scales, mirrors) of small meshes, half of them
// non-opaque.
InstancedScene alpha_scene(uint32_t seed) {
    const std::filesystem::path dir = RTSIM_CGAL_MESH_DIR;
    InstancedScene s;
    s.name = "alpha test";
    s.meshes.push_back(load_scene((dir / "cube-meshed.off").string()));
    s.meshes.push_back(load_scene((dir / "blob.off").string()));
    s.meshes.push_back(load_scene((dir / "cactus.off").string()));

    AlphaMask checker, holes;
    checker.pattern = AlphaPattern::Checker;
    checker.cells = 3;
    holes.pattern = AlphaPattern::Triangles;
    holes.keep = 0.3;
    // Eight large triangles through one centre at different tilts: their boxes overlap, so a
    // builder keeps them in one leaf (two blocks of four), and a ray through it meets several
    // candidates there, nearer ones after farther ones in slot order.
    Scene layers;
    layers.name = "star";
    std::mt19937 tilt(3);
    std::uniform_real_distribution<float> d(-1.0f, 1.0f);
    for (uint32_t k = 0; k < 8; ++k) {
        const Vec3 n = normalize(Vec3(d(tilt), d(tilt), d(tilt)));
        const Vec3 e1 = normalize(cross(n, std::fabs(n.x) < 0.9f ? Vec3(1, 0, 0) : Vec3(0, 1, 0)));
        const Vec3 e2 = cross(n, e1);
        const auto v = uint32_t(layers.vertices.size());
        for (const float a : {0.0f, 2.0944f, 4.1888f})
            layers.vertices.push_back(Vec3(0.5f, 0.5f, 0.5f) +
                                      (e1 * std::cos(a) + e2 * std::sin(a)));
        layers.triangles.push_back({v, v + 1, v + 2});
    }
    s.meshes.push_back(layers);
    // The cactus has no mask (non-opaque, it accepts all).
    s.alpha = {checker, holes, AlphaMask(), checker};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    for (int k = 0; k < 32; ++k) {
        Instance inst;
        inst.mesh = uint32_t(k % 4);
        inst.opaque = (k / 4) % 2 == 1;
        inst.mask = (k / 3) % 2 == 0 ? 0x0f : 0xf0;
        const AABB b = s.meshes[inst.mesh].bounds();
        const float size = std::max({b.extent().x, b.extent().y, b.extent().z});
        // A random rotation (Gram-Schmidt of a random matrix), scaled per axis, some mirrored.
        Vec3 a0 = normalize(Vec3(u(rng), u(rng), u(rng)));
        Vec3 a1 = Vec3(u(rng), u(rng), u(rng));
        a1 = normalize(a1 - a0 * dot(a0, a1));
        const Vec3 a2 = cross(a0, a1);
        const Vec3 sc = Vec3(0.6f + 0.4f * u(rng), 0.6f + 0.4f * u(rng), 0.6f + 0.4f * u(rng)) *
                        ((k % 5 == 0 ? -1.0f : 1.0f) / size);
        const Vec3 cols[3] = {a0 * sc.x, a1 * sc.y, a2 * sc.z};
        const Vec3 c = b.center();
        const Vec3 at = Vec3(u(rng), u(rng), u(rng)) * 1.5f;
        for (int row = 0; row < 3; ++row) {
            for (int col = 0; col < 3; ++col)
                inst.object_to_world.m[size_t(row * 4 + col)] = cols[col][row];
            // Centre the mesh at `at`.
            inst.object_to_world.m[size_t(row * 4 + 3)] =
                at[row] - (cols[0][row] * c.x + cols[1][row] * c.y + cols[2][row] * c.z);
        }
        s.instances.push_back(inst);
    }
    s.validate();
    return s;
}

}  // namespace

// Closest-hit and any-hit queries at every width and node format, two ray masks: the hit is the
// nearest accepted candidate (its t bit for bit: the same triangle test on the same local ray),
// the shader runs on every candidate an any-hit query meets when nothing is accepted, and in a
// closest-hit query on every candidate nearer than the hit (and on no more than all of them).
TEST(Alpha, TwoLevelTraversalKeepsTheNearestAcceptedCandidate) {
    ASSERT_TRUE(std::filesystem::is_directory(RTSIM_CGAL_MESH_DIR)) << "run scripts/setup.sh";
    const InstancedScene s = alpha_scene(5);
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<Ray> rays;
    for (int i = 0; i < 400; ++i) {
        Ray r;
        r.org = Vec3(u(rng), u(rng), u(rng)) * 6.0f;
        r.dir = normalize(Vec3(u(rng), u(rng), u(rng)) * 1.2f - r.org);
        if (i % 3 == 2) r.tmax = 4.0f + 4.0f * u(rng);
        rays.push_back(r);
    }
    size_t ignored_total = 0, hits = 0, star_hits = 0;
    for (const NodeFormat format : {NodeFormat::Full, NodeFormat::Compressed})
        for (const int w : {2, 4, 8}) {
            BvhBuildOptions bo;
            bo.node_format = format;
            bo.width = w;
            bo.max_leaf_size = w;  // BVH8: leaves of up to 8, two blocks of four
            const TwoLevelBvh two = build_two_level(s, bo);
            for (const uint8_t ray_mask : {uint8_t(0xff), uint8_t(0x0f)})
                for (size_t i = 0; i < rays.size(); ++i) {
                    SCOPED_TRACE("BVH" + std::to_string(w) + " " + node_format_name(format) +
                                 " mask " + std::to_string(ray_mask) + " ray " + std::to_string(i));
                    const Ray& r = rays[i];
                    const BruteResult b = brute_force(s, two, r, ray_mask);
                    TraceCounters cc, ca;
                    const Hit closest = trace_ray(two, r, HitQuery::Closest, ray_mask, &cc);
                    const Hit any = trace_ray(two, r, HitQuery::Any, ray_mask, &ca);
                    ASSERT_EQ(closest.valid(), b.prim != kInvalidPrim || !b.at_best.empty());
                    ASSERT_EQ(any.valid(), closest.valid());
                    EXPECT_LE(cc.any_hits, b.candidates);
                    EXPECT_GE(cc.any_hits, b.nearer_candidates);
                    if (!closest.valid()) {
                        EXPECT_EQ(ca.any_hits, b.candidates);  // every candidate ignored
                        ignored_total += b.candidates;
                        continue;
                    }
                    ++hits;
                    if (s.instances[closest.instance].mesh == 3) ++star_hits;
                    EXPECT_EQ(closest.t, b.t);
                    const std::pair<uint32_t, uint32_t> got{closest.instance, closest.prim};
                    EXPECT_NE(std::find(b.at_best.begin(), b.at_best.end(), got), b.at_best.end());
                    // An any-hit query ends at an accepted candidate within the range.
                    const Instance& ai = s.instances[any.instance];
                    EXPECT_TRUE(ai.mask & ray_mask);
                    EXPECT_LT(any.t, r.tmax);
                    EXPECT_TRUE(ai.opaque || s.mesh_alpha(ai.mesh).accepts(any.prim, any.u, any.v));
                }
        }
    // The case is not vacuous: rays hit, and rays pass candidates the masks cut out.
    EXPECT_GT(hits, 6u * 2 * rays.size() / 5);
    EXPECT_GT(ignored_total, 100u);
    EXPECT_GT(star_hits, hits / 10);
}

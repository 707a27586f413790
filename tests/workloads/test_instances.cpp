// Two-level step streams (workloads/instances.h) on cases small enough to write out by hand.
#include <gtest/gtest.h>

#include <random>

#include "workloads/instances.h"

using namespace rtsim;

namespace {

// Two copies of one triangle (0,0,0), (1,0,0), (0,1,0): one at z = 0, one moved to z = -5; one
// instance per TLAS leaf, so the TLAS root has the two as children.
InstancedScene two_copies() {
    InstancedScene s;
    s.name = "two copies";
    Scene tri;
    tri.vertices = std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    tri.triangles = std::vector<std::array<uint32_t, 3>>{{0, 1, 2}};
    s.meshes.push_back(tri);
    Instance near, far;
    far.object_to_world.m[11] = -5;
    s.instances = {near, far};
    return s;
}

BvhBuildOptions one_per_leaf() {
    BvhBuildOptions o;
    o.max_leaf_size = 1;
    return o;
}

}  // namespace

TEST(Instances, StepsFollowTheNearestInstanceThenCullTheOther) {
    const TwoLevelBvh two = build_two_level(two_copies(), one_per_leaf());
    const BvhLayout& L = two.layout;
    ASSERT_EQ(two.tlas_node_count, 1u);  // a root with two leaf children
    ASSERT_EQ(L.inner_node_count, 2u);   // and the BLAS's one record
    ASSERT_EQ(L.triangle_count, 1u);
    ASSERT_EQ(L.instance_count, 2u);
    for (const float dz : {-1.0f, 1.0f}) {
        Ray r;
        r.org = Vec3(0.2f, 0.2f, dz > 0 ? -10.0f : 10.0f);
        r.dir = Vec3(0, 0, dz);
        std::vector<Step> steps;
        const Hit h = trace_ray_recorded(two, r, HitQuery::Closest, steps);
        // From above the z = 0 copy is hit at t = 10; from below the z = -5 one at t = 5.
        const uint32_t want = dz < 0 ? 0u : 1u;
        ASSERT_TRUE(h.valid());
        EXPECT_EQ(h.instance, want);
        EXPECT_FLOAT_EQ(h.t, dz < 0 ? 10.0f : 5.0f);
        EXPECT_EQ(h.instance, trace_ray(two, r, HitQuery::Closest).instance);
        // The TLAS root; the nearer instance's record; the BLAS's root record (global node 1)
        // and its triangle (global slot 0). The farther instance is culled: its entry distance
        // lies beyond the hit.
        ASSERT_EQ(steps.size(), 4u);
        EXPECT_EQ(steps[0].kind, StepKind::Node);
        EXPECT_EQ(steps[0].id, 0u);
        EXPECT_EQ(steps[1].kind, StepKind::Transform);
        EXPECT_EQ(two.tlas.prim_order[steps[1].id], want);  // the record is in TLAS slot order
        EXPECT_EQ(steps[1].addr, two.instance_base_addr + uint64_t(steps[1].id) * 64);
        EXPECT_EQ(steps[1].size_bytes, 64);
        EXPECT_EQ(steps[2].kind, StepKind::Node);
        EXPECT_EQ(steps[2].id, 1u);
        EXPECT_EQ(steps[2].addr, L.node_base_addr + L.node_size_bytes);
        EXPECT_EQ(steps[3].kind, StepKind::Triangle);
        EXPECT_EQ(steps[3].id, 0u);
        EXPECT_EQ(steps[3].addr, L.tri_base_addr);
        // The TLAS keeps the farther leaf on its stack while the BLAS runs: depth 1 under it.
        EXPECT_EQ(stack_depth(steps[0]), 0u);
        EXPECT_EQ(stack_depth(steps[1]), 1u);
        EXPECT_EQ(stack_depth(steps[2]), 1u);
    }
}

TEST(Instances, MaskedInstancesAreNeitherFetchedNorHit) {
    InstancedScene s = two_copies();
    s.instances[0].mask = 2;
    const TwoLevelBvh two = build_two_level(s, one_per_leaf());
    Ray r;
    r.org = Vec3(0.2f, 0.2f, 10.0f);
    r.dir = Vec3(0, 0, -1);
    std::vector<Step> steps;
    const Hit h = trace_ray_recorded(two, r, HitQuery::Closest, steps, /*mask=*/1);
    ASSERT_TRUE(h.valid());
    EXPECT_EQ(h.instance, 1u);  // through the masked-out copy to the one behind
    EXPECT_FLOAT_EQ(h.t, 15.0f);
    int transforms = 0;
    for (const Step& st : steps) transforms += st.kind == StepKind::Transform;
    EXPECT_EQ(transforms, 1);
}

// A non-opaque copy whose alpha mask cuts its triangle out: the ray from above tests it (triangle
// step), hands the candidate to the any-hit shader (any-hit step on the triangle's alpha record),
// which ignores it, and goes on to the opaque copy behind, which it hits at once (no any-hit
// step). Made opaque again, the near copy is hit with no shader call.
TEST(Instances, AnIgnoredCandidateLetsTraversalGoOnBehindIt) {
    InstancedScene s = two_copies();
    AlphaMask cut_out;
    cut_out.pattern = AlphaPattern::Triangles;
    cut_out.keep = 0;  // no triangle solid
    s.alpha = {cut_out};
    s.instances[0].opaque = false;
    BvhLayout sizes;
    sizes.alpha_size_bytes = 16;
    const TwoLevelBvh two = build_two_level(s, one_per_leaf(), sizes);
    const BvhLayout& L = two.layout;
    ASSERT_EQ(L.alpha_count, 1u);  // one triangle slot, one alpha record
    EXPECT_GE(L.alpha_base_addr, L.tri_base_addr + L.tri_size_bytes);
    Ray r;
    r.org = Vec3(0.2f, 0.2f, 10.0f);
    r.dir = Vec3(0, 0, -1);
    for (const HitQuery q : {HitQuery::Closest, HitQuery::Any}) {
        std::vector<Step> steps;
        TraceCounters c;
        const Hit h = trace_ray_recorded(two, r, q, steps, 0xff, &c);
        ASSERT_TRUE(h.valid());
        EXPECT_EQ(h.instance, 1u);
        EXPECT_FLOAT_EQ(h.t, 15.0f);
        EXPECT_EQ(c.any_hits, 1u);
        std::vector<StepKind> kinds;
        for (const Step& st : steps) kinds.push_back(st.kind);
        const std::vector<StepKind> want = {
            StepKind::Node,   StepKind::Transform, StepKind::Node, StepKind::Triangle,
            StepKind::AnyHit, StepKind::Transform, StepKind::Node, StepKind::Triangle};
        EXPECT_EQ(kinds, want);
        EXPECT_EQ(steps[4].addr, L.alpha_base_addr);
        EXPECT_EQ(steps[4].size_bytes, 16);
        EXPECT_EQ(two.tlas.prim_order[steps[1].id], 0u);  // the near copy first
    }
    s.instances[0].opaque = true;
    const TwoLevelBvh solid = build_two_level(s, one_per_leaf(), sizes);
    EXPECT_EQ(solid.layout.alpha_count, 0u);  // no shader can run: no alpha region
    TraceCounters c;
    const Hit h = trace_ray(solid, r, HitQuery::Closest, 0xff, &c);
    EXPECT_EQ(h.instance, 0u);
    EXPECT_EQ(c.any_hits, 0u);
}

// Treelets over two levels: the TLAS and every BLAS are cut on their own and numbered TLAS
// first; each treelet's records are a run of the global layout, and every step of a recorded
// traversal carries the treelet whose run holds its record (an instance record: its TLAS leaf's
// treelet; an any-hit step: its triangle's). The cut only moves records, so hits do not change.
TEST(Instances, TreeletsCutBothLevelsAndStepsCarryTheirRecordsTreelet) {
    InstancedScene s;
    s.name = "treelet forest";
    s.meshes.push_back(load_scene("builtin:sphere"));
    s.meshes.push_back(load_scene("builtin:cornell"));
    AlphaMask holes;
    holes.pattern = AlphaPattern::Triangles;
    s.alpha = {holes};
    for (int k = 0; k < 40; ++k) {
        Instance inst;
        inst.mesh = uint32_t(k % 2);
        inst.opaque = k % 4 != 0;
        inst.object_to_world.m = {
            0.2f, 0, 0, float(k % 8) * 0.5f, 0, 0.2f, 0, float(k / 8) * 0.5f, 0, 0, 0.2f, 0};
        s.instances.push_back(inst);
    }
    BvhBuildOptions plain, cut;
    plain.width = cut.width = 4;
    cut.treelet_bytes = 4096;
    const TwoLevelBvh a = build_two_level(s, plain), b = build_two_level(s, cut);
    const BvhLayout& L = b.layout;
    ASSERT_GT(L.treelet_count(), b.tlas.layout.treelet_count());
    const uint32_t tlas_treelets = b.tlas.layout.treelet_count();
    ASSERT_GT(tlas_treelets, 1u);  // instance records in more than one treelet
    ASSERT_EQ(L.treelet_instance_start.size(), L.treelet_node_start.size());
    EXPECT_EQ(L.treelet_instance_start[tlas_treelets], L.instance_count);  // all in the TLAS's
    EXPECT_EQ(L.treelet_tri_start[tlas_treelets], 0u);  // which hold no triangles
    EXPECT_EQ(L.treelet_node_start[tlas_treelets], b.tlas_node_count);
    auto holds = [](const std::vector<uint32_t>& start, uint32_t treelet, uint32_t id) {
        return start[treelet] <= id && id < start[treelet + 1];
    };
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    size_t steps_checked = 0, any_hit_steps = 0, transforms = 0;
    for (int i = 0; i < 500; ++i) {
        Ray r;
        r.org = Vec3(1.75f, 2.25f, 3.0f) + Vec3(u(rng), u(rng), u(rng)) * 0.5f;
        r.dir = normalize(Vec3(1.75f + 2 * u(rng), 2.25f + 2 * u(rng), 0) - r.org);
        for (const HitQuery q : {HitQuery::Closest, HitQuery::Any}) {
            std::vector<Step> steps;
            const Hit x = trace_ray(a, r, q), y = trace_ray_recorded(b, r, q, steps);
            ASSERT_EQ(x.valid(), y.valid());
            if (x.valid() && q == HitQuery::Closest) {
                EXPECT_EQ(x.t, y.t);
                EXPECT_EQ(x.instance, y.instance);
            }
            for (const Step& st : steps) {
                ++steps_checked;
                switch (st.kind) {
                    case StepKind::Node:
                        EXPECT_TRUE(holds(L.treelet_node_start, st.treelet, st.id));
                        break;
                    case StepKind::Transform:
                        ++transforms;
                        EXPECT_TRUE(holds(L.treelet_instance_start, st.treelet, st.id));
                        EXPECT_LT(st.treelet, tlas_treelets);
                        break;
                    default:  // a triangle, or the any-hit step on it
                        any_hit_steps += st.kind == StepKind::AnyHit;
                        EXPECT_TRUE(holds(L.treelet_tri_start, st.treelet, st.id));
                        EXPECT_GE(st.treelet, tlas_treelets);
                }
            }
        }
    }
    EXPECT_GT(steps_checked, 5000u);
    EXPECT_GT(transforms, 500u);
    EXPECT_GT(any_hit_steps, 50u);
}

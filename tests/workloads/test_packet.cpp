#include <gtest/gtest.h>

#include "workloads/packet.h"
#include "workloads/raygen.h"
#include "workloads/tile_queue.h"

using namespace rtsim;

namespace {

struct Rays {
    std::vector<Ray> rays;
    HitQuery query = HitQuery::Closest;
};

Rays generate(const Scene& s, const Bvh& bvh, const char* kind, int res) {
    RayGenOptions o;
    o.width = o.height = res;
    o.kinds = parse_ray_kinds(kind, "test");
    RayGenerator g(s, bvh, o);
    std::vector<GeneratedRay> out;
    TileQueue tiles(g, 1);
    while (tiles.next(out)) {
    }
    Rays r;
    for (const auto& x : out) r.rays.push_back(x.ray);
    if (!out.empty()) r.query = out[0].query;
    return r;
}

// Traces all rays in packets of `size`, checking each hit against single-ray traversal.
PacketStats trace_and_compare(const Bvh& bvh, const Rays& r, int size, float threshold) {
    PacketOptions po;
    po.size = size;
    po.switch_threshold = threshold;
    PacketStats st;
    Hit hits[kMaxPacketSize];
    for (size_t b = 0; b < r.rays.size(); b += size) {
        const int n = int(std::min<size_t>(size, r.rays.size() - b));
        trace_packet(bvh, &r.rays[b], n, r.query, hits, po, st);
        for (int i = 0; i < n; ++i) {
            const Hit single = trace_ray(bvh, r.rays[b + i], r.query);
            EXPECT_EQ(hits[i].valid(), single.valid()) << "ray " << b + i;
            if (r.query == HitQuery::Closest && single.valid()) {
                EXPECT_EQ(hits[i].t, single.t)
                    << "ray " << b + i;  // same minimum; prims differ only on ties
            }
        }
    }
    return st;
}

}  // namespace

TEST(Packet, ResultsEqualSingleRayForEveryWidthSizeAndKind) {
    Scene s = load_scene("builtin:cornell");
    for (int w : {2, 4, 8}) {
        BvhBuildOptions o;
        o.width = w;
        const Bvh bvh = build_bvh(s, o);
        for (const char* kind : {"primary", "shadow", "ao", "diffuse", "reflection"}) {
            const Rays r = generate(s, bvh, kind, 24);
            for (int size : {8, 16, 64})
                for (float threshold : {0.0f, 0.3f}) {
                    SCOPED_TRACE(std::string(kind) + " BVH" + std::to_string(w) + " packet " +
                                 std::to_string(size) + " switch " + std::to_string(threshold));
                    trace_and_compare(bvh, r, size, threshold);
                }
        }
    }
}

TEST(Packet, CoherentRaysFillLanesIncoherentRaysDoNot) {
    Scene s = load_scene("builtin:cornell");
    const Bvh bvh = build_bvh(s, BvhBuildOptions());
    // 256x256 pixels, 16-ray packets (8x2 pixel strips of a tile, or 16 consecutive bounces).
    const PacketStats primary = trace_and_compare(bvh, generate(s, bvh, "primary", 256), 16, 0.0f);
    const PacketStats diffuse = trace_and_compare(bvh, generate(s, bvh, "diffuse", 256), 16, 0.0f);
    std::printf("lane utilisation, 16-ray packets: primary %.3f, diffuse %.3f\n",
                primary.utilization(), diffuse.utilization());
    EXPECT_GT(primary.utilization(), 0.5);
    EXPECT_LT(diffuse.utilization(), 0.5 * primary.utilization());
}

TEST(Packet, SwitchKeepsPacketVisitsAboveThreshold) {
    Scene s = load_scene("builtin:cornell");
    const Bvh bvh = build_bvh(s, BvhBuildOptions());
    const Rays r = generate(s, bvh, "diffuse", 48);
    const PacketStats st = trace_and_compare(bvh, r, 32, 0.25f);
    // A packet visits a node only with at least a quarter of its lanes active; the rest goes
    // ray by ray.
    EXPECT_GE(st.utilization(), 0.25);
    EXPECT_GT(st.switches, 0u);
    EXPECT_GT(st.single_ray_nodes, 0u);
}

TEST(Packet, SizeOneMatchesSingleRayWork) {
    Scene s = load_scene("builtin:sphere");
    const Bvh bvh = build_bvh(s, BvhBuildOptions());
    const Rays r = generate(s, bvh, "primary", 16);
    const PacketStats st = trace_and_compare(bvh, r, 1, 0.0f);
    uint64_t nodes = 0;
    for (const Ray& ray : r.rays) {
        TraceCounters c;
        trace_ray(bvh, ray, r.query, nullptr, &c);
        nodes += c.nodes;
    }
    EXPECT_EQ(st.node_visits, nodes);
    EXPECT_DOUBLE_EQ(st.utilization(), nodes ? 1.0 : 0.0);
}

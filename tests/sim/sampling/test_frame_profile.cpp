// The skip design of sampled runs (sim.sample_fast_forward = skip): which tiles it traces, and the
// frame profile it regresses on and replays into the L2.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include "sim/sampling/frame_profile.h"
#include "sim/sampling/sampler.h"
#include "support/cache_damage.h"
#include "support/file_bytes.h"
#include "workloads/tile_queue.h"
#include "workloads/tracer.h"

using namespace rtsim;
namespace fs = std::filesystem;

namespace {

SamplingParams skip_params() {
    SamplingParams p;
    p.skip = true;
    p.stratified = false;
    p.period_units = 3;
    p.first_unit = 1;
    p.unit_tiles = 2;
    p.warm_tiles = 2;
    p.warmup_tiles = 1;
    p.tiles = 12;
    return p;
}

}  // namespace

// Units of 2 tiles, every third from unit 1: units 1 and 4 (tiles 2-3 and 8-9) are measured.
// Written out by hand: the tile after each measured unit closes it (4, 10), one tile before it
// runs in detail (1, 7), the two before those warm the caches (0; 5 and 6), the rest is skipped.
TEST(SkipDesign, TileRolesByHand) {
    using R = SampleDesign::TileRole;
    const SampleDesign d(skip_params());
    const R want[12] = {R::Warming, R::Warmup, R::Measured, R::Measured, R::After, R::Warming,
                        R::Warming, R::Warmup, R::Measured, R::Measured, R::After, R::Skipped};
    for (uint64_t t = 0; t < 12; ++t) EXPECT_EQ(int(d.tile_role(t)), int(want[t])) << "tile " << t;
    EXPECT_EQ(d.units(), 6u);
    EXPECT_FALSE(d.wants_tile(11));
}

// The same design knowing each tile's rays, with a warm-up of at least 5 rays: it reaches back
// past its one tile while the tiles it holds have fewer (tiles 0 and 1 hold none and 3 rays; 7
// and 6, none and 6), then one tile warms the caches (5), and the tile that closes unit 1 (4)
// stays what it is. By hand.
TEST(SkipDesign, WarmupReachesBackUntilItHoldsEnoughRays) {
    using R = SampleDesign::TileRole;
    SamplingParams p = skip_params();
    p.warm_tiles = 1;
    p.warmup_tile_rays = 5;
    p.tile_rays = {3, 0, 9, 9, 2, 1, 6, 0, 9, 9, 9, 9};
    const SampleDesign d(p);
    const R want[12] = {R::Warmup, R::Warmup, R::Measured, R::Measured, R::After, R::Warming,
                        R::Warmup, R::Warmup, R::Measured, R::Measured, R::After, R::Skipped};
    for (uint64_t t = 0; t < 12; ++t) EXPECT_EQ(int(d.tile_role(t)), int(want[t])) << "tile " << t;
    // A warm-up tile without rays is not generated (it hands nothing on); one with rays is.
    EXPECT_FALSE(d.wants_tile(1));
    EXPECT_FALSE(d.wants_tile(7));
    EXPECT_TRUE(d.wants_tile(0));
    EXPECT_TRUE(d.wants_tile(6));
    // Without the rays, the warm-up is its one tile again.
    p.tile_rays.clear();
    const SampleDesign tiles_only(p);
    EXPECT_EQ(int(tiles_only.tile_role(0)), int(R::Warming));
    EXPECT_EQ(int(tiles_only.tile_role(6)), int(R::Warming));
    EXPECT_EQ(int(tiles_only.tile_role(5)), int(R::Skipped));
    // A measured unit without rays (4, tiles 8-9) takes no cycles whatever came before and has
    // nothing to close: no warm-up, no closing tile; and the warm-up of the next one (7, tiles
    // 14-15) reaches back through it as through any tile without rays, to tile 6. By hand.
    p.tiles = 18;
    p.tile_rays = {3, 0, 9, 9, 2, 1, 6, 0, 0, 0, 0, 0, 0, 0, 9, 9, 9, 9};
    const SampleDesign rayless(p);
    const R want_rayless[18] = {R::Warmup,   R::Warmup, R::Measured, R::Measured, R::After,
                                R::Warming,  R::Warmup, R::Warmup,   R::Measured, R::Measured,
                                R::Warmup,   R::Warmup, R::Warmup,   R::Warmup,   R::Measured,
                                R::Measured, R::After,  R::Skipped};
    for (uint64_t t = 0; t < 18; ++t)
        EXPECT_EQ(int(rayless.tile_role(t)), int(want_rayless[t])) << "tile " << t;
}

// A warm-up that reaches back to the tile closing the measured unit before runs all of that
// tile: units 1 and 4 (tiles 2-3, 8-9) at 9 rays a tile and a warm-up of at least 30 rays.
// Unit 4's goes back over tiles 7, 6 and 5 (27 rays) to tile 4, which closes unit 1: tiles 2 to
// 9 are one window, and none of tile 4's rays is skipped between them. By hand.
TEST(SkipDesign, AWarmupThatReachesTheWindowBeforeJoinsIt) {
    using R = SampleDesign::TileRole;
    SamplingParams p = skip_params();
    p.warmup_tile_rays = 30;
    p.tile_rays.assign(12, 9);
    const SampleDesign d(p);
    const R want[12] = {R::Warmup, R::Warmup, R::Measured, R::Measured, R::Warmup, R::Warmup,
                        R::Warmup, R::Warmup, R::Measured, R::Measured, R::After,  R::Skipped};
    for (uint64_t t = 0; t < 12; ++t) EXPECT_EQ(int(d.tile_role(t)), int(want[t])) << "tile " << t;
}

// A warm-up reaches back until it holds warmup_work besides its rays: units 1 and 4 (tiles 2-3,
// 8-9), 4 rays a tile, a one-tile warm-up, a least work of 50. Tiles 7 to 5 hold background rays
// (work 4 each), tile 4 closes unit 1: unit 4's warm-up goes back over 7, 6, 5 (work 12) and
// joins unit 1's window at tile 4. With work 100 in tile 7 it stops there. Unit 1's reaches the
// frame's start. By hand.
TEST(SkipDesign, AWarmupReachesBackUntilItHoldsEnoughWork) {
    using R = SampleDesign::TileRole;
    SamplingParams p = skip_params();
    p.warm_tiles = 0;
    p.warmup_tile_rays = 0;
    p.tile_rays.assign(12, 4);
    p.tile_work.assign(12, 4);
    p.warmup_work = 50;
    const SampleDesign light(p);
    const R joined[12] = {R::Warmup, R::Warmup, R::Measured, R::Measured, R::Warmup, R::Warmup,
                          R::Warmup, R::Warmup, R::Measured, R::Measured, R::After,  R::Skipped};
    for (uint64_t t = 0; t < 12; ++t)
        EXPECT_EQ(int(light.tile_role(t)), int(joined[t])) << "tile " << t;
    p.tile_work[7] = 100;
    const SampleDesign heavy(p);
    const R apart[12] = {R::Warmup,  R::Warmup, R::Measured, R::Measured, R::After, R::Skipped,
                         R::Skipped, R::Warmup, R::Measured, R::Measured, R::After, R::Skipped};
    for (uint64_t t = 0; t < 12; ++t)
        EXPECT_EQ(int(heavy.tile_role(t)), int(apart[t])) << "tile " << t;
}

// A stratified skip design draws its last, shorter stratum among the units it has: every stratum
// then holds exactly one measured unit, whatever the seed.
TEST(SkipDesign, EveryStratumHasOneMeasuredUnit) {
    SamplingParams p = skip_params();
    p.stratified = true;
    p.first_unit = -1;
    p.period_units = 4;
    p.tiles = 2 * 10;  // 10 units: strata of 4, 4 and 2
    for (uint64_t seed = 1; seed <= 200; ++seed) {
        p.seed = seed;
        const SampleDesign d(p);
        for (uint64_t h = 0; h < 3; ++h) {
            int measured = 0;
            for (uint64_t u = 4 * h; u < std::min<uint64_t>(10, 4 * h + 4); ++u)
                measured += d.measured_unit(u);
            EXPECT_EQ(measured, 1) << "seed " << seed << " stratum " << h;
        }
    }
}

// Strata cut from a given order of the units: each run of period_units units of the order holds
// exactly one measured unit, whatever the seed; the order listed in the frame's own order
// measures what no order does; and the tiles of the units measured are the ones run in detail.
TEST(SkipDesign, StrataFollowTheUnitOrder) {
    SamplingParams p = skip_params();
    p.stratified = true;
    p.first_unit = -1;
    p.period_units = 4;
    p.tiles = 2 * 10;  // 10 units: strata of 4, 4 and 2 in the order
    const std::vector<uint32_t> order = {7, 2, 9, 0, 5, 1, 8, 3, 6, 4};
    const std::set<uint32_t> strata[3] = {{7, 2, 9, 0}, {5, 1, 8, 3}, {6, 4}};
    for (uint64_t seed = 1; seed <= 200; ++seed) {
        p.seed = seed;
        p.unit_order = order;
        const SampleDesign d(p);
        for (int h = 0; h < 3; ++h) {
            int measured = 0;
            for (uint32_t u : strata[h]) measured += d.measured_unit(u);
            EXPECT_EQ(measured, 1) << "seed " << seed << " stratum " << h;
        }
        for (uint32_t u = 0; u < 10; ++u) {
            const auto role = d.tile_role(2 * u);
            EXPECT_EQ(role == SampleDesign::TileRole::Measured, d.measured_unit(u)) << u;
        }
        // The first measured unit of the order is the one reported.
        EXPECT_TRUE(d.measured_unit(d.first_unit()));
        EXPECT_EQ(strata[0].count(uint32_t(d.first_unit())), 1u);
        p.unit_order = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
        const SampleDesign in_order(p);
        p.unit_order.clear();
        const SampleDesign frame(p);
        for (uint64_t u = 0; u < 10; ++u)
            EXPECT_EQ(in_order.measured_unit(u), frame.measured_unit(u)) << seed << " " << u;
    }
    // Not a permutation of the frame's units.
    p.unit_order = {0, 1, 2};
    EXPECT_THROW(SampleDesign{p}, std::invalid_argument);
    p.unit_order = {0, 1, 2, 3, 4, 5, 6, 7, 8, 8};
    EXPECT_THROW(SampleDesign{p}, std::invalid_argument);
    p.unit_order = {0, 1, 2, 3, 4, 5, 6, 7, 8, 10};
    EXPECT_THROW(SampleDesign{p}, std::invalid_argument);
}

namespace {

struct Frame {
    Scene scene = load_scene("builtin:cornell");
    Bvh bvh = build_bvh(scene, BvhBuildOptions());
    RayGenOptions options() const {
        RayGenOptions o;
        o.width = 40;
        o.height = 24;  // 5 x 3 tiles of 8x8
        o.kinds = parse_ray_kinds("primary,ao", "test");
        return o;
    }
    uint64_t base() const { return bvh.layout.fetch_begin(); }
    uint64_t end() const { return bvh.layout.fetch_end(); }
};

}  // namespace

// The profile against an independent count: every ray of the frame traced one tile at a time, its
// lines gathered in std::sets (the tile's, and the frame's so far).
TEST(FrameProfile, CountsWhatTheFrameTracesAndFetches) {
    const Frame f;
    RayGenerator gen(f.scene, f.bvh, f.options());
    gen.set_record_steps(true);
    const uint64_t unit_tiles = 2;
    const FrameProfile p =
        profile_frame(gen, tracer_of(f.bvh), unit_tiles, f.base(), f.end(), 64, 1);
    ASSERT_EQ(p.units.size(), 8u);  // 15 tiles in units of 2
    ASSERT_EQ(p.tile_line_start.size(), 16u);
    auto line_of = [&p](uint32_t k) { return (p.line_base + uint64_t(k) * 64) / 64; };

    std::set<uint64_t> seen;
    uint64_t shared = 0;  // tile lines more than one ray fetched
    std::vector<uint64_t> rays(p.units.size()), steps(p.units.size()), fresh(p.units.size()),
        fresh_rays(p.units.size());
    for (int t = 0; t < gen.tile_count(); ++t) {
        std::vector<GeneratedRay> tile;
        gen.generate_tile(t, tile);
        EXPECT_EQ(p.tile_rays[size_t(t)], tile.size()) << "tile " << t;
        // Per line of the tile: the rays that fetched it, and whether it held triangles.
        std::map<uint64_t, std::pair<std::set<size_t>, bool>> tile_lines;
        std::set<uint64_t> tile_fresh;  // lines no earlier tile fetched
        for (size_t r = 0; r < tile.size(); ++r) {
            GeneratedRay& g = tile[r];
            if (!g.traced) trace_ray(f.bvh, g.ray, g.query, &g.steps);
            rays[size_t(t) / unit_tiles] += 1;
            steps[size_t(t) / unit_tiles] += g.steps.size();
            for (const Step& s : g.steps)
                for (uint64_t a = s.addr / 64; a <= (s.addr + s.size_bytes - 1) / 64; ++a) {
                    const bool first = seen.insert(a).second;
                    fresh[size_t(t) / unit_tiles] += first;
                    if (first) tile_fresh.insert(a);
                    tile_lines[a].first.insert(r);
                    tile_lines[a].second |= s.kind == StepKind::Triangle;
                }
        }
        // The tile's lines, each once, with their rays (at most 127) and kind.
        std::set<uint64_t> listed;
        for (uint32_t i = p.tile_line_start[size_t(t)]; i < p.tile_line_start[size_t(t) + 1]; ++i) {
            const uint64_t line = line_of(p.tile_lines[i]);
            EXPECT_TRUE(listed.insert(line).second) << "tile " << t;
            ASSERT_EQ(tile_lines.count(line), 1u);
            const auto& [by, triangles] = tile_lines[line];
            EXPECT_EQ(p.tile_line_info[i] & kTileLineRays, std::min<size_t>(by.size(), 127));
            EXPECT_EQ((p.tile_line_info[i] & kTileLineTriangle) != 0, triangles);
            shared += by.size() > 1;
        }
        EXPECT_EQ(listed.size(), tile_lines.size()) << "tile " << t;
        // The rays waiting on the tile's new lines: those of the tile that fetched each.
        for (uint64_t a : tile_fresh)
            fresh_rays[size_t(t) / unit_tiles] += std::min<size_t>(tile_lines[a].first.size(), 127);
    }
    for (size_t u = 0; u < p.units.size(); ++u) {
        EXPECT_EQ(p.units[u][kAuxRays], rays[u]) << u;
        EXPECT_EQ(p.units[u][kAuxWork], steps[u] + rays[u]) << u;
        EXPECT_EQ(p.units[u][kAuxNewLines], fresh[u]) << u;
        EXPECT_EQ(p.unit_new_line_rays[u], fresh_rays[u]) << u;
        EXPECT_GE(fresh_rays[u], fresh[u]) << u;  // each new line, at least its first ray
    }
    EXPECT_GT(p.tile_lines.size(), seen.size());  // tiles share lines (the root's, at least)
    EXPECT_GT(shared, 0u);
    // The same profile on two threads.
    const FrameProfile q =
        profile_frame(gen, tracer_of(f.bvh), unit_tiles, f.base(), f.end(), 64, 2);
    EXPECT_EQ(q.units, p.units);
    EXPECT_EQ(q.unit_new_line_rays, p.unit_new_line_rays);
    EXPECT_EQ(q.tile_line_start, p.tile_line_start);
    EXPECT_EQ(q.tile_lines, p.tile_lines);
    EXPECT_EQ(q.tile_line_info, p.tile_line_info);
    EXPECT_EQ(q.tile_rays, p.tile_rays);
}

// The profile cache: stored, then served; a damaged, truncated or foreign entry is recomputed
// and stored over, never used.
TEST(FrameProfile, CacheServesValidEntriesAndRefusesDamagedOnes) {
    const Frame f;
    RayGenerator gen(f.scene, f.bvh, f.options());
    gen.set_record_steps(true);
    const fs::path dir = fs::path(::testing::TempDir()) / "rtsim_profile_cache";
    fs::remove_all(dir);
    auto get = [&](const std::string& key) {
        return profile_frame_cached(gen, tracer_of(f.bvh), 2, f.base(), f.end(), 64, 1, key,
                                    dir.string());
    };
    const FrameProfile built = get("a");
    EXPECT_EQ(built.cache, "built");
    const FrameProfile hit = get("a");
    EXPECT_EQ(hit.cache, "hit");
    EXPECT_EQ(hit.units, built.units);
    EXPECT_EQ(hit.unit_new_line_rays, built.unit_new_line_rays);
    EXPECT_EQ(hit.tile_line_start, built.tile_line_start);
    EXPECT_EQ(hit.tile_lines, built.tile_lines);
    EXPECT_EQ(hit.tile_line_info, built.tile_line_info);
    EXPECT_EQ(hit.tile_rays, built.tile_rays);
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir)) files.push_back(e.path());
    ASSERT_EQ(files.size(), 1u);
    const fs::path entry = files[0];
    auto bytes = [](const fs::path& f) { return test::read_file_bytes(f); };
    auto put = [](const fs::path& f, const std::string& s) { test::write_file_bytes(f, s); };
    test::expect_damaged_entry_rebuilt(entry, [&] { return get("a").cache; });
    // Another key's valid entry under this key's name.
    get("b");
    std::string other;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path() != entry) other = bytes(e.path());
    ASSERT_FALSE(other.empty());
    put(entry, other);
    EXPECT_EQ(get("a").cache, "rebuilt: key mismatch");
    EXPECT_EQ(get("a").cache, "hit");
    fs::remove_all(dir);
}

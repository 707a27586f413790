// End-to-end: the rtsim binary as a user runs it.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <fmt/format.h>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <set>
#include <sstream>

#include "support/run_rtsim.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using rtsim::test::expect_one_line_error;
using rtsim::test::Result;
using rtsim::test::run_rtsim;
using rtsim::test::slurp;
using rtsim::test::work_dir;

// Every run's stats; each must show that no block was asked about a cycle behind its time floor
// (the cores' promise that lets calendars forget the past).
json stats_of(const fs::path& dir) {
    json s = json::parse(slurp(dir / "stats.json"));
    if (s.contains("counters")) {
        EXPECT_EQ(s["counters"].value("sim.late_requests", uint64_t(1)), 0u) << dir;
    }
    // Every ray-slot cycle is charged to exactly one cause or counted as no work.
    if (s.contains("stalls")) {
        EXPECT_EQ(s["stalls"]["total"].value("unaccounted_cycles", int64_t(1)), 0) << dir;
    }
    // Where the fast model claims exact order it has it: a private L1 serves its core's
    // lookups and misses in time order (they follow the core's in-order issue port), except in
    // treelet mode, whose treelet loads at a batch's start may precede a lookup just issued.
    if (s.contains("out_of_order") && s.value("traversal_mode", "") != "treelet") {
        EXPECT_EQ(s["out_of_order"]["l1_lookups"].get<uint64_t>(), 0u) << dir;
        EXPECT_EQ(s["out_of_order"]["l1_mshr_requests"].get<uint64_t>(), 0u) << dir;
    }
    return s;
}

// A scene file at `path`: a flattened Cornell box as the floor and an n x n grid of small
// spheres `spacing` apart above it.
fs::path spheres_on_a_floor(const fs::path& path, int n, double spacing) {
    std::ofstream(path) << fmt::format(
        R"({{"meshes": {{"c": "builtin:cornell", "s": "builtin:sphere"}},
            "instances": [{{"mesh": "c", "scale": [1, 0.2, 1]}},
                          {{"mesh": "s", "scale": 0.1, "grid": {{"count": [{0}, 1, {0}],
                           "spacing": [{1}, 0, {1}]}}, "translate": [-0.3, 0.3, -0.3]}}]}})",
        n, spacing);
    return path;
}

// A trace's per-kind field (trace-info --json's by_kind), summed over ray kinds.
uint64_t trace_kind_total(const fs::path& rtt, const char* field) {
    const Result ti = run_rtsim("trace-info --json '" + rtt.string() + "'");
    EXPECT_EQ(ti.status, 0) << ti.err;
    uint64_t total = 0;
    const json info = json::parse(ti.out);
    for (const auto& [kind, k] : info["by_kind"].items()) total += k.value(field, uint64_t(0));
    return total;
}

// Operations of every unit of a kind (`transform_unit`): the sum of its counters `kind[i].ops`.
uint64_t unit_ops(const json& stats, const std::string& kind) {
    uint64_t ops = 0;
    for (const auto& [name, v] : stats["counters"].items())
        if (name.rfind(kind + "[", 0) == 0 && name.find(".ops") != std::string::npos)
            ops += v.get<uint64_t>();
    return ops;
}

// The fields item 7 of the foundation issue promises.
void expect_complete_stats(const json& s) {
    for (const char* k : {"config", "config_hash", "scene", "bvh", "rays", "total_cycles",
                          "rays_per_second", "units", "caches", "bandwidth", "counters", "host"})
        ASSERT_TRUE(s.contains(k)) << k;
    EXPECT_GT(s["total_cycles"].get<uint64_t>(), 0u);
    EXPECT_GT(s["rays"]["total"].get<uint64_t>(), 0u);
    EXPECT_GT(s["rays_per_second"].get<double>(), 0.0);
    for (const char* u : {"box_unit[0]", "triangle_unit[0]", "box_unit_total"}) {
        ASSERT_TRUE(s["units"].contains(u)) << u;
        const double util = s["units"][u]["utilization"];
        EXPECT_GT(util, 0.0);
        EXPECT_LE(util, 1.0);
        EXPECT_TRUE(s["units"][u].contains("busy_cycles"));
    }
    for (const char* c : {"l1[0]", "l1_total", "l2"})
        for (const char* f : {"accesses", "hits", "misses", "hit_rate"})
            ASSERT_TRUE(s["caches"][c].contains(f)) << c << f;
    for (const char* l : {"l1", "l2", "dram"}) {
        EXPECT_GT(s["bandwidth"][l]["bytes"].get<uint64_t>(), 0u) << l;
        EXPECT_GT(s["bandwidth"][l]["gbps"].get<double>(), 0.0) << l;
    }
    EXPECT_GT(s["host"]["run_time_s"].get<double>(), 0.0);
    EXPECT_GT(s["host"]["simulated_rays_per_host_second"].get<double>(), 0.0);
}

json without_host(json s) {
    s.erase("host");
    return s;
}

}  // namespace

TEST(Run, DefaultSceneWritesCompleteStats) {
    const fs::path out = work_dir() / "default";
    const Result r = run_rtsim(fmt::format("run --out '{}'", out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    expect_complete_stats(s);
    EXPECT_EQ(s["scene"]["name"], "builtin:cornell");
    EXPECT_EQ(s["rays"]["by_kind"]["primary"].get<uint64_t>(), 128u * 128u);
    EXPECT_NE(r.out.find("Mrays/s"), std::string::npos);
    EXPECT_TRUE(r.err.empty()) << r.err;  // no banner, no progress when not on a terminal
}

TEST(Run, Glmark2BunnyWithSecondaryRays) {
    ASSERT_TRUE(fs::exists(RTSIM_BUNNY_OBJ)) << "run scripts/setup.sh";
    const fs::path out = work_dir() / "bunny";
    const Result r =
        run_rtsim(fmt::format("run --scene {} --rays primary,shadow,ao --res 64x64 --out '{}'",
                              RTSIM_BUNNY_OBJ, out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    expect_complete_stats(s);
    EXPECT_EQ(s["scene"]["triangles"].get<uint64_t>(), 69666u);
    EXPECT_GT(s["rays"]["by_kind"]["ao"].get<uint64_t>(), 0u);
    EXPECT_GT(s["rays"]["by_kind"]["shadow"].get<uint64_t>(), 0u);
}

TEST(Run, SameInputsGiveIdenticalSimulatedStats) {
    const std::string args = "run --rays primary,ao --res 48x48 --seed 7 --set core.count=3";
    const fs::path a = work_dir() / "a", b = work_dir() / "b", c = work_dir() / "c";
    ASSERT_EQ(run_rtsim(args + " --out '" + a.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(args + " --out '" + b.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim("run --rays primary,ao --res 48x48 --seed 8 --set core.count=3 --out '" +
                        c.string() + "'")
                  .status,
              0);
    const json sa = stats_of(a), sb = stats_of(b), sc = stats_of(c);
    EXPECT_EQ(without_host(sa), without_host(sb));
    // A different seed changes the AO rays, and so the simulated result.
    EXPECT_NE(sa["total_cycles"], sc["total_cycles"]);
}

// Tiles generated and traced on several threads hand on the same stream: every simulated figure
// is the one thread's, in a sampled run (which also reads each ray's steps and id for its
// auxiliaries and hit records) and in packet mode (whose packets end at batch edges).
TEST(Run, AnyTracerThreadCountGivesIdenticalStats) {
    const std::string common = "run -q --rays primary,ao,diffuse --diffuse-depth 2 --res 96x64 ";
    for (const std::string extra : {"--set sim.sampled=true --set sim.sample_unit_rays=128 "
                                    "--set core.hit_record_bytes=16",
                                    "--set traversal.mode=packet"}) {
        const fs::path a = work_dir() / "one", b = work_dir() / "three";
        ASSERT_EQ(run_rtsim(common + extra + " -o '" + a.string() + "'").status, 0);
        ASSERT_EQ(run_rtsim(common + extra + " --tracer-threads 3 -o '" + b.string() + "'").status,
                  0);
        EXPECT_EQ(without_host(stats_of(a)), without_host(stats_of(b))) << extra;
        fs::remove_all(a);
        fs::remove_all(b);
    }
    EXPECT_EQ(run_rtsim("run --tracer-threads 0").status, 2);
}

TEST(Run, LargeWorkingSetDramBytesEqualL2MissesTimesLine) {
    // Caches far smaller than the bunny's 5.5 MiB BVH: every L2 miss is one line from DRAM,
    // and every L1 miss is one L2 access.
    ASSERT_TRUE(fs::exists(RTSIM_BUNNY_OBJ));
    const fs::path out = work_dir() / "tiny";
    const Result r = run_rtsim(
        fmt::format("run --scene {} --rays ao --res 64x64 --set l1.size_kib=1 --set l1.ways=2 "
                    "--set l2.size_kib=16 --set l2.line_bytes=128 --out '{}'",
                    RTSIM_BUNNY_OBJ, out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    const uint64_t l2_misses = s["caches"]["l2"]["misses"], l2_acc = s["caches"]["l2"]["accesses"];
    EXPECT_GT(l2_misses, 10000u);
    EXPECT_EQ(s["bandwidth"]["dram"]["bytes"].get<uint64_t>(), l2_misses * 128);
    EXPECT_EQ(l2_acc, s["caches"]["l1_total"]["misses"].get<uint64_t>());
    EXPECT_EQ(s["bandwidth"]["l2"]["bytes"].get<uint64_t>(),
              s["caches"]["l1_total"]["misses"].get<uint64_t>() * 64);
}

// Shared state served out of simulated-time order is counted, not hidden: on 64 cores x 32 slots
// (transfers booked when issued) with L2 MSHRs starved to 8, stack spills and hit records
// written back from a 64 KiB L2, and one DRAM bank, requests from many cores reach the L2's
// lookups and MSHRs and the DRAM out of order.
TEST(Run, OutOfOrderServiceIsCountedWhereItHappens) {
    const fs::path out = work_dir() / "ooo";
    const Result r = run_rtsim(fmt::format(
        "run -q --config {}/configs/write_traffic.json --scene {} --rays primary,ao --res 48x48 "
        "--set l1.size_kib=4 --set l2.size_kib=64 --set core.count=64 --set core.ray_slots=32 "
        "--set l2.mshrs=8 --set dram.channels=1 --set dram.banks=1 --out '{}'",
        RTSIM_SOURCE_DIR, RTSIM_BUNNY_OBJ, out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    const json& o = s["out_of_order"];
    EXPECT_GT(o["l2_lookups"].get<uint64_t>(), 0u);
    EXPECT_GT(o["l2_mshr_requests"].get<uint64_t>(), 0u);
    EXPECT_GT(o["dram_requests"].get<uint64_t>(), 0u);
    EXPECT_LE(o["l2_lookups"].get<uint64_t>(), s["caches"]["l2"]["accesses"].get<uint64_t>());
    EXPECT_EQ(o["l2_lookups"], s["counters"]["l2.lookup_out_of_order"]);
}

TEST(Run, BiggerCachesNeverMoveMoreDramBytes) {
    const fs::path small = work_dir() / "small", big = work_dir() / "big";
    ASSERT_EQ(
        run_rtsim("run --res 64x64 --set l2.size_kib=64 --out '" + small.string() + "'").status, 0);
    ASSERT_EQ(
        run_rtsim("run --res 64x64 --set l2.size_kib=4096 --out '" + big.string() + "'").status, 0);
    EXPECT_LT(stats_of(big)["bandwidth"]["dram"]["bytes"].get<uint64_t>(),
              stats_of(small)["bandwidth"]["dram"]["bytes"].get<uint64_t>());
}

// A reduced-precision box unit finds the same hits (conservative rounding) with more
// box and triangle operations, and the trace it records carries its width.
TEST(Run, ReducedPrecisionBoxUnitsKeepHitsAndAddWork) {
    const fs::path full = work_dir() / "fp32", narrow = work_dir() / "box6b";
    const std::string common = "run --scene builtin:sphere --rays primary,diffuse --res 32x32 ";
    ASSERT_EQ(run_rtsim(common + "-o '" + full.string() + "'").status, 0);
    ASSERT_EQ(
        run_rtsim(common + "--set box_unit.mantissa_bits=6 -o '" + narrow.string() + "'").status,
        0);
    const json f = stats_of(full), n = stats_of(narrow);
    EXPECT_EQ(n["bvh"]["box_mantissa_bits"], 6);
    EXPECT_EQ(f["bvh"]["box_mantissa_bits"], 23);
    EXPECT_EQ(f["rays"]["hits_by_kind"], n["rays"]["hits_by_kind"]);
    EXPECT_GT(n["units"]["box_unit_total"]["ops"].get<uint64_t>(),
              f["units"]["box_unit_total"]["ops"].get<uint64_t>());
    EXPECT_GT(n["units"]["triangle_unit_total"]["ops"].get<uint64_t>(),
              f["units"]["triangle_unit_total"]["ops"].get<uint64_t>());
    expect_one_line_error(run_rtsim(common + "--set box_unit.mantissa_bits=30"),
                          "box_unit.mantissa_bits");
}

// Found by fuzz_mesh: a damaged 219-byte PLY header on which assimp 5.2.5's reader never returns.
// The watchdog ends the read with a one-line error naming the file, exit 2, and no output.
TEST(Run, AMeshReaderThatHangsIsStoppedWithOneLine) {
    const std::string ply = std::string(RTSIM_SOURCE_DIR) + "/tests/data/assimp_hang.ply";
    const fs::path out = work_dir() / "hang";
    setenv("RTSIM_IMPORT_TIMEOUT_S", "1", 1);
    const Result r = run_rtsim("run --scene '" + ply + "' -o '" + out.string() + "'");
    unsetenv("RTSIM_IMPORT_TIMEOUT_S");
    expect_one_line_error(r, ply + ": the mesh reader (assimp) did not finish in 1 s");
    EXPECT_FALSE(fs::exists(out));
}

// A mesh file is parsed once and later runs load it from the cache beside the BVHs,
// simulating exactly what a run that parsed it does.
TEST(Run, TheMeshCacheServesLaterRunsTheSameScene) {
    ASSERT_TRUE(fs::exists(RTSIM_BUNNY_OBJ)) << "run scripts/setup.sh";
    const fs::path cache = work_dir() / "mesh_cache";
    fs::remove_all(cache);
    auto run = [&](const std::string& cache_arg, const char* name) {
        const fs::path out = work_dir() / name;
        EXPECT_EQ(run_rtsim(fmt::format("run --scene '{}' --rays primary --res 16x16 --bvh-cache "
                                        "'{}' -o '{}'",
                                        RTSIM_BUNNY_OBJ, cache_arg, out.string()))
                      .status,
                  0);
        return stats_of(out);
    };
    const json a = run(cache.string(), "mesh_a"), b = run(cache.string(), "mesh_b"),
               c = run("off", "mesh_c");
    EXPECT_EQ(a["host"]["mesh_cache"], "built");
    EXPECT_EQ(b["host"]["mesh_cache"], "hit");
    EXPECT_EQ(c["host"]["mesh_cache"], "off");
    EXPECT_EQ(without_host(a), without_host(b));
    EXPECT_EQ(without_host(a), without_host(c));
}

// A scene's BVH is built once per scene content and settings and reused from the cache;
// a run from the cache simulates exactly what a run that built it does.
TEST(Run, TheBvhCacheServesLaterRunsTheSameTree) {
    const fs::path cache = work_dir() / "bvh_cache";
    fs::remove_all(cache);
    const std::string common =
        "run --scene builtin:sphere --rays primary,ao --res 32x32 "
        "--set bvh.width=4 --bvh-cache '" +
        cache.string() + "' ";
    const fs::path a = work_dir() / "cache_a", b = work_dir() / "cache_b",
                   c = work_dir() / "cache_c";
    ASSERT_EQ(run_rtsim(common + "-o '" + a.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(common + "-o '" + b.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim("run --scene builtin:sphere --rays primary,ao --res 32x32 --set "
                        "bvh.width=4 --bvh-cache off -o '" +
                        c.string() + "'")
                  .status,
              0);
    const json sa = stats_of(a), sb = stats_of(b), sc = stats_of(c);
    EXPECT_EQ(sa["host"]["bvh_cache"], "built");
    EXPECT_EQ(sb["host"]["bvh_cache"], "hit");
    EXPECT_EQ(sc["host"]["bvh_cache"], "off");
    EXPECT_EQ(without_host(sa), without_host(sb));
    EXPECT_EQ(without_host(sa), without_host(sc));
    // Another BVH setting is another entry.
    const fs::path d = work_dir() / "cache_d";
    ASSERT_EQ(run_rtsim(common + "--set bvh.max_leaf_size=2 -o '" + d.string() + "'").status, 0);
    EXPECT_EQ(stats_of(d)["host"]["bvh_cache"], "built");
    size_t entries = 0;
    for (const auto& e : fs::directory_iterator(cache)) entries += e.path().extension() == ".bvh";
    EXPECT_EQ(entries, 2u);
}

// Sampled simulation. Measuring every unit fast-forwards nothing, so the sampled run
// is the full run itself (the sampler only watches), and its estimate of the frame's cycles is
// within a unit's hand-out granularity of what that run measured.
// A sampled run's counters less the one it adds, l2.first_fills: the L2's misses on BVH lines it
// never held, which on a run that starts cold and measures everything are the frame's distinct
// lines as the ray stream's own line count found them (sampling.new_lines).
namespace {
json counters_less_first_fills(const json& sampled) {
    json c = sampled["counters"];
    EXPECT_EQ(c.value("l2.first_fills", 0.0), sampled["sampling"]["new_lines"].get<double>());
    EXPECT_GT(c.value("l2.first_fills", 0.0), 0.0);
    c.erase("l2.first_fills");
    return c;
}
}  // namespace

TEST(Sampled, MeasuringEveryUnitIsTheFullRun) {
    const std::string common = "run --scene builtin:sphere --rays primary,ao --res 48x48 ";
    const fs::path full = work_dir() / "s_full", all = work_dir() / "s_all";
    ASSERT_EQ(run_rtsim(common + "-o '" + full.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(common +
                        "--set sim.sampled=true --set sim.sample_period_units=1 "
                        "--set sim.sample_unit_rays=256 -o '" +
                        all.string() + "'")
                  .status,
              0);
    const json f = stats_of(full), a = stats_of(all);
    const json& sm = a["sampling"];
    EXPECT_EQ(sm["detailed_share"], 1.0);
    EXPECT_EQ(sm["simulated_cycles"], f["total_cycles"]);
    EXPECT_EQ(counters_less_first_fills(a), f["counters"]);  // nothing perturbed
    const double est = sm["total_cycles"]["value"].get<double>();
    const double truth = f["total_cycles"].get<double>();
    EXPECT_NEAR(est, truth, 0.01 * truth);
    // Everything measured: the finite-population correction leaves no interval.
    EXPECT_NEAR(sm["total_cycles"]["half_width_pct"].get<double>(), 0.0, 1e-9);
    EXPECT_NEAR(sm["counters"]["dram.bytes"]["value"].get<double>(),
                f["counters"]["dram.bytes"].get<double>(),
                0.02 * f["counters"]["dram.bytes"].get<double>());
}

// The full run's count of `suffix` over blocks whose names start with one of `prefixes`, and a
// sampled run's estimates of the same counters summed.
namespace {

std::pair<double, double> full_and_estimated(const json& full, const json& sampled,
                                             const std::vector<std::string>& prefixes,
                                             const std::string& suffix) {
    double f = 0, e = 0;
    for (const auto& [name, v] : full["counters"].items())
        for (const std::string& p : prefixes)
            if (name.rfind(p, 0) == 0 && name.size() > suffix.size() &&
                name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
                f += v.get<double>();
                if (sampled["sampling"]["counters"].contains(name))
                    e += sampled["sampling"]["counters"][name]["value"].get<double>();
            }
    return {f, e};
}

}  // namespace

// One unit in five measured: most rays never reach a core, the run is deterministic for a seed,
// another seed measures other units, and on this frame the intervals hold the full run's figures
// (a 95% interval may miss; this seed and frame were checked not to, against the full run).
TEST(Sampled, SampleOfTheFrameEstimatesItsTotals) {
    const std::string common =
        "run --scene " RTSIM_BUNNY_OBJ " --rays primary,ao,diffuse --res 96x96 ";
    const std::string sampled =
        "--set sim.sampled=true --set sim.sample_design=systematic "
        "--set sim.sample_period_units=5 --set sim.sample_unit_rays=256 "
        "--set sim.sample_warmup_rays=128 ";
    const fs::path full = work_dir() / "f", a = work_dir() / "a", b = work_dir() / "b",
                   c = work_dir() / "c";
    ASSERT_EQ(run_rtsim(common + "-o '" + full.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(common + sampled + "-o '" + a.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(common + sampled + "-o '" + b.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(common + sampled + "--seed 2 -o '" + c.string() + "'").status, 0);
    const fs::path d = work_dir() / "d";
    ASSERT_EQ(run_rtsim(common + sampled + "--seed 3 -o '" + d.string() + "'").status, 0);
    const json f = stats_of(full), sa = stats_of(a), sb = stats_of(b), sc = stats_of(c);
    EXPECT_EQ(without_host(sa), without_host(sb));
    const json& sm = sa["sampling"];
    EXPECT_LT(sm["detailed_share"].get<double>(), 0.5);
    EXPECT_GE(sm["units_measured"].get<int>(), 5);
    EXPECT_EQ(sa["rays"], f["rays"]);  // every ray is counted, detailed or not
    // Other seeds start the sample at other units (two of three differ at least).
    const json sd = stats_of(d)["sampling"];
    EXPECT_FALSE(sc["sampling"]["first_unit"] == sm["first_unit"] &&
                 sd["first_unit"] == sm["first_unit"]);
    auto holds = [&](const json& e, double truth) {
        return e["lo"].get<double>() <= truth && truth <= e["hi"].get<double>();
    };
    EXPECT_TRUE(holds(sm["total_cycles"], f["total_cycles"].get<double>())) << sm["total_cycles"];
    EXPECT_TRUE(holds(sm["counters"]["dram.bytes"], f["counters"]["dram.bytes"].get<double>()))
        << sm["counters"]["dram.bytes"];
    EXPECT_EQ(sa["total_cycles"].get<double>(),
              std::llround(sm["total_cycles"]["value"].get<double>()));
    // Derived figures carry intervals too: the full run's L1 and L2 hit rates and box-unit
    // utilisation fall in them here.
    const json& fig = sm["figures"];
    EXPECT_TRUE(holds(fig["l1_hit_rate"], f["caches"]["l1_total"]["hit_rate"].get<double>()))
        << fig["l1_hit_rate"];
    EXPECT_TRUE(holds(fig["l2_hit_rate"], f["caches"]["l2"]["hit_rate"].get<double>()))
        << fig["l2_hit_rate"];
    EXPECT_TRUE(holds(fig["box_unit_utilization"],
                      f["units"]["box_unit_total"]["utilization"].get<double>()))
        << fig["box_unit_utilization"];
    EXPECT_TRUE(holds(fig["rays_per_second"], f["rays_per_second"].get<double>()))
        << fig["rays_per_second"];
    EXPECT_TRUE(fig["stall_shares"].contains("l1"));
    // Energy too (sim/energy.h): its value is the energy section's, from the counters'
    // estimates; its interval, from their joint jackknife, holds the full run's here.
    const json& se = sm["energy"];
    for (const char* figure : {"total_pj", "per_ray_nj", "average_power_w"}) {
        EXPECT_EQ(se[figure]["value"], sa["energy"][figure]) << figure;
        EXPECT_GT(se[figure]["half_width_pct"].get<double>(), 0.0) << figure;
        EXPECT_TRUE(holds(se[figure], f["energy"][figure].get<double>()))
            << figure << " " << se[figure] << " full " << f["energy"][figure];
    }
    // Box and triangle operations are the rays' node and triangle steps, known for the whole
    // frame: their estimates sum to the full run's counts.
    for (const auto& [prefixes, suffix] :
         std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"box_unit["}, ".ops"},
             {{"triangle_unit["}, ".ops"},
             {{"l1[", "l1_tri["}, ".accesses"}}) {
        const auto [full_count, estimated] = full_and_estimated(f, sa, prefixes, suffix);
        EXPECT_GT(full_count, 0) << suffix;
        EXPECT_NEAR(estimated, full_count, 1e-9 * full_count) << prefixes[0] << suffix;
    }
    EXPECT_NEAR(se["blocks_pj"]["box_unit"]["value"].get<double>(),
                f["energy"]["blocks_pj"]["box_unit"].get<double>(),
                1e-9 * f["energy"]["blocks_pj"]["box_unit"].get<double>());
    EXPECT_LT(se["blocks_pj"]["box_unit"]["half_width_pct"].get<double>(), 1e-6);
    // compare shows a sampled run's estimates with their intervals.
    const Result cmp = run_rtsim("compare '" + full.string() + "' '" + a.string() + "'");
    ASSERT_EQ(cmp.status, 0) << cmp.err;
    const size_t row = cmp.out.find("\ncycles ");
    ASSERT_NE(row, std::string::npos) << cmp.out;
    const std::string line = cmp.out.substr(row + 1, cmp.out.find('\n', row + 1) - row - 1);
    EXPECT_NE(
        line.find(fmt::format("+-{:.1f}%", sm["total_cycles"]["half_width_pct"].get<double>())),
        std::string::npos)
        << line;
    EXPECT_NE(cmp.out.find("95% interval"), std::string::npos);
    const size_t energy_row = cmp.out.find("\nenergy per ray (nJ) ");
    ASSERT_NE(energy_row, std::string::npos) << cmp.out;
    const std::string energy_line =
        cmp.out.substr(energy_row + 1, cmp.out.find('\n', energy_row + 1) - energy_row - 1);
    EXPECT_NE(energy_line.find(
                  fmt::format("+-{:.1f}%", se["per_ray_nj"]["half_width_pct"].get<double>())),
              std::string::npos)
        << energy_line;
}

// --target-error: a pilot of the whole frame sizes the sample; the intervals of the frame's
// cycles and DRAM bytes then come within the target, and a looser target measures less. (A
// 96x96 frame's 106 units are too few: its 10% plan needs most of them, and runs in full.)
TEST(Sampled, TargetErrorIsHonoured) {
    const std::string common = "run --scene " RTSIM_BUNNY_OBJ
                               " --rays primary,ao --res 192x192 --set sim.sampled=true "
                               "--set sim.sample_unit_rays=128 --set sim.sample_period_units=8 ";
    const fs::path loose = work_dir() / "loose", tight = work_dir() / "tight";
    ASSERT_EQ(run_rtsim(common + "--target-error 40 -o '" + loose.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(common + "--target-error 10 -o '" + tight.string() + "'").status, 0);
    const json l = stats_of(loose)["sampling"], t = stats_of(tight)["sampling"];
    for (const json* s : {&l, &t}) {
        const double target = (*s)["target"]["target_error_pct"].get<double>();
        EXPECT_TRUE((*s)["target"]["met"].get<bool>()) << (*s)["target"];
        EXPECT_LE((*s)["total_cycles"]["half_width_pct"].get<double>(), target);
        EXPECT_LE((*s)["counters"]["dram.bytes"]["half_width_pct"].get<double>(), target);
    }
    EXPECT_GT(l["target"]["period_units"].get<int>(), t["target"]["period_units"].get<int>());
    EXPECT_LT(l["detailed_share"].get<double>(), t["detailed_share"].get<double>());
    expect_one_line_error(run_rtsim("run --res 16x16 --target-error 5"),
                          "--target-error: needs a sampled run");
}

// sim.sample_first_unit fixes the systematic sample: the period's starts measure disjoint units
// that together are every unit of the frame (so running every start enumerates every sample the
// design can draw, which bench_sampled.py uses for the intervals' exact coverage).
TEST(Sampled, EveryStartTogetherMeasuresTheFrameOnce) {
    const std::string common =
        "run --scene builtin:sphere --rays primary --res 48x48 --set sim.sampled=true "
        "--set sim.sample_design=systematic --set sim.sample_unit_rays=256 "
        "--set sim.sample_period_units=3 ";
    uint64_t measured = 0, units = 0;
    for (int start = 0; start < 3; ++start) {
        const fs::path out = work_dir() / ("start" + std::to_string(start));
        ASSERT_EQ(run_rtsim(common + "--set sim.sample_first_unit=" + std::to_string(start) +
                            " -o '" + out.string() + "'")
                      .status,
                  0);
        const json sm = stats_of(out)["sampling"];
        EXPECT_EQ(sm["first_unit"].get<int>(), start);
        measured += sm["units_measured"].get<uint64_t>();
        units = sm["units"].get<uint64_t>();
    }
    EXPECT_EQ(units, 48u * 48u / 256u);  // 2304 rays in units of 256
    EXPECT_EQ(measured, units);
    expect_one_line_error(run_rtsim(common + "--set sim.sample_first_unit=3"),
                          "sim.sample_first_unit: expected -1 or below sim.sample_period_units "
                          "(3), got 3");
}

// The stratified design (the default) measures exactly one unit in each run of
// sample_period_units; the draw is the same for a seed and another for another seed, on the
// same frame (sim.sample_seed leaves the rays alone).
TEST(Sampled, StratifiedDesignDrawsOneUnitPerPeriod) {
    const std::string common =
        "run --scene builtin:sphere --rays primary,ao --res 48x48 --set sim.sampled=true "
        "--set sim.sample_unit_rays=256 --set sim.sample_period_units=3 ";
    std::set<int> firsts;
    json first_run;
    for (int seed = 1; seed <= 6; ++seed) {
        const fs::path out = work_dir() / ("strat" + std::to_string(seed));
        ASSERT_EQ(run_rtsim(common + "--set sim.sample_seed=" + std::to_string(seed) + " -o '" +
                            out.string() + "'")
                      .status,
                  0);
        const json s = stats_of(out);
        const json& sm = s["sampling"];
        EXPECT_EQ(sm["design"], "stratified");
        const uint64_t units = sm["units"].get<uint64_t>();
        // One per full period, and one more if the last, partial period's draw fell in it.
        EXPECT_GE(sm["units_measured"].get<uint64_t>(), units / 3);
        EXPECT_LE(sm["units_measured"].get<uint64_t>(), (units + 2) / 3);
        firsts.insert(sm["first_unit"].get<int>());
        if (seed == 1) first_run = s;
        EXPECT_EQ(s["rays"], first_run["rays"]);  // the same frame
    }
    EXPECT_GT(firsts.size(), 1u);
    const fs::path again = work_dir() / "strat1_again";
    ASSERT_EQ(run_rtsim(common + "--set sim.sample_seed=1 -o '" + again.string() + "'").status, 0);
    EXPECT_EQ(without_host(stats_of(again)), without_host(first_run));
    expect_one_line_error(run_rtsim(common + "--set sim.sample_first_unit=1"),
                          "sim.sample_first_unit: only a systematic sample has a first unit");
}

TEST(Sampled, TreeletModeIsRefusedForNow) {
    expect_one_line_error(run_rtsim("run --config '" + std::string(RTSIM_SOURCE_DIR) +
                                    "/configs/treelet.json' --set sim.sampled=true"),
                          "sim.sampled: not yet with traversal.mode=treelet");
}

namespace {
// A sampled_units.csv: its header, and its columns by name, one value per row.
struct UnitsCsv {
    std::vector<std::string> header;
    std::map<std::string, std::vector<double>> cols;
};
UnitsCsv read_units_csv(const fs::path& path) {
    std::ifstream csv(path);
    std::string line, cell;
    UnitsCsv out;
    std::getline(csv, line);
    for (std::stringstream ss(line); std::getline(ss, cell, ',');) out.header.push_back(cell);
    while (std::getline(csv, line)) {
        size_t c = 0;
        for (std::stringstream ss(line); std::getline(ss, cell, ',') && c < out.header.size();)
            out.cols[out.header[c++]].push_back(std::stod(cell));
    }
    return out;
}
double column_sum(const UnitsCsv& csv, const std::string& name) {
    const auto& v = csv.cols.at(name);
    return std::accumulate(v.begin(), v.end(), 0.0);
}

// Runs `common` (an `rtsim run` command line) in full, and again as a skip run that measures
// every unit of 2 tiles: the two stats.json, full first (null when a run failed).
std::pair<json, json> full_and_every_unit_run(const std::string& common, const std::string& name) {
    const fs::path full = work_dir() / (name + "_full"), all = work_dir() / (name + "_all");
    const Result f = run_rtsim(common + "-o '" + full.string() + "'");
    EXPECT_EQ(f.status, 0) << f.err;
    const Result r = run_rtsim(common +
                               "--set sim.sampled=true --set sim.sample_fast_forward=skip "
                               "--set sim.sample_period_units=1 --set sim.sample_unit_tiles=2 "
                               "--bvh-cache off -o '" +
                               all.string() + "'");
    EXPECT_EQ(r.status, 0) << r.err;
    if (f.status != 0 || r.status != 0) return {};  // null: the caller stops
    return {stats_of(full), stats_of(all)};
}

// Runs `frame` (an `rtsim run` command line) in full and as a 1-in-4 sample of the work design
// (units of one tile), and checks that the sample's interval holds the full run's cycles.
void expect_work_sample_holds_the_full_run(const std::string& frame, const std::string& name) {
    const fs::path truth_dir = work_dir() / (name + "_full"), sample_dir = work_dir() / name;
    ASSERT_EQ(run_rtsim(frame + "-o '" + truth_dir.string() + "'").status, 0);
    const Result s = run_rtsim(frame +
                               "--set sim.sampled=true --set sim.sample_fast_forward=skip "
                               "--set sim.sample_design=work --set sim.sample_period_units=4 "
                               "--set sim.sample_unit_tiles=1 -o '" +
                               sample_dir.string() + "'");
    ASSERT_EQ(s.status, 0) << s.err;
    const json sampled = stats_of(sample_dir);
    const json& est = sampled["sampling"]["total_cycles"];
    const double truth = stats_of(truth_dir)["total_cycles"].get<double>();
    ASSERT_TRUE(est["lo"].is_number()) << est.dump();
    EXPECT_LT(sampled["sampling"]["units_measured"].get<double>(),
              sampled["sampling"]["units"].get<double>());
    EXPECT_LE(est["lo"].get<double>(), truth) << est.dump();
    EXPECT_GE(est["hi"].get<double>(), truth) << est.dump();
}
}  // namespace

// The skip design (sim.sample_fast_forward = skip) with every unit measured traces every tile and
// skips none: the run is the full run, and the estimates are what it measured.
TEST(Sampled, SkipDesignMeasuringEveryUnitIsTheFullRun) {
    const std::string common = "run --scene builtin:sphere --rays primary,ao --res 48x48 ";
    const fs::path all = work_dir() / "k_all";
    const auto [f, a] = full_and_every_unit_run(common, "k");
    ASSERT_FALSE(f.is_null() || a.is_null());
    const json& sm = a["sampling"];
    EXPECT_EQ(sm["units"], 18);  // 6 x 6 tiles
    EXPECT_EQ(sm["units_measured"], 18);
    EXPECT_EQ(sm["simulated_cycles"], f["total_cycles"]);
    EXPECT_EQ(counters_less_first_fills(a), f["counters"]);
    EXPECT_EQ(a["rays"]["total"], f["rays"]["total"]);
    EXPECT_EQ(sm["profile"]["cache"], "off");
    const double truth = f["total_cycles"].get<double>();
    EXPECT_NEAR(sm["total_cycles"]["value"].get<double>(), truth, 1e-4 * truth);
    EXPECT_NEAR(sm["counters"]["dram.bytes"]["value"].get<double>(),
                f["counters"]["dram.bytes"].get<double>(), 1e-9);

    // sampled_units.csv: a row per unit whose columns add up to the full run's figures (cycles
    // with the drain after the last hand-out; like blocks' counters summed into one column).
    const UnitsCsv csv = read_units_csv(all / "sampled_units.csv");
    ASSERT_GE(csv.header.size(), 6u);
    EXPECT_EQ(
        std::vector<std::string>(csv.header.begin(), csv.header.begin() + 6),
        (std::vector<std::string>{"unit", "work", "new_lines", "node_steps", "rays", "cycles"}));
    // 18 rows, every one with every column.
    ASSERT_EQ(csv.cols.size(), csv.header.size());
    for (const auto& [name, values] : csv.cols) EXPECT_EQ(values.size(), 18u) << name;
    EXPECT_EQ(column_sum(csv, "cycles") + sm["drain_cycles"].get<double>(), truth);
    EXPECT_EQ(column_sum(csv, "rays"), f["rays"]["total"].get<double>());
    EXPECT_EQ(column_sum(csv, "dram.bytes"), f["counters"]["dram.bytes"].get<double>());
    double l1_hits = 0;
    for (const auto& [name, v] : f["counters"].items())
        if (name.rfind("l1[", 0) == 0 && name.find(".hits") != std::string::npos)
            l1_hits += v.get<double>();
    EXPECT_GT(l1_hits, 0);
    EXPECT_EQ(column_sum(csv, "l1.hits"), l1_hits);
    // Energy from every unit's counters is the full run's, with no interval.
    const json& se = sm["energy"];
    for (const char* figure : {"total_pj", "per_ray_nj", "average_power_w"}) {
        const double want = f["energy"][figure].get<double>();
        EXPECT_NEAR(se[figure]["value"].get<double>(), want, 1e-9 * want) << figure;
        EXPECT_EQ(se[figure]["half_width_pct"].get<double>(), 0.0) << figure;
    }
    for (const auto& [block, pj] : f["energy"]["blocks_pj"].items())
        EXPECT_NEAR(se["blocks_pj"][block]["value"].get<double>(), pj.get<double>(),
                    1e-9 * pj.get<double>())
            << block;
}

// Sampling is a layer over either engine: on the time-ordered engine a skip run that measures every
// unit is that engine's full run, counter for counter, and a 1-in-4 sample of a 96x96 frame
// estimates the full run's cycles within its interval (the truth: the accurate engine's own full
// run).
TEST(Sampled, TheAccurateEngineSamplesAsTheFastOneDoes) {
    // One MSHR per L1: here the fast engine's cycles differ from the accurate engine's, so a
    // sample run on the wrong engine would show.
    const std::string chip =
        "run --scene builtin:sphere --rays primary,ao --res 48x48 --set "
        "l1.mshrs=1 --set l2.mshrs=2 ";
    const std::string common = chip + "--set sim.fidelity=accurate ";
    const auto [f, a] = full_and_every_unit_run(common, "acc");
    ASSERT_FALSE(f.is_null() || a.is_null());
    EXPECT_EQ(a["config"]["sim"]["fidelity"], "accurate");
    EXPECT_EQ(a["sampling"]["units_measured"], 18);
    EXPECT_EQ(a["sampling"]["simulated_cycles"], f["total_cycles"]);
    EXPECT_EQ(counters_less_first_fills(a), f["counters"]);
    const fs::path fast = work_dir() / "acc_fast";
    ASSERT_EQ(run_rtsim(chip + "-o '" + fast.string() + "'").status, 0);
    EXPECT_NE(stats_of(fast)["total_cycles"], f["total_cycles"]);

    expect_work_sample_holds_the_full_run("run --scene " RTSIM_BUNNY_OBJ
                                          " --rays primary,ao --res 96x96 --set "
                                          "sim.fidelity=accurate ",
                                          "acc96");
}

// The units a skip run measures take what the same units took in the full run (the run that
// measures every unit): the caches hold what they held there. Elephant primary rays at 960x544,
// where many tiles between measured units are background: when the L1 window of the replay
// counted a line at each touch, these units missed their L1s 5.3% more often than in the full
// run and took 0.9% more cycles (1.1% and 0.6% now).
TEST(Sampled, SkipDesignMeasuredUnitsTakeWhatTheyTookInTheFullRun) {
    const std::string common = "run --scene " RTSIM_CGAL_MESH_DIR
                               "/elephant.off --rays primary --res 960x544 "
                               "--set sim.sampled=true --set sim.sample_fast_forward=skip "
                               "--set sim.sample_unit_tiles=16 --set sim.sample_warmup_tiles=8 "
                               "--set sim.sample_warmup_tile_rays=512 ";
    const fs::path all = work_dir() / "mu_all", part = work_dir() / "mu_part";
    ASSERT_EQ(
        run_rtsim(common + "--set sim.sample_period_units=1 -o '" + all.string() + "'").status, 0);
    ASSERT_EQ(
        run_rtsim(common + "--set sim.sample_period_units=8 -o '" + part.string() + "'").status, 0);
    auto truth = read_units_csv(all / "sampled_units.csv").cols;
    auto sample = read_units_csv(part / "sampled_units.csv").cols;
    ASSERT_EQ(truth["unit"].size(), 510u);  // 120 x 68 tiles of 8 x 8, 16 to a unit
    ASSERT_GE(sample["unit"].size(), 60u);
    double cycles[2] = {0, 0}, l1_misses[2] = {0, 0};
    for (size_t i = 0; i < sample["unit"].size(); ++i) {
        const size_t u = size_t(sample["unit"][i]);
        ASSERT_EQ(truth["unit"][u], double(u));
        cycles[0] += sample["cycles"][i];
        cycles[1] += truth["cycles"][u];
        l1_misses[0] += sample["l1.misses"][i];
        l1_misses[1] += truth["l1.misses"][u];
    }
    EXPECT_NEAR(cycles[0] / cycles[1], 1.0, 0.01);
    EXPECT_NEAR(l1_misses[0] / l1_misses[1], 1.0, 0.03);
}

// One unit in four measured, tiles far from them never traced: the frame's rays are the
// profile's (exact), the run is deterministic and its profile is cached for the next run, and on
// this frame the intervals hold the full run's cycles and DRAM bytes (a 95% interval may miss;
// this seed and frame were checked not to, against the full run).
TEST(Sampled, SkipDesignTracesPartOfTheFrame) {
    const std::string common =
        "run --scene " RTSIM_BUNNY_OBJ " --rays primary,ao,diffuse --res 96x96 ";
    const fs::path cache = work_dir() / "k_cache";
    const std::string sampled =
        "--set sim.sampled=true --set sim.sample_fast_forward=skip "
        "--set sim.sample_design=systematic --set sim.sample_period_units=4 "
        "--set sim.sample_unit_tiles=2 --set sim.sample_warm_tiles=2 "
        "--set sim.sample_warmup_tiles=1 --set sim.sample_warmup_tile_rays=0 "
        "--set sim.sample_warmup_slot_fills=0 --set sim.sample_unit_slot_fills=0 --bvh-cache '" +
        cache.string() + "' ";
    const fs::path full = work_dir() / "kf", a = work_dir() / "ka", b = work_dir() / "kb";
    ASSERT_EQ(run_rtsim(common + "-o '" + full.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(common + sampled + "-o '" + a.string() + "'").status, 0);
    const Result rb = run_rtsim(common + sampled + "-o '" + b.string() + "'");
    ASSERT_EQ(rb.status, 0);
    json f = stats_of(full), sa = stats_of(a), sb = stats_of(b);
    // The summary gives the frame's DRAM bytes as estimated, not the detailed part's.
    const json& dram = sb["sampling"]["counters"]["dram.bytes"];
    EXPECT_NE(
        rb.out.find(fmt::format(", DRAM {:.2f} MB +- {:.1f}%", dram["value"].get<double>() / 1e6,
                                dram["half_width_pct"].get<double>())),
        std::string::npos)
        << rb.out;
    EXPECT_EQ(sa["sampling"]["profile"]["cache"], "built");
    EXPECT_EQ(sb["sampling"]["profile"]["cache"], "hit");
    for (json* s : {&sa, &sb}) (*s)["sampling"].erase("profile");
    EXPECT_EQ(without_host(sa), without_host(sb));
    const json& sm = sa["sampling"];
    EXPECT_EQ(sm["units"], 72);  // 12 x 12 tiles in units of 2
    EXPECT_EQ(sm["units_measured"], 18);
    EXPECT_LT(sm["traced_share"].get<double>(), 0.75);
    EXPECT_LT(sa["rays"]["traced"].get<uint64_t>(), f["rays"]["total"].get<uint64_t>());
    EXPECT_EQ(sa["rays"]["total"], f["rays"]["total"]);
    auto holds = [&](const json& e, double truth) {
        return e["lo"].get<double>() <= truth && truth <= e["hi"].get<double>();
    };
    EXPECT_TRUE(holds(sm["total_cycles"], f["total_cycles"].get<double>())) << sm["total_cycles"];
    EXPECT_TRUE(holds(sm["counters"]["dram.bytes"], f["counters"]["dram.bytes"].get<double>()))
        << sm["counters"]["dram.bytes"];
    // Counters that follow the rays' steps alone are the profile's totals: the full run's.
    for (const auto& [prefixes, suffix] :
         std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"box_unit["}, ".ops"},
             {{"triangle_unit["}, ".ops"},
             {{"l1[", "l1_tri["}, ".accesses"},
             {{"l1[", "l1_tri["}, ".bytes_requested"}}) {
        const auto [full_count, estimated] = full_and_estimated(f, sa, prefixes, suffix);
        EXPECT_GT(full_count, 0) << suffix;
        EXPECT_NEAR(estimated, full_count, 1e-9 * full_count) << prefixes[0] << suffix;
    }
    EXPECT_EQ(sm["functional_totals"].size(), 4u) << sm["functional_totals"];
}

// A frame whose lines outgrow the L2 (Cornell 2-bounce paths through a 128 KiB L2: most misses
// are capacity misses). The skip design counts the frame's L2 misses functionally over its
// profile (sim/sampling/functional_l2.h); checked here against the detailed model's in the full
// run, and what the estimates make of them: exact with every unit measured, and at 1 in 4 an
// interval on DRAM bytes that holds the full run's and is far narrower than a regression on work
// alone made it (+-23% on this frame and seed before; +-3.4% now).
TEST(Sampled, SkipDesignCountsCapacityMissesFunctionally) {
    const std::string common =
        "run --scene builtin:cornell --rays diffuse --diffuse-depth 2 --res 128x128 "
        "--set l2.size_kib=128 --bvh-cache off ";
    const std::string sampled =
        "--set sim.sampled=true --set sim.sample_fast_forward=skip "
        "--set sim.sample_unit_tiles=2 --set sim.sample_seed=1 ";
    const fs::path full = work_dir() / "cm_full", all = work_dir() / "cm_all",
                   part = work_dir() / "cm_part", fifo = work_dir() / "cm_fifo";
    ASSERT_EQ(run_rtsim(common + "-o '" + full.string() + "'").status, 0);
    ASSERT_EQ(
        run_rtsim(common + sampled + "--set sim.sample_period_units=1 -o '" + all.string() + "'")
            .status,
        0);
    ASSERT_EQ(
        run_rtsim(common + sampled + "--set sim.sample_period_units=4 -o '" + part.string() + "'")
            .status,
        0);
    const json f = stats_of(full), a = stats_of(all), p = stats_of(part);
    const double l2_misses = f["counters"]["l2.misses"].get<double>();
    const double dram = f["counters"]["dram.bytes"].get<double>();
    // The functional count against the detailed model (-0.8% when written).
    const json& fl2 = a["sampling"]["functional_l2"];
    EXPECT_NEAR(fl2["misses"].get<double>(), l2_misses, 0.02 * l2_misses);
    EXPECT_GT(fl2["capacity_misses"].get<double>(), 0.4 * fl2["misses"].get<double>());
    EXPECT_EQ(p["sampling"]["functional_l2"], fl2);  // the frame's, whatever the sample
    EXPECT_GT(a["host"]["functional_l2_s"].get<double>(), 0.0);
    // The replay's host seconds: a part of the simulation's where tiles are skipped; no such
    // field outside the skip design.
    EXPECT_GT(p["host"]["replay_s"].get<double>(), 0.0);
    EXPECT_LT(p["host"]["replay_s"].get<double>(), p["host"]["simulation_s"].get<double>());
    EXPECT_FALSE(f["host"].contains("replay_s"));
    // Every unit measured: the units' counts sum to the frame's, the estimate is the full run's.
    const UnitsCsv csv = read_units_csv(all / "sampled_units.csv");
    EXPECT_EQ(column_sum(csv, "functional_capacity_misses"), fl2["capacity_misses"].get<double>());
    EXPECT_NEAR(a["sampling"]["counters"]["dram.bytes"]["value"].get<double>(), dram, 1e-9 * dram);
    // 1 in 4.
    const json& d = p["sampling"]["counters"]["dram.bytes"];
    EXPECT_LE(d["lo"].get<double>(), dram) << d;
    EXPECT_GE(d["hi"].get<double>(), dram) << d;
    EXPECT_LT(d["half_width_pct"].get<double>(), 8.0) << d;
    EXPECT_EQ(p["host"]["functional_l2_cache"], "off");
    // Cached beside the profile: counted once, then read, the same figures.
    const fs::path cache = work_dir() / "cm_cache";
    std::string with_cache = common + sampled + "--set sim.sample_period_units=4 ";
    with_cache.replace(with_cache.find("--bvh-cache off"), 15,
                       "--bvh-cache '" + cache.string() + "'");
    json cached[2];
    for (int i = 0; i < 2; ++i) {
        const fs::path out = work_dir() / ("cm_cached" + std::to_string(i));
        ASSERT_EQ(run_rtsim(with_cache + "-o '" + out.string() + "'").status, 0);
        cached[i] = stats_of(out);
    }
    EXPECT_EQ(cached[0]["host"]["functional_l2_cache"], "built");
    EXPECT_EQ(cached[1]["host"]["functional_l2_cache"], "hit");
    for (json& c : cached) c["sampling"].erase("profile");
    EXPECT_EQ(cached[1]["sampling"], cached[0]["sampling"]);
    json uncached = p["sampling"];
    uncached.erase("profile");
    EXPECT_EQ(cached[0]["sampling"], uncached);
    // Another replacement policy has no functional model: no count, the regression as before.
    ASSERT_EQ(run_rtsim(common + sampled +
                        "--set sim.sample_period_units=4 --set l2.replacement=fifo -o '" +
                        fifo.string() + "'")
                  .status,
              0);
    EXPECT_FALSE(stats_of(fifo)["sampling"].contains("functional_l2"));
}

// An unpaired sampled run's units hold at least sim.sample_unit_slot_fills fills of the chip's
// ray slots. The rays per tile come from an every-unit run of 1-tile units (which keeps the
// units it is given); on 16 x 16 cores (256 slots, 4 fills: 1,024 rays) the units are the fewest
// tiles reaching that at the mean over tiles with rays, and the every-unit run's own units, the
// default chip's (64 slots) and a run with the default (0 fills) keep the configured 4 tiles.
TEST(Sampled, UnitsHoldSeveralFillsOfTheChipsSlots) {
    const std::string common = "run -q --scene " RTSIM_BUNNY_OBJ
                               " --rays primary,ao --res 96x96 --bvh-cache off "
                               "--set sim.sampled=true --set sim.sample_fast_forward=skip ";
    const fs::path tiles = work_dir() / "uf_tiles", big = work_dir() / "uf_big",
                   small = work_dir() / "uf_small", off = work_dir() / "uf_off";
    const std::string chip =
        "--set core.count=16 --set core.ray_slots=16 --set sim.sample_unit_slot_fills=4 ";
    ASSERT_EQ(run_rtsim(common + chip +
                        "--set sim.sample_unit_tiles=1 --set sim.sample_period_units=1 -o '" +
                        tiles.string() + "'")
                  .status,
              0);
    const UnitsCsv per_tile = read_units_csv(tiles / "sampled_units.csv");
    EXPECT_EQ(stats_of(tiles)["sampling"]["unit_tiles"], 1);
    double rays = 0, with_rays = 0;
    for (double r : per_tile.cols.at("rays")) {
        rays += r;
        with_rays += r > 0;
    }
    ASSERT_GT(with_rays, 0);
    const uint64_t want = uint64_t(std::ceil(1024.0 / (rays / with_rays)));
    ASSERT_GT(want, 4u);  // the premise: the rule matters here
    ASSERT_EQ(run_rtsim(common + chip + "--set sim.sample_period_units=4 -o '" + big.string() + "'")
                  .status,
              0);
    EXPECT_EQ(stats_of(big)["sampling"]["unit_tiles"].get<uint64_t>(), want);
    ASSERT_EQ(run_rtsim(common +
                        "--set sim.sample_unit_slot_fills=4 --set sim.sample_period_units=4 -o '" +
                        small.string() + "'")
                  .status,
              0);
    EXPECT_EQ(stats_of(small)["sampling"]["unit_tiles"], 4);
    ASSERT_EQ(run_rtsim(common +
                        "--set core.count=16 --set core.ray_slots=16 "
                        "--set sim.sample_period_units=4 -o '" +
                        off.string() + "'")
                  .status,
              0);
    EXPECT_EQ(stats_of(off)["sampling"]["unit_tiles"], 4);
}

// A sample whose measured units fetched nothing (seed 6 picks three background tiles of a 96x96
// bunny frame) still knows the frame's first fills: DRAM bytes and their energy are estimated,
// not left out (1080p elephant primary at 1 in 100 had reported none, and the bench read -100%).
TEST(Sampled, SkipDesignKnowsTheFirstFillsWhenNoMeasuredUnitFetched) {
    const std::string common =
        "run --scene " RTSIM_BUNNY_OBJ " --rays primary --res 96x96 --bvh-cache off ";
    const fs::path full = work_dir() / "nf_full", part = work_dir() / "nf_part";
    ASSERT_EQ(run_rtsim(common + "-o '" + full.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(common +
                        "--set sim.sampled=true --set sim.sample_fast_forward=skip "
                        "--set sim.sample_unit_tiles=1 --set sim.sample_period_units=48 "
                        "--set sim.sample_unit_slot_fills=0 --set sim.sample_seed=6 "
                        "--set sim.sample_warmup_slot_fills=2 --set sim.sample_warmup_work=false "
                        // (no window hold: held, one measured unit takes in a 64-byte fill)
                        "--set sim.sample_window_hold=none -o '" +
                        part.string() + "'")
                  .status,
              0);
    // The premise: no measured unit moved the DRAM.
    ASSERT_EQ(column_sum(read_units_csv(part / "sampled_units.csv"), "dram.bytes"), 0.0);
    const json sm = stats_of(part)["sampling"];
    const double dram = stats_of(full)["counters"]["dram.bytes"].get<double>();
    ASSERT_TRUE(sm["counters"].contains("dram.bytes")) << sm["counters"];
    const json& d = sm["counters"]["dram.bytes"];
    EXPECT_LE(d["lo"].get<double>(), dram) << d;
    EXPECT_GE(d["hi"].get<double>(), dram) << d;
    EXPECT_GT(sm["energy"]["blocks_pj"]["dram"]["value"].get<double>(), 0.0);
}

// --target-error in the skip design: the period is chosen before any tile is generated (the
// source skips by it), and the intervals come within the target. The work design: a small
// stratified sample that misses the frame's heaviest units gives no interval at all.
TEST(Sampled, SkipDesignHonoursTargetError) {
    const fs::path out = work_dir() / "k_target";
    const Result r = run_rtsim("run --scene " RTSIM_BUNNY_OBJ
                               " --rays primary,ao --res 384x384 --set sim.sampled=true "
                               "--set sim.sample_fast_forward=skip --set sim.sample_unit_tiles=2 "
                               "--set sim.sample_design=work "
                               "--set sim.sample_period_units=8 --bvh-cache '" +
                               (work_dir() / "k_target_cache").string() +
                               "' --target-error 15 -o '" + out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out)["sampling"];
    EXPECT_TRUE(s["target"]["met"].get<bool>()) << s["target"];
    EXPECT_EQ(s["period_units"], s["target"]["period_units"]);
    EXPECT_LE(s["total_cycles"]["half_width_pct"].get<double>(), 15.0);
    EXPECT_LE(s["counters"]["dram.bytes"]["half_width_pct"].get<double>(), 15.0);
    // The pilot (a child run) stored the profile; the run itself loaded it.
    EXPECT_EQ(s["profile"]["cache"], "hit");
}

// Design `work` measures a frame's start-up outright: its first units with work, until their
// rays fill the chip's slots sim.sample_startup_slot_fills times (counted here from an every-unit
// run's table), are certainty units that stand for themselves, and the regression runs over the
// other units with work. The counters the profile knows exactly (box and triangle operations, L1
// accesses) stay the full run's with certainty units in the sample: calibrated to the frame's
// totals, not to those of the units left to draw.
TEST(Sampled, WorkDesignMeasuresTheStartUpOutright) {
    // AO rays in a closed room: the first units with work have node steps (a primary frame's
    // first rows see background, whose rays take none).
    const std::string frame =
        "run -q --scene builtin:cornell --rays ao --res 96x96 --set core.count=4 "
        "--set core.ray_slots=8 --bvh-cache '" +
        (work_dir() / "startup_cache").string() + "' ";
    const std::string sampled =
        "--set sim.sampled=true --set sim.sample_fast_forward=skip --set sim.sample_design=work "
        "--set sim.sample_unit_tiles=1 --set sim.sample_startup_slot_fills=3 ";
    const fs::path full = work_dir() / "startup_full", all = work_dir() / "startup_all",
                   sample = work_dir() / "startup_sample";
    ASSERT_EQ(run_rtsim(frame + "-o '" + full.string() + "'").status, 0);
    ASSERT_EQ(
        run_rtsim(frame + sampled + "--set sim.sample_period_units=1 -o '" + all.string() + "'")
            .status,
        0);
    ASSERT_EQ(
        run_rtsim(frame + sampled + "--set sim.sample_period_units=2 -o '" + sample.string() + "'")
            .status,
        0);
    // The start-up by hand: units with work in frame order until 3 x 4 x 8 = 96 rays.
    const UnitsCsv every = read_units_csv(all / "sampled_units.csv");
    const std::vector<double>&units = every.cols.at("unit"), &rays = every.cols.at("rays"),
          &work = every.cols.at("work");
    std::vector<double> startup;
    double startup_rays = 0;
    size_t with_work = 0;
    for (size_t i = 0; i < units.size(); ++i) {
        if (work[i] <= 0) continue;
        ++with_work;
        if (startup_rays < 96) {
            startup.push_back(units[i]);
            startup_rays += rays[i];
        }
    }
    ASSERT_GE(startup.size(), 2u) << "the frame's first units should each hold under 96 rays";
    const UnitsCsv s = read_units_csv(sample / "sampled_units.csv");
    std::map<double, std::pair<double, double>> certainty;  // unit: (certainty, design weight)
    for (size_t i = 0; i < s.cols.at("unit").size(); ++i)
        certainty[s.cols.at("unit")[i]] = {s.cols.at("certainty")[i],
                                           s.cols.at("design_weight")[i]};
    for (double u : startup) {
        ASSERT_TRUE(certainty.count(u)) << "start-up unit " << u << " not measured";
        EXPECT_EQ(certainty[u], std::make_pair(1.0, 1.0)) << "unit " << u;
    }
    const json f = stats_of(full), st = stats_of(sample);
    const json& sm = st["sampling"];
    ASSERT_GE(sm["certainty_units"].get<size_t>(), startup.size());
    EXPECT_EQ(sm["drawn_population"].get<size_t>(),
              with_work - sm["certainty_units"].get<size_t>());
    // The unit count is an auxiliary over the units drawn from (here about 40 of them), and not
    // for a sample too small for the jackknife alone to set its interval (1 in 8: about 10).
    EXPECT_EQ(sm["regression"]["totals"]["unit_with_work"].get<double>(),
              sm["drawn_population"].get<double>());
    const fs::path few = work_dir() / "startup_few";
    ASSERT_EQ(
        run_rtsim(frame + sampled + "--set sim.sample_period_units=8 -o '" + few.string() + "'")
            .status,
        0);
    EXPECT_FALSE(stats_of(few)["sampling"]["regression"]["totals"].contains("unit_with_work"));
    for (const auto& [prefixes, suffix] :
         std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"box_unit["}, ".ops"}, {{"triangle_unit["}, ".ops"}, {{"l1["}, ".accesses"}}) {
        const auto [full_count, estimated] = full_and_estimated(f, st, prefixes, suffix);
        EXPECT_GT(full_count, 0) << suffix;
        EXPECT_NEAR(estimated, full_count, 1e-9 * full_count) << prefixes[0] << suffix;
    }
}

// A skip-design pilot measures about 40 units, not one in the configured period: 256 units of a
// 128x128 frame (8x8-pixel tiles, one a unit) at a configured 1 in 2 make a pilot of 1 in 256 / 40
// = 6 (the stratified design draws from every unit), and a run configured coarser than that keeps
// its own period.
TEST(Sampled, APilotMeasuresAboutFortyUnits) {
    // (A warm-up of 2 slot fills of rays alone: with 4, or reaching back over background tiles
    // for their work, this small frame's plan puts 57-60% of its rays in detail and the run goes
    // in full.)
    const std::string frame = "run -q --scene " RTSIM_BUNNY_OBJ
                              " --rays primary --res 128x128 --set sim.sampled=true "
                              "--set sim.sample_fast_forward=skip --set sim.sample_unit_tiles=1 "
                              "--set sim.sample_warmup_slot_fills=2 "
                              "--set sim.sample_warmup_work=false "
                              "--bvh-cache '" +
                              (work_dir() / "pilot_cache").string() + "' --target-error 50 ";
    const fs::path fine = work_dir() / "pilot_fine", coarse = work_dir() / "pilot_coarse";
    ASSERT_EQ(
        run_rtsim(frame + "--set sim.sample_period_units=2 -o '" + fine.string() + "'").status, 0);
    const json f = stats_of(fine)["sampling"];
    ASSERT_EQ(f["units"], 256);
    EXPECT_EQ(f["target"]["pilot_period_units"], 6) << f["target"];
    EXPECT_NEAR(f["target"]["pilot_units_measured"].get<double>(), 256.0 / 6, 1.0);
    ASSERT_EQ(
        run_rtsim(frame + "--set sim.sample_period_units=8 -o '" + coarse.string() + "'").status,
        0);
    EXPECT_EQ(stats_of(coarse)["sampling"]["target"]["pilot_period_units"], 8);
}

namespace {

// A frame (`rtsim run` arguments naming its scene, rays and size), asked for +-`target_pct`%
// with the work design and run in full: the asked run's stats.json (without l2.first_fills, a
// counter only sampled configs register) and the full run's; `out`: what the asked run printed.
std::pair<json, json> asked_and_full(const std::string& frame_args, const std::string& target_pct,
                                     const std::string& name, std::string* out) {
    const std::string frame = "run " + frame_args + " ";
    const fs::path full = work_dir() / (name + "_full"), asked = work_dir() / (name + "_asked");
    EXPECT_EQ(run_rtsim(frame + "-q -o '" + full.string() + "'").status, 0);
    const Result r = run_rtsim(frame +
                               "--set sim.sampled=true --set sim.sample_fast_forward=skip "
                               "--set sim.sample_design=work --target-error " +
                               target_pct + " -o '" + asked.string() + "'");
    EXPECT_EQ(r.status, 0) << r.err;
    if (out) *out = r.out;
    json a = stats_of(asked);
    a["counters"].erase("l2.first_fills");
    return {a, stats_of(full)};
}

}  // namespace

// A target far beyond what a sample of the frame could reach is seen by a quick pilot of about 10
// units, and the frame runs in full without the pilot of about 40 (whose rays in detail, with
// their warm-ups, had cost heavy frames 27-57% of the full run before it ran in full).
TEST(Sampled, AQuickPilotSendsAFrameFarFromItsTargetInFull) {
    const auto [a, f] = asked_and_full(
        "--scene " RTSIM_BUNNY_OBJ " --rays primary,ao --res 192x192", "0.05", "quick", nullptr);
    const json& plan = a["sampling"]["target"];
    ASSERT_TRUE(a["sampling"]["in_full"].get<bool>()) << a["sampling"];
    EXPECT_NE(plan["note"].get<std::string>().find("quick pilot"), std::string::npos) << plan;
    EXPECT_LE(plan["pilot_units_measured"].get<double>(), 15.0) << plan;
    for (const char* k : {"total_cycles", "counters", "caches", "bandwidth"})
        EXPECT_EQ(a[k], f[k]) << k;
}

// The quick pilot also sends a frame in full when the units its need asks for, each with its
// warm-up, would put the frame's rays in detail 1.4 times over (half of them at a need 2.8 times
// smaller), though they are fewer than 4 times the frame's units: a 1024x768 camel frame of
// primary rays (3,072 units of 4 tiles, every one with rays) asked for +-2%.
TEST(Sampled, AQuickPilotSendsAFrameInFullWhenItsNeedPutsTheRaysInDetail) {
    const auto [a, f] =
        asked_and_full("--scene " RTSIM_CGAL_MESH_DIR "/camel.off --rays primary --res 1024x768",
                       "2", "quick_share", nullptr);
    const json& plan = a["sampling"]["target"];
    ASSERT_TRUE(a["sampling"]["in_full"].get<bool>()) << plan;
    EXPECT_NE(plan["note"].get<std::string>().find("quick pilot"), std::string::npos) << plan;
    EXPECT_LE(plan["pilot_units_measured"].get<double>(), 15.0) << plan;
    EXPECT_LT(plan["units_needed"].get<double>(), 4.0 * 3072) << plan;
    EXPECT_GE(plan["detailed_share_planned"].get<double>(), 1.4) << plan;
    EXPECT_EQ(a["total_cycles"], f["total_cycles"]);
}

// A target no sample can reach cheaper than the whole frame: the run says so and runs the frame
// in full, its statistics the full fast run's, field for field (a skip run measuring half the
// units or more costs more than the full run: each unit's warm-up and cache replay besides).
TEST(Sampled, ATargetThatNeedsMostUnitsRunsTheFrameInFull) {
    std::string out;
    const auto [a, f] = asked_and_full("--scene " RTSIM_BUNNY_OBJ " --rays primary,ao --res 64x64",
                                       "0.1", "infull", &out);
    EXPECT_NE(out.find("sampling cannot beat the full run"), std::string::npos) << out;
    ASSERT_TRUE(a["sampling"]["in_full"].get<bool>()) << a["sampling"];
    EXPECT_GE(a["sampling"]["target"]["units_needed"].get<double>(),
              0.5 * a["sampling"]["target"]["pilot_units_measured"].get<double>());
    EXPECT_FALSE(a["sampling"].contains("total_cycles"));  // nothing estimated
    // Everything the blocks counted is the full run's; the config differs in sim.* only.
    for (const char* k : {"total_cycles", "counters", "caches", "bandwidth", "units", "stalls"})
        EXPECT_EQ(a[k], f[k]) << k;
}

TEST(Sampled, SkipDesignNeedsGeneratedRays) {
    const fs::path rtt = work_dir() / "skip.rtt";
    ASSERT_EQ(run_rtsim("trace -q --res 16x16 -o '" + rtt.string() + "'").status, 0);
    expect_one_line_error(run_rtsim("run --trace '" + rtt.string() +
                                    "' --set sim.sampled=true "
                                    "--set sim.sample_fast_forward=skip"),
                          "sim.sample_fast_forward=skip skips tiles before they are traced");
}

// Matched-pair sampling (--reference, sim/sampling/reference.h) on a 96x96 bunny frame in units of
// 2 tiles (72 units), paired runs' too.
const std::string kPairFrame = "run --scene " RTSIM_BUNNY_OBJ
                               " --rays primary,ao --res 96x96 --set sim.sampled=true "
                               "--set sim.sample_fast_forward=skip --set sim.sample_unit_tiles=2 "
                               "--set sim.sample_paired_unit_tiles=2 ";

// The reference's every unit (a run measuring every unit), in a folder of its own.
fs::path make_reference(const std::string& name, const std::string& design = "") {
    const fs::path dir = work_dir() / name;
    fs::remove_all(dir);
    const Result r = run_rtsim(kPairFrame + design + "--set sim.sample_period_units=1 -o '" +
                               dir.string() + "'");
    EXPECT_EQ(r.status, 0) << r.err;
    return dir;
}

// The reference design against itself: its matched sample is the run's own, unit for unit, so
// the regression on it is exact and every total is the reference's, which the test reads from
// the reference's sampled_units.csv and stats.json.
// A second run finds the matched sample kept in the folder and gives the same figures.
TEST(Sampled, ReferenceOfTheSameDesignGivesItsTotals) {
    const fs::path ref = make_reference("pair_ref");
    const fs::path a = work_dir() / "pair_a", b = work_dir() / "pair_b";
    const std::string sampled =
        kPairFrame + "--set sim.sample_period_units=4 --reference '" + ref.string() + "' ";
    const Result ra = run_rtsim(sampled + "-o '" + a.string() + "'");
    ASSERT_EQ(ra.status, 0) << ra.err;
    const Result rb = run_rtsim(sampled + "-o '" + b.string() + "'");
    ASSERT_EQ(rb.status, 0) << rb.err;
    EXPECT_NE(rb.out.find("paired   with reference design 'baseline'"), std::string::npos)
        << rb.out;
    json sa = stats_of(a), sb = stats_of(b);
    EXPECT_EQ(sa["sampling"]["reference"]["matched_sample"], "ran");
    EXPECT_EQ(sb["sampling"]["reference"]["matched_sample"], "cached");
    // The reference's units carry its capacity misses: a paired run counts none functionally
    // (its reference, unpaired, did).
    EXPECT_FALSE(sa["sampling"].contains("functional_l2"));
    EXPECT_TRUE(stats_of(ref)["sampling"].contains("functional_l2"));
    // A paired run warms up over sim.sample_paired_warmup_tiles (1 tile, whatever its rays), its
    // reference unpaired over sim.sample_warmup_tiles (2, holding at least 256 rays: 4 fills of
    // the default chip's 64 slots); the matched sample runs with the paired run's warm-up, else
    // the units below would differ.
    EXPECT_EQ(sa["sampling"]["warmup_tiles"], 1);
    EXPECT_EQ(sa["sampling"]["warmup_tile_rays"], 0);
    EXPECT_EQ(stats_of(ref)["sampling"]["warmup_tiles"], 2);
    EXPECT_EQ(stats_of(ref)["sampling"]["warmup_tile_rays"], 256);
    EXPECT_NE(ra.out.find("warm-up 1 tile (sim.sample_paired_warmup_*); units of 2 tiles "
                          "(sim.sample_paired_unit_tiles)"),
              std::string::npos)
        << ra.out;
    for (json* s : {&sa, &sb}) {
        (*s)["sampling"].erase("reference");
        (*s)["sampling"].erase("profile");
    }
    EXPECT_EQ(without_host(sa), without_host(sb));

    const UnitsCsv truth = read_units_csv(ref / "sampled_units.csv");
    const json& sm = sa["sampling"];
    ASSERT_EQ(sm["units"], 72);
    ASSERT_EQ(sm["units_measured"], 18);
    // With the drain after the last hand-out as the reference (the full run) had it: the
    // frame's cycles exactly.
    const json full = stats_of(ref);
    const double cycles = full["total_cycles"].get<double>();
    EXPECT_EQ(column_sum(truth, "cycles") + full["sampling"]["drain_cycles"].get<double>(), cycles);
    EXPECT_NEAR(sm["total_cycles"]["value"].get<double>(), cycles, 1e-6 * cycles);
    EXPECT_LT(sm["total_cycles"]["half_width_pct"].get<double>(), 1e-6);
    for (const char* counter : {"l2.accesses", "dram.bytes"}) {
        const double t = column_sum(truth, counter);
        ASSERT_GT(t, 0) << counter;
        EXPECT_NEAR(sm["counters"][counter]["value"].get<double>(), t, 1e-6 * t) << counter;
    }
    // Like blocks are each regressed on their column's sum (the estimator is linear in the
    // figure): their estimates add up to it.
    double ops = 0;
    int blocks = 0;
    for (const auto& [name, e] : sm["counters"].items())
        if (name.rfind("triangle_unit[", 0) == 0 && name.find("].ops") != std::string::npos) {
            ops += e["value"].get<double>();
            ++blocks;
        }
    EXPECT_EQ(blocks, 8);
    const double t = column_sum(truth, "triangle_unit.ops");
    EXPECT_NEAR(ops, t, 1e-6 * t);
}

// A paired run's units may be several of its reference's (sim.sample_paired_unit_tiles): the
// reference's units are merged to them. Every unit of a frame measured runs the same simulation
// whatever the units, so a reference in units of 2 tiles and one in units of 4 give a paired run
// in units of 4 the same order of units, the same totals and the same matched sample: the same
// figures.
TEST(Sampled, ReferenceUnitsMergeToAPairedRunsLargerUnits) {
    const fs::path small = make_reference("merge_ref2");
    const fs::path large = make_reference("merge_ref4", "--set sim.sample_unit_tiles=4 ");
    json runs[2];
    int k = 0;
    for (const fs::path& ref : {small, large}) {
        const fs::path out = work_dir() / ("merge_paired" + std::to_string(k));
        const Result r =
            run_rtsim(kPairFrame +
                      "--set box_unit.latency_cycles=16 --set sim.sample_period_units=3 "
                      "--set sim.sample_paired_unit_tiles=4 --reference '" +
                      ref.string() + "' -o '" + out.string() + "'");
        ASSERT_EQ(r.status, 0) << r.err;
        runs[k] = stats_of(out);
        EXPECT_EQ(runs[k]["sampling"]["unit_tiles"], 4);
        EXPECT_EQ(runs[k]["sampling"]["units"], 36);
        EXPECT_EQ(runs[k]["sampling"]["units_measured"], 12);
        runs[k]["sampling"].erase("reference");  // names its folder and config
        runs[k]["sampling"].erase("profile");    // made by the first run, read by the second
        runs[k]["sampling"].erase("order");      // names the reference's folder
        ++k;
    }
    EXPECT_EQ(without_host(runs[0]), without_host(runs[1]));
    // Units of 3 tiles are not whole units of 2: refused, naming both.
    const Result bad =
        run_rtsim(kPairFrame + "--set sim.sample_paired_unit_tiles=3 --reference '" +
                  small.string() + "' -o '" + (work_dir() / "merge_bad").string() + "'");
    expect_one_line_error(bad, "its units are 2 tiles, this run's 3 (a multiple of them is needed");
}

// Another design paired with the reference: the run's units and the reference's are the same,
// and the interval on the frame's cycles is narrower than the same sample's without the pair
// (the same units, by --sample-order) and still holds the full run's (unit latencies doubled;
// checked on these three seeds).
TEST(Sampled, ReferenceNarrowsTheIntervalOfANearDesign) {
    const fs::path ref = make_reference("near_ref");
    const std::string design =
        "--set box_unit.latency_cycles=16 --set triangle_unit.latency_cycles=36 ";
    const fs::path full = make_reference("near_full", design);
    const double truth = stats_of(full)["total_cycles"].get<double>();
    double ratios = 0;
    for (int seed = 1; seed <= 3; ++seed) {
        const fs::path alone = work_dir() / ("near_alone" + std::to_string(seed)),
                       paired = work_dir() / ("near_paired" + std::to_string(seed));
        const std::string sampled =
            kPairFrame + design +
            "--set sim.sample_period_units=4 --set sim.sample_seed=" + std::to_string(seed) + " ";
        ASSERT_EQ(
            run_rtsim(sampled + "--sample-order '" + ref.string() + "' -o '" + alone.string() + "'")
                .status,
            0);
        const Result r =
            run_rtsim(sampled + "--reference '" + ref.string() + "' -o '" + paired.string() + "'");
        ASSERT_EQ(r.status, 0) << r.err;
        const json sa = stats_of(alone)["sampling"], sp = stats_of(paired)["sampling"];
        const json& c = sp["total_cycles"];
        // The run alone may give no interval (null: it would extrapolate to heavier units than
        // it measured); the paired one always does here.
        auto half_width = [](const json& e) {
            return e["half_width_pct"].is_null() ? std::numeric_limits<double>::infinity()
                                                 : e["half_width_pct"].get<double>();
        };
        EXPECT_LT(half_width(c), half_width(sa["total_cycles"])) << seed;
        ratios += half_width(c) / half_width(sa["total_cycles"]);
        EXPECT_LE(c["lo"].get<double>(), truth) << seed;
        EXPECT_GE(c["hi"].get<double>(), truth) << seed;
        const UnitsCsv mine = read_units_csv(paired / "sampled_units.csv");
        EXPECT_EQ(read_units_csv(alone / "sampled_units.csv").cols.at("unit"),
                  mine.cols.at("unit"));
        bool found = false;
        for (const auto& f : fs::directory_iterator(ref)) {
            if (f.path().filename().string().rfind("matched-", 0) != 0 ||
                f.path().extension() != ".csv")
                continue;
            const auto units = read_units_csv(f.path()).cols.at("unit");
            found |= units == mine.cols.at("unit");
        }
        EXPECT_TRUE(found) << seed;
    }
    EXPECT_LT(ratios / 3, 0.5);
}

// A paired run cuts its strata from the units in order of the reference's cycles: ordered here
// from the reference's sampled_units.csv (ties by unit), each run of 4 units of that order holds
// one measured unit. An unpaired run given the same order (--sample-order) measures the same
// units for the same seed; without one, the strata are the frame's neighbouring units.
TEST(Sampled, StrataFollowTheReferenceCycles) {
    const fs::path ref = make_reference("order_ref");
    const UnitsCsv truth = read_units_csv(ref / "sampled_units.csv");
    const auto& unit = truth.cols.at("unit");
    const auto& cycles = truth.cols.at("cycles");
    const auto& work = truth.cols.at("work");
    std::vector<size_t> rows(unit.size());
    std::iota(rows.begin(), rows.end(), size_t(0));
    std::sort(rows.begin(), rows.end(), [&](size_t a, size_t b) {
        return std::make_pair(cycles[a], unit[a]) < std::make_pair(cycles[b], unit[b]);
    });
    // Then, within each run of 4 strata (16 units), by work per cycle (0 without cycles).
    auto per_cycle = [&](size_t row) { return cycles[row] > 0 ? work[row] / cycles[row] : 0.0; };
    for (size_t k = 0; k < rows.size(); k += 16)
        std::sort(rows.begin() + long(k), rows.begin() + long(std::min(rows.size(), k + 16)),
                  [&](size_t a, size_t b) {
                      return std::make_pair(per_cycle(a), unit[a]) <
                             std::make_pair(per_cycle(b), unit[b]);
                  });
    std::map<uint64_t, size_t> stratum;  // unit -> its stratum in that order
    for (size_t k = 0; k < rows.size(); ++k) stratum[uint64_t(unit[rows[k]])] = k / 4;
    ASSERT_EQ(stratum.size(), 72u);
    // The order is not the frame's: some stratum spans units far apart.
    bool apart = false;
    for (size_t k = 4; k < rows.size(); k += 4) apart |= unit[rows[k]] - unit[rows[k - 1]] > 8;
    EXPECT_TRUE(apart);

    const std::string design =
        kPairFrame + "--set box_unit.latency_cycles=16 --set sim.sample_period_units=4 ";
    const fs::path paired = work_dir() / "order_paired", ordered = work_dir() / "order_alone",
                   frame = work_dir() / "order_frame";
    Result r =
        run_rtsim(design + "--reference '" + ref.string() + "' -o '" + paired.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    r = run_rtsim(design + "--sample-order '" + ref.string() + "' -o '" + ordered.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    // In the reference's units (an unpaired run would otherwise size them to the chip's slots).
    r = run_rtsim(design + "--set sim.sample_unit_slot_fills=0 -o '" + frame.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;

    const auto measured = [](const fs::path& dir) {
        return read_units_csv(dir / "sampled_units.csv").cols.at("unit");
    };
    std::vector<int> per_stratum(18, 0);
    for (double u : measured(paired)) ++per_stratum.at(stratum.at(uint64_t(u)));
    EXPECT_EQ(per_stratum, std::vector<int>(18, 1));
    EXPECT_EQ(measured(ordered), measured(paired));
    EXPECT_NE(measured(frame), measured(paired));
    std::vector<int> per_block(18, 0);  // the frame's own order: units 4h..4h+3
    for (double u : measured(frame)) ++per_block.at(size_t(u) / 4);
    EXPECT_EQ(per_block, std::vector<int>(18, 1));

    const json order = {{"by", "cycles"},
                        {"then", "work per cycle"},
                        {"strata_per_group", 4},
                        {"of", ref.string()}};
    EXPECT_EQ(stats_of(paired)["sampling"]["order"], order);
    EXPECT_EQ(stats_of(ordered)["sampling"]["order"], order);
    EXPECT_EQ(stats_of(frame)["sampling"]["order"], "frame");
}

TEST(Sampled, SampleOrderMustBeAnEveryUnitRunOfTheSameUnits) {
    const fs::path ref = make_reference("order_bad_ref");
    const fs::path out = work_dir() / "order_bad_out";
    const std::string order = "--sample-order '" + ref.string() + "' -o '" + out.string() + "'";
    // Not a skip run.
    expect_one_line_error(
        run_rtsim("run --scene " RTSIM_BUNNY_OBJ " --res 96x96 --set sim.sampled=true " + order),
        "needs sim.sampled=true and sim.sample_fast_forward=skip");
    // Units that are not whole units of the run's (units of 4 would be two of them), or a frame
    // of other units.
    expect_one_line_error(run_rtsim(kPairFrame + "--set sim.sample_unit_tiles=3 " + order),
                          "its units are 2 tiles, this run's 3");
    expect_one_line_error(run_rtsim("run --scene " RTSIM_BUNNY_OBJ
                                    " --rays primary --res 64x64 --set sim.sampled=true "
                                    "--set sim.sample_fast_forward=skip "
                                    "--set sim.sample_unit_tiles=2 " +
                                    order),
                          "its run has 72 units, this frame 32");
    // A sampled run, not one that measured every unit.
    const fs::path part = work_dir() / "order_bad_part";
    ASSERT_EQ(
        run_rtsim(kPairFrame + "--set sim.sample_period_units=4 -o '" + part.string() + "'").status,
        0);
    expect_one_line_error(
        run_rtsim(kPairFrame + "--sample-order '" + part.string() + "' -o '" + out.string() + "'"),
        "not a run that measured every unit");
    EXPECT_FALSE(fs::exists(out));
}

// --target-error with a reference: the pilot is paired too (its own matched sample), so the
// period it picks is sized by the pair's spread, and the run meets the target.
TEST(Sampled, ReferenceWithTargetError) {
    // 192x192: the 96x96 frame's 72 units are too few (its plan needs 30 units, two thirds of
    // the rays, and runs in full).
    std::string frame = kPairFrame;
    frame.replace(frame.find("96x96"), 5, "192x192");
    const fs::path ref = work_dir() / "target_ref";
    fs::remove_all(ref);
    ASSERT_EQ(run_rtsim(frame + "--set sim.sample_period_units=1 -o '" + ref.string() + "'").status,
              0);
    const fs::path out = work_dir() / "target_paired";
    const Result r = run_rtsim(frame +
                               "--set box_unit.latency_cycles=16 --set sim.sample_period_units=4 "
                               "--target-error 2 --reference '" +
                               ref.string() + "' -o '" + out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out)["sampling"];
    EXPECT_TRUE(s["target"]["met"].get<bool>()) << s["target"];
    EXPECT_LE(s["total_cycles"]["half_width_pct"].get<double>(), 2.0);
    EXPECT_EQ(s["period_units"], s["target"]["period_units"]);
    ASSERT_TRUE(s.contains("reference"));
    // The pilot's plan and the run's: a matched sample each, kept in the reference's folder.
    int tables = 0;
    for (const auto& f : fs::directory_iterator(ref))
        tables += f.path().extension() == ".csv" &&
                  f.path().filename().string().rfind("matched-", 0) == 0;
    EXPECT_EQ(tables, s["period_units"] == 4 ? 1 : 2);
}

TEST(Sampled, ReferenceMustBeTheSameFrameMeasuredInFull) {
    const fs::path ref = make_reference("bad_ref");
    const fs::path out = work_dir() / "bad_ref_out";
    const std::string sampled =
        kPairFrame + "--set sim.sample_period_units=4 -o '" + out.string() + "' --reference ";
    // No run there.
    expect_one_line_error(run_rtsim(sampled + "'" + (work_dir() / "nowhere").string() + "'"),
                          "nowhere: no readable stats.json");
    // A sampled run, not one that measured every unit.
    const fs::path part = work_dir() / "bad_ref_part";
    ASSERT_EQ(
        run_rtsim(kPairFrame + "--set sim.sample_period_units=4 -o '" + part.string() + "'").status,
        0);
    expect_one_line_error(run_rtsim(sampled + "'" + part.string() + "'"),
                          "not a run that measured every unit");
    // Another frame: the same scene at another resolution, or other rays.
    expect_one_line_error(
        run_rtsim("run --scene " RTSIM_BUNNY_OBJ
                  " --rays primary,ao --res 64x64 --set sim.sampled=true "
                  "--set sim.sample_fast_forward=skip --set sim.sample_unit_tiles=2 "
                  "--set sim.sample_period_units=4 --reference '" +
                  ref.string() + "' -o '" + out.string() + "'"),
        "made on another frame (its workload differs");
    // Other units.
    expect_one_line_error(run_rtsim(kPairFrame + "--set sim.sample_paired_unit_tiles=3 -o '" +
                                    out.string() + "' --reference '" + ref.string() + "'"),
                          "its units are 2 tiles, this run's 3");
    // A damaged table of the reference's matched sample (kept in its folder by a first run).
    const fs::path damaged = work_dir() / "bad_ref_damaged";
    fs::remove_all(damaged);
    fs::copy(ref, damaged);
    const fs::path first = work_dir() / "bad_ref_first";
    ASSERT_EQ(run_rtsim(kPairFrame + "--set sim.sample_period_units=4 -o '" + first.string() +
                        "' --reference '" + damaged.string() + "'")
                  .status,
              0);
    fs::path table;
    for (const auto& f : fs::directory_iterator(damaged))
        if (f.path().extension() == ".csv" &&
            f.path().filename().string().rfind("matched-", 0) == 0)
            table = f.path();
    ASSERT_FALSE(table.empty());
    std::ofstream(table, std::ios::app) << "72,1,2,x\n";  // line 20: after the header, 18 units
    expect_one_line_error(run_rtsim(sampled + "'" + damaged.string() + "'"),
                          table.filename().string() + ": line 20: 'x' is not a number");
    // A reference whose config this rtsim no longer accepts (as from an older schema).
    const fs::path old_schema = work_dir() / "bad_ref_schema";
    fs::remove_all(old_schema);
    fs::copy(ref, old_schema);
    json stats = json::parse(slurp(old_schema / "stats.json"));
    stats["config"]["l1"]["size_kib"] = 0;
    std::ofstream(old_schema / "stats.json") << stats.dump();
    expect_one_line_error(run_rtsim(sampled + "'" + old_schema.string() + "'"),
                          "bad_ref_schema: its config does not load in this rtsim (l1.size_kib");
    // A config that loads but cannot run sampled: the reference's matched sample (a child run)
    // fails, and its reason is part of this run's one line.
    const fs::path no_run = work_dir() / "bad_ref_no_run";
    fs::remove_all(no_run);
    fs::copy(ref, no_run);
    stats = json::parse(slurp(no_run / "stats.json"));
    stats["config"]["traversal"]["mode"] = "treelet";
    stats["config"]["bvh"]["treelet_bytes"] = 32768;
    std::ofstream(no_run / "stats.json") << stats.dump();
    expect_one_line_error(run_rtsim(sampled + "'" + no_run.string() + "'"),
                          "bad_ref_no_run: the reference design's sample of this run's units: "
                          "the run failed: sim.sampled: not yet with "
                          "traversal.mode=treelet");
    // Not a sampled run.
    expect_one_line_error(run_rtsim("run --scene " RTSIM_BUNNY_OBJ " --res 96x96 -o '" +
                                    out.string() + "' --reference '" + ref.string() + "'"),
                          "needs sim.sampled=true and sim.sample_fast_forward=skip");
    EXPECT_FALSE(fs::exists(out));
}

TEST(Run, BrokenConfigExitsTwoWithOneLine) {
    const fs::path cfg = work_dir() / "broken.json";
    std::ofstream(cfg) << R"({"l1": {"size_kib": 0}})";
    const fs::path out = work_dir() / "never";
    const Result r =
        run_rtsim(fmt::format("run --config '{}' --out '{}'", cfg.string(), out.string()));
    expect_one_line_error(r, cfg.string() + ": l1.size_kib");
    EXPECT_FALSE(fs::exists(out / "stats.json"));
}

TEST(Run, MissingSceneExitsTwoWithOneLine) {
    const fs::path out = work_dir() / "never";
    const Result r =
        run_rtsim(fmt::format("run --scene /no/such/mesh.obj --out '{}'", out.string()));
    expect_one_line_error(r, "/no/such/mesh.obj: scene file not found");
    EXPECT_FALSE(fs::exists(out / "stats.json"));
}

TEST(Run, BadCommandLinesExitTwo) {
    expect_one_line_error(run_rtsim("run --res 0x5"), "--res");
    expect_one_line_error(run_rtsim("run --rays primary,bogus"), "unknown ray kind 'bogus'");
    expect_one_line_error(run_rtsim("run --set nope=1"), "unknown key");
    EXPECT_EQ(run_rtsim("run --no-such-flag").status, 2);
    EXPECT_EQ(run_rtsim("").status, 2);
    EXPECT_EQ(run_rtsim("frobnicate").status, 2);
}

TEST(Run, HelpOnEveryCommand) {
    for (const char* c : {"--help", "run --help", "config --help", "compare --help", "sweep --help",
                          "list --help"}) {
        const Result r = run_rtsim(c);
        EXPECT_EQ(r.status, 0) << c;
        EXPECT_NE(r.out.find("Usage"), std::string::npos) << c;
    }
    const Result run_help = run_rtsim("run --help");
    for (const char* opt : {"--config", "--set", "--scene", "--rays", "--res", "--seed", "--out"})
        EXPECT_NE(run_help.out.find(opt), std::string::npos) << opt;
}

TEST(Run, ConfigCommandPrintsEffectiveConfig) {
    const Result r = run_rtsim(fmt::format(
        "config --config {}/configs/small_caches.json --set l1.ways=2", RTSIM_SOURCE_DIR));
    ASSERT_EQ(r.status, 0) << r.err;
    const json c = json::parse(r.out);
    EXPECT_EQ(c["l1"]["size_kib"], 4);
    EXPECT_EQ(c["l1"]["ways"], 2);
    EXPECT_EQ(c["l2"]["ways"], 16);
}

// rtsim list: every registered kind and component, as text and JSON; each component it lists is
// accepted by the config field that selects it, and an unknown kind is one line, exit 2.
TEST(Run, ListShowsRegisteredComponentsThatConfigsAccept) {
    const Result text = run_rtsim("list");
    ASSERT_EQ(text.status, 0) << text.err;
    for (const char* name : {"replacement", "srrip", "tree_plru", "age_ordered", "dram_model",
                             "traversal_mode", "treelet"})
        EXPECT_NE(text.out.find(name), std::string::npos) << name;
    const Result js = run_rtsim("list --json");
    ASSERT_EQ(js.status, 0) << js.err;
    const json all = json::parse(js.out);
    for (auto& [kind, entry] : all.items())
        for (const auto& sel : entry["selected_by"])
            for (const auto& c : entry["components"]) {
                const Result r = run_rtsim(fmt::format("config --set {}={}", sel.get<std::string>(),
                                                       c["name"].get<std::string>()));
                // Accepted; or refused for what else the defaults set, in a line that names it
                // (treelet mode without treelets), never as an unknown value.
                EXPECT_TRUE(r.status == 0 ||
                            (r.status == 2 &&
                             r.err.find(c["name"].get<std::string>()) != std::string::npos &&
                             r.err.find("one of") == std::string::npos))
                    << kind << " " << c["name"] << ": " << r.err;
            }
    const Result one = run_rtsim("list replacement");
    EXPECT_EQ(one.status, 0);
    EXPECT_EQ(one.out.find("traversal_mode"), std::string::npos);
    expect_one_line_error(run_rtsim("list wavefronts"), "unknown component kind");
}

namespace {

// Leaf paths of a JSON document whose values differ, for a readable failure.
void diff_json(const json& a, const json& b, const std::string& path,
               std::vector<std::string>& out) {
    if (a.is_object() && b.is_object()) {
        for (auto& [k, v] : a.items())
            if (!b.contains(k))
                out.push_back(path + "/" + k + " (only in run)");
            else
                diff_json(v, b[k], path + "/" + k, out);
        for (auto& [k, v] : b.items())
            if (!a.contains(k)) out.push_back(path + "/" + k + " (only in golden)");
        return;
    }
    if (a != b) out.push_back(path + ": run " + a.dump() + ", golden " + b.dump());
}

}  // namespace

// Simulated statistics of small fixed runs (tests/golden/cases.json: independent, treelet with
// the age-ordered scheduler, packet, shared units with tree-PLRU and SRRIP, the time-ordered
// engine, and command DRAM with the writes of a small write-back L2). A change here must
// be deliberate: regenerate with scripts/update_golden.sh, which prints each file's diff, and
// explain in the commit why the numbers moved.
TEST(Golden, EveryCaseMatchesItsFile) {
    const json cases = json::parse(slurp(fs::path(RTSIM_SOURCE_DIR) / "tests/golden/cases.json"));
    ASSERT_GE(cases.size(), 4u);
    for (const auto& [name, args] : cases.items()) {
        SCOPED_TRACE(name);
        const fs::path out = work_dir() / ("golden_" + name);
        std::string cmd = "run -q";
        for (const auto& a : args) cmd += " '" + a.get<std::string>() + "'";
        const Result r = run_rtsim(cmd + " --out '" + out.string() + "'");
        ASSERT_EQ(r.status, 0) << r.err;
        json s = stats_of(out);
        s.erase("host");
        s.erase("rtsim_version");
        const json golden =
            json::parse(slurp(fs::path(RTSIM_SOURCE_DIR) / ("tests/golden/" + name + ".json")));
        std::vector<std::string> diffs;
        diff_json(s, golden, "", diffs);
        std::string report;
        for (size_t i = 0; i < diffs.size() && i < 20; ++i) report += "\n  " + diffs[i];
        EXPECT_TRUE(diffs.empty())
            << name << ": " << diffs.size() << " differences from the golden stats:" << report;
    }
}

namespace {

std::string write_rays(const fs::path& p, const std::vector<std::array<float, 8>>& recs) {
    std::ofstream f(p, std::ios::binary);
    for (const auto& r : recs) f.write(reinterpret_cast<const char*>(r.data()), 32);
    return p.string();
}

}  // namespace

TEST(Trace, ExternalRaysHitPrimitivesInFileOrder) {
    // Three unit quads side by side along x, as OBJ faces: a triangle, a quad (split into two
    // triangles in file order), a triangle. Ids must follow the file: 0, then 1 and 2, then 3.
    const fs::path obj = work_dir() / "strip.obj";
    std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 3 0 0\nv 3 1 0\n"
                          "f 1 2 3\nf 2 4 5 6\nf 4 7 8\n";
    const float inf = std::numeric_limits<float>::infinity();
    const std::string rays = write_rays(work_dir() / "rays.bin",
                                        {
                                            {0.7f, 0.2f, 1, 0, 0, 0, -1, inf},  // tri 0
                                            {1.7f, 0.2f, 1, 0, 0, 0, -1, inf},  // quad, first half
                                            {1.2f, 0.8f, 1, 0, 0, 0, -1, inf},  // quad, second half
                                            {2.7f, 0.2f, 1, 0, 0, 0, -1, inf},  // tri 3
                                            {5.0f, 5.0f, 1, 0, 0, 0, -1, inf},  // miss
                                            {0.7f, 0.2f, 1, 0, 0, 0, -1, 0.5f},  // too short
                                        });
    const fs::path csv = work_dir() / "hits.csv";
    const Result r = run_rtsim(fmt::format("trace -q --scene '{}' --rays-file '{}' --hits '{}'",
                                           obj.string(), rays, csv.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    std::istringstream in(slurp(csv));
    std::string line;
    std::getline(in, line);
    EXPECT_EQ(line, "ray,t,prim,u,v");
    std::vector<std::string> prims;
    while (std::getline(in, line)) {
        std::vector<std::string> cols;
        std::stringstream ls(line);
        std::string c;
        while (std::getline(ls, c, ',')) cols.push_back(c);
        ASSERT_EQ(cols.size(), 5u) << line;
        EXPECT_EQ(cols[0], std::to_string(prims.size()));
        prims.push_back(cols[2]);
        if (cols[2] != "-1")
            EXPECT_EQ(cols[1], "1") << line;  // every quad is at distance 1
        else
            EXPECT_EQ(cols[1], "inf");
    }
    EXPECT_EQ(prims, (std::vector<std::string>{"0", "1", "2", "3", "-1", "-1"}));
}

TEST(Trace, IdenticalOutputForAnyThreadCount) {
    const fs::path a = work_dir() / "a.csv", b = work_dir() / "b.bin", c = work_dir() / "c.csv",
                   d = work_dir() / "d.bin";
    const std::string args = "trace -q --rays primary,ao,diffuse,reflection,shadow --res 64x64 ";
    ASSERT_EQ(
        run_rtsim(args + "-j 1 --hits '" + a.string() + "' --hits-bin '" + b.string() + "'").status,
        0);
    ASSERT_EQ(
        run_rtsim(args + "-j 2 --hits '" + c.string() + "' --hits-bin '" + d.string() + "'").status,
        0);
    const std::string ca = slurp(a);
    EXPECT_GT(std::count(ca.begin(), ca.end(), '\n'), 64 * 64);
    EXPECT_EQ(ca, slurp(c));
    EXPECT_EQ(slurp(b), slurp(d));
}

TEST(Trace, GeneratedRaysReplayFromFileGiveSameHits) {
    const fs::path rays = work_dir() / "gen.bin", h1 = work_dir() / "h1.csv",
                   h2 = work_dir() / "h2.csv";
    ASSERT_EQ(run_rtsim("trace -q --rays primary,reflection --res 32x32 --write-rays '" +
                        rays.string() + "' --hits '" + h1.string() + "'")
                  .status,
              0);
    ASSERT_EQ(run_rtsim("trace -q --rays-file '" + rays.string() + "' --hits '" + h2.string() + "'")
                  .status,
              0);
    EXPECT_EQ(slurp(h1), slurp(h2));  // all closest-hit queries, ids in emission order
}

TEST(Trace, BadRayFileExitsTwoAndWritesNothing) {
    const float inf = std::numeric_limits<float>::infinity();
    const std::string rays = write_rays(work_dir() / "bad.bin",
                                        {{0, 0, 0, 0, 0, 0, 1, inf}, {0, 0, 0, 0, 0, 0, 0, inf}});
    const fs::path csv = work_dir() / "never.csv";
    const Result r =
        run_rtsim(fmt::format("trace --rays-file '{}' --hits '{}'", rays, csv.string()));
    expect_one_line_error(r, "ray 1 (byte 32): zero direction");
    EXPECT_FALSE(fs::exists(csv));
    EXPECT_FALSE(fs::exists(csv.string() + ".tmp"));
}

TEST(Trace, OutOfRangeSceneIsRefusedByEveryCommand) {
    // A tetrahedron of extent 1e30: beyond kMaxSceneExtent (every single-precision triangle test
    // overflows). `run` and a generated `trace` refuse it; a rays file must too, not trace it
    // silently (0 hits, exit 0).
    const fs::path off = work_dir() / "huge.off";
    std::ofstream(off) << "OFF\n4 4 0\n0 0 0\n1e30 0 0\n0 1e30 0\n0 0 1e30\n"
                          "3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n";
    const float inf = std::numeric_limits<float>::infinity();
    const std::string rays =
        write_rays(work_dir() / "huge_rays.bin", {{1e29f, 1e29f, -1e30f, 0, 0, 1, 0, inf}});
    const fs::path csv = work_dir() / "huge.csv";
    for (const std::string& cmd :
         {fmt::format("trace --scene '{}' --rays-file '{}' --hits '{}'", off.string(), rays,
                      csv.string()),
          fmt::format("trace --scene '{}' --res 8x8 --hits '{}'", off.string(), csv.string()),
          fmt::format("run --scene '{}' --res 8x8 -o '{}'", off.string(),
                      (work_dir() / "huge_out").string())}) {
        const Result r = run_rtsim(cmd);
        expect_one_line_error(
            r, "huge.off: scene bounds (0, 0, 0) to (1e+30, 1e+30, 1e+30) are too large");
        EXPECT_FALSE(fs::exists(csv)) << cmd;
    }
    EXPECT_FALSE(fs::exists(work_dir() / "huge_out" / "stats.json"));
}

TEST(Trace, SceneFileHitsNameTheirInstance) {
    // A 4 x 3 grid of one triangle (spacing 2), traced by rays straight down onto copies; the
    // hits CSV gains an instance column: copy (x, y) is instance x + 4 y.
    const fs::path dir = work_dir();
    std::ofstream(dir / "tri.off") << "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    const fs::path scene = dir / "grid.json";
    std::ofstream(scene) << R"({"meshes": {"t": "tri.off"}, "instances": [{"mesh": "t",
        "grid": {"count": [4, 3, 1], "spacing": [2, 2, 0]}}]})";
    const float inf = std::numeric_limits<float>::infinity();
    const std::string rays =
        write_rays(dir / "down.bin", {{0.25f, 0.25f, 1, 0, 0, 0, -1, inf},    // copy (0, 0)
                                      {6.25f, 4.5f, 3, 0, 0, 0, -1, inf},     // copy (3, 2)
                                      {2.75f, 2.75f, 1, 0, 0, 0, -1, inf}});  // outside (1, 1)
    const fs::path csv = dir / "grid_hits.csv";
    const Result r = run_rtsim(fmt::format("trace -q --scene '{}' --rays-file '{}' --hits '{}'",
                                           scene.string(), rays, csv.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(slurp(csv),
              "ray,t,prim,u,v,instance\n0,1,0,0.25,0.25,0\n1,3,0,0.25,0.5,11\n"
              "2,inf,-1,0,0,-1\n");
    // What two-level scenes do not have yet is refused in one line, writing nothing.
    const fs::path bin = dir / "grid_hits.bin";
    expect_one_line_error(
        run_rtsim(fmt::format("trace --scene '{}' --hits-bin '{}'", scene.string(), bin.string())),
        "is an instanced scene; its hits carry an instance");
    EXPECT_FALSE(fs::exists(bin));
}

// A frame too short for two sampling periods gets no estimate, and the summary says that its
// cycles line is the measured units' alone, not the frame's.
TEST(Sampled, AFrameWithoutAnEstimateSaysItsFiguresAreTheMeasuredUnits) {
    const fs::path out = work_dir() / "no_estimate";
    const Result r = run_rtsim("run --scene " RTSIM_BUNNY_OBJ
                               " --rays primary,ao --res 96x96 --set sim.sampled=true "
                               "-o '" +
                               out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    EXPECT_FALSE(s["sampling"].contains("total_cycles"));
    EXPECT_LT(s["sampling"]["units_measured"].get<int>(), 2);
    EXPECT_NE(r.out.find("caution  frame: no estimate: the cycles, rate and traffic above are "
                         "the measured units' only"),
              std::string::npos)
        << r.out;
}

// Sampled runs over a scene of instances: the skip design profiles the frame over both levels;
// measuring every unit is the full run counter for counter, and a 1-in-4 sample of the work
// design holds the full run's cycles within its interval.
TEST(Sampled, ScenesOfInstancesSampleAsMeshesDo) {
    const fs::path dir = work_dir();
    const fs::path scene = spheres_on_a_floor(dir / "sampled_copies.json", 4, 0.2);
    const std::string common =
        "run --scene '" + scene.string() + "' --rays primary,ao --res 48x48 ";
    const auto [f, a] = full_and_every_unit_run(common, "inst");
    ASSERT_FALSE(f.is_null() || a.is_null());
    EXPECT_EQ(a["sampling"]["units_measured"], a["sampling"]["units"]);
    EXPECT_EQ(a["sampling"]["simulated_cycles"], f["total_cycles"]);
    EXPECT_EQ(counters_less_first_fills(a), f["counters"]);
    EXPECT_GT(f["units"]["transform_unit_total"]["ops"].get<uint64_t>(), 0u);

    expect_work_sample_holds_the_full_run(
        "run --scene '" + scene.string() + "' --rays primary,ao --res 96x96 ", "inst96");
}

// A scene file simulated: every instance entered is one transform-unit operation (counted by
// the functional trace's transform steps), its records are DRAM traffic of their own region,
// and a replay of the recorded trace gives the on-the-fly run's counters, every one.
TEST(Run, SceneFileRunsTheTransformUnitAndReplaysExactly) {
    const fs::path dir = work_dir();
    const fs::path scene = spheres_on_a_floor(dir / "copies.json", 4, 0.2);
    const std::string w = "--rays primary,ao --res 48x48 --scene '" + scene.string() + "'";
    const fs::path rtt = dir / "copies.rtt";
    ASSERT_EQ(run_rtsim("trace -q " + w + " -o '" + rtt.string() + "'").status, 0);
    const uint64_t transforms = trace_kind_total(rtt, "transform_steps");
    ASSERT_GT(transforms, 1000u);
    const fs::path direct = dir / "copies_direct", replay = dir / "copies_replay";
    ASSERT_EQ(run_rtsim("run -q " + w + " -o '" + direct.string() + "'").status, 0);
    ASSERT_EQ(
        run_rtsim("run -q --trace '" + rtt.string() + "' -o '" + replay.string() + "'").status, 0);
    const nlohmann::json a = nlohmann::json::parse(slurp(direct / "stats.json")),
                         b = nlohmann::json::parse(slurp(replay / "stats.json"));
    EXPECT_EQ(unit_ops(a, "transform_unit"), transforms);
    EXPECT_EQ(a["counters"], b["counters"]);
    EXPECT_EQ(a["scene"]["instances"], 17);
    EXPECT_GT(a["bandwidth"]["dram"]["by_region"]["instances"]["read_bytes"].get<uint64_t>(), 0u);
    EXPECT_LE(a["bandwidth"]["dram"]["by_region"]["instances"]["read_bytes"].get<uint64_t>(),
              17u * 64);  // each record fetched from DRAM once at most (the L2 keeps 1 KiB)
}

// A scene of alpha-masked foliage stand-ins: the any-hit shader runs once per any-hit step the
// trace records, in both engines; its alpha reads are the DRAM traffic's alpha region, and a
// shader that reads nothing leaves that region empty and the calls the same.
TEST(Run, NonOpaqueInstancesRunTheAnyHitShaderInBothEngines) {
    const fs::path dir = work_dir();
    const fs::path scene = dir / "leaves.json";
    std::ofstream(scene) << R"({"meshes": {"c": "builtin:cornell",
            "s": {"file": "builtin:sphere", "alpha": {"pattern": "checker", "cells": 2}}},
        "instances": [{"mesh": "c", "translate": [-1, -1, -2.5]},
                      {"mesh": "s", "scale": 0.3, "grid": {"count": [4, 4, 2],
                       "spacing": [0.5, 0.5, 0.6]}, "translate": [-0.75, -0.75, -0.3]}]})";
    const std::string w = "--rays primary,ao --res 40x40 --scene '" + scene.string() + "'";
    const fs::path rtt = dir / "leaves.rtt";
    ASSERT_EQ(run_rtsim("trace -q " + w + " -o '" + rtt.string() + "'").status, 0);
    const uint64_t calls = trace_kind_total(rtt, "any_hit_steps");
    ASSERT_GT(calls, 300u);
    auto shader_ops = [](const json& stats) { return unit_ops(stats, "any_hit_shader"); };
    auto alpha_dram = [](const nlohmann::json& stats) {
        return stats["bandwidth"]["dram"]["by_region"]["alpha"]["read_bytes"].get<uint64_t>();
    };
    nlohmann::json fast;
    for (const std::string engine : {"fast", "accurate"}) {
        const fs::path out = dir / ("leaves_" + engine);
        const Result r = run_rtsim("run -q " + w + " --set sim.fidelity=" + engine + " -o '" +
                                   out.string() + "'");
        ASSERT_EQ(r.status, 0) << r.err;
        const nlohmann::json stats = nlohmann::json::parse(slurp(out / "stats.json"));
        EXPECT_EQ(shader_ops(stats), calls) << engine;
        EXPECT_GT(alpha_dram(stats), 0u) << engine;
        EXPECT_GT(stats["stalls"]["total"]["any_hit_shader"].get<uint64_t>(), 0u);
        EXPECT_GT(stats["energy"]["blocks_pj"]["any_hit_shader"].get<double>(), 0.0);
        if (engine == "fast") fast = stats;
    }
    // The trace replays counter for counter.
    const fs::path replay = dir / "leaves_replay";
    ASSERT_EQ(
        run_rtsim("run -q --trace '" + rtt.string() + "' -o '" + replay.string() + "'").status, 0);
    EXPECT_EQ(fast["counters"], nlohmann::json::parse(slurp(replay / "stats.json"))["counters"]);
    // A costlier shader takes longer; one that reads nothing moves no alpha data.
    const fs::path slow = dir / "leaves_slow", none = dir / "leaves_none";
    ASSERT_EQ(run_rtsim("run -q " + w + " --set any_hit_shader.latency_cycles=400 -o '" +
                        slow.string() + "'")
                  .status,
              0);
    ASSERT_EQ(run_rtsim("run -q " + w + " --set any_hit_shader.alpha_read_bytes=0 -o '" +
                        none.string() + "'")
                  .status,
              0);
    const nlohmann::json s = nlohmann::json::parse(slurp(slow / "stats.json")),
                         n = nlohmann::json::parse(slurp(none / "stats.json"));
    EXPECT_GT(s["total_cycles"].get<uint64_t>(), fast["total_cycles"].get<uint64_t>());
    EXPECT_EQ(shader_ops(n), calls);
    EXPECT_EQ(alpha_dram(n), 0u);
}

// Treelet queues over a two-level scene: both engines run it with treelet loads that include
// the TLAS treelets' instance records, the hits are those of the run without treelets, and a
// trace (whose header carries the treelet tables, instance runs included) replays exactly.
TEST(Run, TreeletQueuesRunOverTwoLevelScenes) {
    const fs::path dir = work_dir();
    const fs::path scene = spheres_on_a_floor(dir / "treelets.json", 5, 0.15);
    const std::string w = "--rays primary,ao --res 40x40 --scene '" + scene.string() + "'";
    const std::string treelets = " --config '" + std::string(RTSIM_SOURCE_DIR) +
                                 "/configs/treelet.json' --set traversal.treelet_prefetch=true";
    const fs::path plain = dir / "tl_plain";
    ASSERT_EQ(run_rtsim("run -q " + w + " -o '" + plain.string() + "'").status, 0);
    const json base = stats_of(plain);
    json fast;
    for (const std::string engine : {"fast", "accurate"}) {
        const fs::path out = dir / ("tl_" + engine);
        const Result r = run_rtsim("run -q " + w + treelets + " --set sim.fidelity=" + engine +
                                   " -o '" + out.string() + "'");
        ASSERT_EQ(r.status, 0) << r.err;
        const json s = stats_of(out);
        EXPECT_GT(s["bvh"]["layout"]["treelets"].get<uint64_t>(), 2u) << engine;
        EXPECT_GT(s["ray_buffer"]["treelet_loads"].get<uint64_t>(), 0u) << engine;
        EXPECT_GT(s["ray_buffer"]["crossings_per_ray"].get<double>(), 0.0) << engine;
        EXPECT_EQ(s["rays"]["hits_by_kind"], base["rays"]["hits_by_kind"]) << engine;
        if (engine == "fast") fast = s;
    }
    const fs::path rtt = dir / "tl.rtt", replay = dir / "tl_replay";
    ASSERT_EQ(run_rtsim("trace -q " + w + treelets + " -o '" + rtt.string() + "'").status, 0);
    const Result r = run_rtsim("run -q --trace '" + rtt.string() + "'" + treelets + " -o '" +
                               replay.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(stats_of(replay)["counters"], fast["counters"]);
}

// A scene file's meshes and BLASes go through the mesh and BVH caches: the second run reads
// every BLAS back and simulates the same counters.
TEST(Run, SceneFileBlasesAreCachedAcrossRuns) {
    const fs::path dir = work_dir();
    const fs::path scene = dir / "cached.json", cache = dir / "scene-cache";
    fs::remove_all(cache);
    std::ofstream(scene) << R"({"meshes": {"c": "builtin:cornell", "b": ")" RTSIM_BUNNY_OBJ R"("},
        "instances": [{"mesh": "c"}, {"mesh": "b", "scale": 4, "grid": {"count": [2, 1, 2],
                       "spacing": [0.6, 0, 0.6]}}]})";
    json stats[2];
    for (int k = 0; k < 2; ++k) {
        const fs::path out = dir / ("cached" + std::to_string(k));
        const Result r =
            run_rtsim("run -q --res 32x32 --rays primary,ao --scene '" + scene.string() +
                      "' --bvh-cache '" + cache.string() + "' -o '" + out.string() + "'");
        ASSERT_EQ(r.status, 0) << r.err;
        stats[k] = stats_of(out);
    }
    EXPECT_EQ(stats[0]["host"]["bvh_cache"], "0 of 2 BLASes hit");
    EXPECT_EQ(stats[1]["host"]["bvh_cache"], "2 of 2 BLASes hit");
    EXPECT_EQ(stats[0]["counters"], stats[1]["counters"]);
}

// A glTF file whose nodes share meshes (the milk truck's two wheels) runs as instances: one
// BLAS per shared mesh, an instance per node, transform steps timed; and replays exactly.
TEST(Run, GltfWithSharedMeshesRunsAsInstances) {
    const fs::path truck = fs::path(RTSIM_ASSIMP_MODEL_DIR) / "CesiumMilkTruck.gltf";
    ASSERT_TRUE(fs::exists(truck)) << "run scripts/setup.sh";
    const fs::path dir = work_dir();
    const std::string w = "--rays primary,ao --res 40x40 --scene '" + truck.string() + "'";
    const fs::path rtt = dir / "truck.rtt", direct = dir / "truck", replay = dir / "truck_replay";
    ASSERT_EQ(run_rtsim("trace -q " + w + " -o '" + rtt.string() + "'").status, 0);
    const Result r = run_rtsim("run -q " + w + " -o '" + direct.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    ASSERT_EQ(
        run_rtsim("run -q --trace '" + rtt.string() + "' -o '" + replay.string() + "'").status, 0);
    const nlohmann::json a = nlohmann::json::parse(slurp(direct / "stats.json")),
                         b = nlohmann::json::parse(slurp(replay / "stats.json"));
    EXPECT_EQ(a["scene"]["instances"], 5);
    EXPECT_EQ(a["scene"]["meshes"], 4);
    EXPECT_EQ(a["bvh"]["levels"], 2);
    EXPECT_GT(a["units"]["transform_unit_total"]["ops"].get<uint64_t>(), 0u);
    EXPECT_EQ(a["counters"], b["counters"]);
    // --flatten: one mesh of every placement, one level.
    const fs::path flat = dir / "truck_flat";
    ASSERT_EQ(run_rtsim("run -q --flatten " + w + " -o '" + flat.string() + "'").status, 0);
    const nlohmann::json f = nlohmann::json::parse(slurp(flat / "stats.json"));
    EXPECT_FALSE(f["scene"].contains("instances"));
    EXPECT_EQ(f["scene"]["triangles"], a["scene"]["instanced_triangles"]);
    EXPECT_EQ(f["units"]["transform_unit_total"]["ops"].get<uint64_t>(), 0u);
    // What two levels cannot do yet is refused in one line that names the way out.
    expect_one_line_error(run_rtsim("trace --packet 8 " + w), "add --flatten");
    expect_one_line_error(run_rtsim("run " + w + " --set traversal.mode=packet"), "add --flatten");
}

TEST(Trace, PacketsReportUtilisationAndKeepHits) {
    const fs::path a = work_dir() / "single.csv", b = work_dir() / "packets.csv";
    ASSERT_EQ(
        run_rtsim("trace -q --rays primary,ao --res 48x48 --hits '" + a.string() + "'").status, 0);
    const Result r =
        run_rtsim("trace --rays primary,ao --res 48x48 --packet 16 --packet-switch 0.25 --hits '" +
                  b.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("lane utilisation"), std::string::npos) << r.out;
    // Same rays, same hit or miss per ray. (AO rays are any-hit queries: which hit is found first
    // depends on the traversal order, so t may differ; the unit tests compare closest-hit t.)
    auto hit_or_miss = [](const std::string& csv) {
        std::vector<std::string> rows;
        std::istringstream in(csv);
        for (std::string line; std::getline(in, line);)
            rows.push_back(line.substr(0, line.find(',')) +
                           (line.find(",inf,") != std::string::npos ? " miss" : " hit"));
        return rows;
    };
    EXPECT_EQ(hit_or_miss(slurp(a)), hit_or_miss(slurp(b)));
    expect_one_line_error(run_rtsim("trace --packet 65"), "--packet");
    expect_one_line_error(
        run_rtsim("trace --chunk-rays 0 -o '" + (work_dir() / "never.rtt").string() + "'"),
        "--chunk-rays");
    expect_one_line_error(run_rtsim("trace --packet 8 --packet-switch 2"), "--packet-switch");
}

TEST(TraceFileRun, RecordThenReplayGivesIdenticalStats) {
    const fs::path rtt = work_dir() / "frame.rtt", live = work_dir() / "live",
                   replay = work_dir() / "replay";
    const std::string rays = "--rays primary,shadow,ao,diffuse --res 40x40 --set bvh.width=4";
    ASSERT_EQ(run_rtsim("trace -q " + rays + " --chunk-rays 500 -o '" + rtt.string() + "'").status,
              0);
    ASSERT_EQ(run_rtsim("run -q " + rays + " --out '" + live.string() + "'").status, 0);
    const Result r = run_rtsim("run --set bvh.width=4 --trace '" + rtt.string() + "' --out '" +
                               replay.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("replayed from"), std::string::npos);
    const json a = stats_of(live), b = stats_of(replay);
    EXPECT_EQ(without_host(a), without_host(b));
    EXPECT_GT(a["rays"]["total"].get<uint64_t>(), 1600u);
}

// A version-1 trace (recorded before the step byte widened; tests/data holds one made by the
// last version-1 build) replays with exactly the stats of the same rays generated on the fly,
// and the Python reader reads it as rtsim does.
TEST(TraceFileRun, VersionOneTracesStillReplay) {
    const std::string v1 = std::string(RTSIM_SOURCE_DIR) + "/tests/data/cornell_16x16_v1.rtt";
    const fs::path live = work_dir() / "v1_live", replay = work_dir() / "v1_replay";
    ASSERT_EQ(run_rtsim("run -q --rays primary,shadow --res 16x16 --set bvh.width=4 --out '" +
                        live.string() + "'")
                  .status,
              0);
    const Result r =
        run_rtsim("run -q --set bvh.width=4 --trace '" + v1 + "' --out '" + replay.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json a = stats_of(live), b = stats_of(replay);
    EXPECT_EQ(without_host(a), without_host(b));
    const Result info = run_rtsim("trace-info --json '" + v1 + "'");
    ASSERT_EQ(info.status, 0) << info.err;
    EXPECT_EQ(json::parse(info.out)["format_version"], 1);
}

TEST(TraceFileRun, MismatchedLayoutOrOptionsAreRefused) {
    const fs::path rtt = work_dir() / "w8.rtt";
    ASSERT_EQ(run_rtsim("trace -q --res 16x16 --set bvh.width=8 -o '" + rtt.string() + "'").status,
              0);
    expect_one_line_error(run_rtsim("run --trace '" + rtt.string() + "'"),
                          "recorded with bvh.width=8");
    expect_one_line_error(
        run_rtsim("run --set bvh.width=8 --set bvh.node_format=compressed --trace '" +
                  rtt.string() + "'"),
        "bvh.node_format");
    expect_one_line_error(
        run_rtsim("run --set bvh.width=8 --set box_unit.mantissa_bits=10 --trace '" + rtt.string() +
                  "'"),
        "recorded with box_unit.mantissa_bits=23");
    expect_one_line_error(
        run_rtsim("run --set bvh.width=8 --scene builtin:sphere --trace '" + rtt.string() + "'"),
        "--scene: cannot be combined with --trace");
    EXPECT_EQ(run_rtsim("run --set bvh.width=8 --trace '" + rtt.string() + "' -o '" +
                        (work_dir() / "ok").string() + "'")
                  .status,
              0);
}

TEST(TraceFileRun, BadTracesExitTwoNamingTheDamage) {
    const fs::path rtt = work_dir() / "good.rtt";
    ASSERT_EQ(run_rtsim("trace -q --rays primary,ao --res 32x32 --chunk-rays 300 -o '" +
                        rtt.string() + "'")
                  .status,
              0);
    const std::string bytes = slurp(rtt);
    auto damaged = [&](const std::string& name, std::string b) {
        const fs::path p = work_dir() / name;
        std::ofstream(p, std::ios::binary) << b;
        return p.string();
    };
    expect_one_line_error(
        run_rtsim("run --trace '" + damaged("trunc.rtt", bytes.substr(0, bytes.size() - 100)) +
                  "'"),
        "footer missing");
    std::string flipped = bytes;
    flipped[bytes.size() / 2] ^= 0x20;
    const Result r = run_rtsim("run -q --trace '" + damaged("flip.rtt", flipped) + "'");
    expect_one_line_error(r, "chunk");
    EXPECT_EQ(r.out, "");  // quiet: not even the kernel's note that the run was stopped
    std::string magic = bytes;
    magic[0] = 'X';
    expect_one_line_error(run_rtsim("trace-info '" + damaged("magic.rtt", magic) + "'"),
                          "wrong magic");
    std::string version = bytes;
    version[8] = 7;
    expect_one_line_error(run_rtsim("trace-info '" + damaged("version.rtt", version) + "'"),
                          "unknown trace format version 7");
    expect_one_line_error(run_rtsim("trace-info '" + (work_dir() / "none.rtt").string() + "'"),
                          "cannot open");
    EXPECT_FALSE(fs::exists(work_dir() / "never"));
}

TEST(TraceFileRun, TraceInfoAndPythonReaderAgree) {
    const fs::path rtt = work_dir() / "info.rtt";
    ASSERT_EQ(run_rtsim("trace -q --rays primary,ao,reflection --res 24x24 --chunk-rays 100 -o '" +
                        rtt.string() + "'")
                  .status,
              0);
    const Result info = run_rtsim("trace-info --json '" + rtt.string() + "'");
    ASSERT_EQ(info.status, 0) << info.err;
    const json ours = json::parse(info.out);
    const fs::path py_out = work_dir() / "py.json";
    const std::string cmd = fmt::format("python3 '{}/scripts/rtt_reader.py' --json '{}' > '{}'",
                                        RTSIM_SOURCE_DIR, rtt.string(), py_out.string());
    ASSERT_EQ(std::system(cmd.c_str()), 0)
        << "scripts/rtt_reader.py failed (python3 and zstd are set up by setup.sh)";
    const json theirs = json::parse(slurp(py_out));
    EXPECT_EQ(ours["rays"], theirs["rays"]);
    EXPECT_EQ(ours["steps"], theirs["steps"]);
    EXPECT_EQ(ours["chunks"], theirs["chunks"]);
    for (const char* kind : {"primary", "ao", "reflection"})
        for (const char* f : {"rays", "hits", "node_steps", "triangle_steps"})
            EXPECT_EQ(ours["by_kind"][kind][f], theirs["by_kind"][kind][f]) << kind << " " << f;
    const Result text = run_rtsim("trace-info '" + rtt.string() + "'");
    EXPECT_NE(text.out.find("bytes per step"), std::string::npos);
    EXPECT_NE(text.out.find("nodes "), std::string::npos);
}

// A trace of a two-level scene with non-opaque instances (format version 4: each hit's
// instance recorded) read by the Python reader, written apart from rtsim's, and by trace-info;
// and a version-3 trace of a two-level scene (tests/data, recorded by the last version-3 build)
// still replays, with the cycles that build simulated (10,962) for the same rays.
TEST(TraceFileRun, TwoLevelTracesOfBothVersionsRead) {
    const fs::path dir = work_dir();
    const fs::path scene = dir / "v4.json";
    std::ofstream(scene) << R"({"meshes": {"c": "builtin:cornell",
            "s": {"file": "builtin:sphere", "alpha": {"pattern": "triangles", "keep": 0.5}}},
        "instances": [{"mesh": "c", "translate": [-1, -1, -2.5]},
                      {"mesh": "s", "scale": 0.3, "grid": {"count": [4, 4, 1],
                       "spacing": [0.5, 0.5, 0]}, "translate": [-0.75, -0.75, 0]}]})";
    const fs::path rtt = dir / "v4.rtt";
    ASSERT_EQ(run_rtsim("trace -q --rays primary,ao --res 24x24 --chunk-rays 100 --scene '" +
                        scene.string() + "' -o '" + rtt.string() + "'")
                  .status,
              0);
    const Result info = run_rtsim("trace-info --json '" + rtt.string() + "'");
    ASSERT_EQ(info.status, 0) << info.err;
    const json ours = json::parse(info.out);
    EXPECT_EQ(ours["format_version"], 4);
    const fs::path py_out = dir / "v4py.json";
    ASSERT_EQ(std::system(fmt::format("python3 '{}/scripts/rtt_reader.py' --json '{}' > '{}'",
                                      RTSIM_SOURCE_DIR, rtt.string(), py_out.string())
                              .c_str()),
              0);
    const json theirs = json::parse(slurp(py_out));
    EXPECT_EQ(ours["steps"], theirs["steps"]);
    for (const char* kind : {"primary", "ao"})
        for (const char* f :
             {"rays", "hits", "node_steps", "triangle_steps", "transform_steps", "any_hit_steps"})
            EXPECT_EQ(ours["by_kind"][kind][f], theirs["by_kind"][kind][f]) << kind << " " << f;
    EXPECT_GT(ours["by_kind"]["primary"]["any_hit_steps"].get<uint64_t>(), 0u);

    const std::string v3 = std::string(RTSIM_SOURCE_DIR) + "/tests/data/copies_16x16_v3.rtt";
    const fs::path replay = dir / "v3_replay";
    const Result r = run_rtsim("run -q --trace '" + v3 + "' --out '" + replay.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(stats_of(replay)["total_cycles"], 10962);
    const Result v3info = run_rtsim("trace-info --json '" + v3 + "'");
    ASSERT_EQ(v3info.status, 0) << v3info.err;
    EXPECT_EQ(json::parse(v3info.out)["format_version"], 3);
}

TEST(Run, StallAttributionAccountsForEverySlotCycle) {
    const fs::path out = work_dir() / "stalls";
    const Result r = run_rtsim(
        "run -q --rays primary,ao --res 48x48 --set core.count=3 --set core.ray_slots=5 "
        "--set box_unit.width=2 --set bvh.width=8 --out '" +
        out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    const char* causes[] = {"issue", "l1", "l2", "dram", "crossbar", "box_unit", "triangle_unit"};
    uint64_t latency = 0, charged = 0;
    for (int c = 0; c < 3; ++c) {
        const json& e = s["stalls"][fmt::format("core[{}]", c)];
        uint64_t core_charged = 0;
        for (const char* k : causes) core_charged += e[k].get<uint64_t>();
        // Charged cycles are exactly the cycles the core's slots held rays (measured separately).
        EXPECT_EQ(core_charged,
                  s["counters"][fmt::format("core[{}].ray_latency_cycles", c)].get<uint64_t>());
        EXPECT_EQ(core_charged + e["no_work"].get<uint64_t>(),
                  5 * s["total_cycles"].get<uint64_t>());
        latency += s["counters"][fmt::format("core[{}].ray_latency_cycles", c)].get<uint64_t>();
        charged += core_charged;
    }
    EXPECT_EQ(latency, charged);
    double shares = 0;
    for (auto& [k, v] : s["stalls"]["total"]["share"].items()) shares += v.get<double>();
    EXPECT_NEAR(shares, 1.0, 1e-9);
    EXPECT_GT(s["stalls"]["total"]["box_unit"].get<uint64_t>(), 0u);
    EXPECT_GT(s["stalls"]["total"]["dram"].get<uint64_t>(), 0u);
    EXPECT_GT(s["stalls"]["total"]["crossbar"].get<uint64_t>(), 0u);
    // 8-wide nodes on a 2-wide box unit: several operations per node visit.
    EXPECT_GT(s["units"]["box_unit_total"]["ops"].get<uint64_t>(),
              s["counters"]["core[0].steps"].get<uint64_t>() / 2);
}

TEST(Run, TimeSeriesAddUpToTheTotals) {
    const fs::path out = work_dir() / "series", plain = work_dir() / "plain";
    ASSERT_EQ(run_rtsim("run -q --rays primary,ao --res 40x40 --set sim.window_cycles=5000 --set "
                        "clock_ghz=2 --out '" +
                        out.string() + "'")
                  .status,
              0);
    const json s = stats_of(out);
    const json& t = s["time_series"];
    const uint64_t windows = t["windows"];
    EXPECT_EQ(windows, (s["total_cycles"].get<uint64_t>() + 4999) / 5000);
    const double window_s = 5000 / 2e9;
    double rays = 0, dram = 0, l2 = 0, box_busy = 0;
    for (size_t w = 0; w < windows; ++w) {
        rays += t["rays"][w].get<double>();
        dram += t["dram_gbps"][w].get<double>() * 1e9 * window_s;
        l2 += t["l2_to_l1_gbps"][w].get<double>() * 1e9 * window_s;
        box_busy +=
            t["box_unit_utilization"][w].get<double>() * 5000 * 8;  // 8 cores, 1 pipeline each
        EXPECT_LE(t["box_unit_utilization"][w].get<double>(), 1.0);
    }
    EXPECT_EQ(uint64_t(rays), s["rays"]["total"].get<uint64_t>());
    EXPECT_NEAR(dram, s["bandwidth"]["dram"]["bytes"].get<double>(), 1e-6 * dram + 1);
    EXPECT_NEAR(l2, s["bandwidth"]["l2"]["bytes"].get<double>(), 1e-6 * l2 + 1);
    EXPECT_NEAR(box_busy, s["units"]["box_unit_total"]["busy_cycles"].get<double>(),
                1e-6 * box_busy + 1);
    // Off by default: no series, and the same simulated result.
    ASSERT_EQ(run_rtsim("run -q --rays primary,ao --res 40x40 --set clock_ghz=2 --out '" +
                        plain.string() + "'")
                  .status,
              0);
    const json p = stats_of(plain);
    EXPECT_FALSE(p.contains("time_series"));
    EXPECT_EQ(p["total_cycles"], s["total_cycles"]);
}

TEST(Run, IdealModesBoundTheAchievedRate) {
    const fs::path real = work_dir() / "real", ideal = work_dir() / "ideal";
    const std::string rays = "run -q --rays primary,ao --res 40x40 ";
    const Result r = run_rtsim(rays + "--bound --out '" + real.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    ASSERT_EQ(run_rtsim(rays + "--set sim.ideal_memory=true --set sim.ideal_units=true --out '" +
                        ideal.string() + "'")
                  .status,
              0);
    const json s = stats_of(real), i = stats_of(ideal);
    // The child run behind --bound is the ideal run of the same rays.
    EXPECT_EQ(s["bound"]["total_cycles"], i["total_cycles"]);
    EXPECT_LT(i["total_cycles"].get<uint64_t>(), s["total_cycles"].get<uint64_t>());
    const double ratio = s["bound"]["achieved_over_bound"];
    EXPECT_GT(ratio, 0.0);
    EXPECT_LT(ratio, 1.0);
    // Ideal memory: no L2 or DRAM time, no queueing at units.
    EXPECT_EQ(i["stalls"]["total"]["l2"].get<uint64_t>(), 0u);
    EXPECT_EQ(i["stalls"]["total"]["dram"].get<uint64_t>(), 0u);
    EXPECT_EQ(i["units"]["box_unit[0]"]["queue_cycles"].get<uint64_t>(), 0u);
    EXPECT_EQ(i["rays"]["total"], s["rays"]["total"]);
}

TEST(Run, UnitsSharedAmongCoresContend) {
    const fs::path own = work_dir() / "own", shared = work_dir() / "shared",
                   again = work_dir() / "again";
    const std::string base = "run -q --rays primary,ao --res 40x40 ";
    ASSERT_EQ(run_rtsim(base + "--out '" + own.string() + "'").status, 0);
    const std::string share = "--set box_unit.shared_by=4 --set triangle_unit.shared_by=3 ";
    ASSERT_EQ(run_rtsim(base + share + "--out '" + shared.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(base + share + "--out '" + again.string() + "'").status, 0);
    const json a = stats_of(own), b = stats_of(shared);
    EXPECT_TRUE(b["units"].contains("box_unit[1]"));
    EXPECT_FALSE(b["units"].contains("box_unit[2]"));      // 8 cores, 4 per box unit
    EXPECT_TRUE(b["units"].contains("triangle_unit[2]"));  // 8 cores, 3 per triangle unit: 3 units
    EXPECT_FALSE(b["units"].contains("triangle_unit[3]"));
    // The same work, on fewer units: more queueing, never faster.
    EXPECT_EQ(a["units"]["box_unit_total"]["ops"], b["units"]["box_unit_total"]["ops"]);
    EXPECT_GE(b["total_cycles"].get<uint64_t>(), a["total_cycles"].get<uint64_t>());
    EXPECT_GT(b["stalls"]["total"]["box_unit"].get<uint64_t>(),
              a["stalls"]["total"]["box_unit"].get<uint64_t>());
    EXPECT_EQ(without_host(b), without_host(stats_of(again)));
}

TEST(Run, SplitL1SeparatesNodesFromTriangles) {
    const fs::path out = work_dir() / "split";
    const Result r = run_rtsim(
        "run -q --rays primary,ao --res 40x40 --set l1.split=true --set l1.size_kib=4 "
        "--set crossbar.bytes_per_cycle=0 --out '" +
        out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    ASSERT_TRUE(s["caches"].contains("l1_tri[0]"));
    EXPECT_FALSE(s["bandwidth"].contains("crossbar"));  // 0: no crossbar block at all
    // Node fetches go to l1[i], triangle fetches to l1_tri[i]: their accesses add up to all L1
    // accesses, and every L1 miss of either is one L2 access.
    uint64_t node = 0, tri = 0;
    for (int i = 0; i < 8; ++i) {
        node += s["caches"][fmt::format("l1[{}]", i)]["accesses"].get<uint64_t>();
        tri += s["caches"][fmt::format("l1_tri[{}]", i)]["accesses"].get<uint64_t>();
    }
    EXPECT_GT(node, 0u);
    EXPECT_GT(tri, 0u);
    EXPECT_EQ(node + tri, s["caches"]["l1_total"]["accesses"].get<uint64_t>());
    EXPECT_EQ(s["caches"]["l2"]["accesses"], s["caches"]["l1_total"]["misses"]);
}

// Treelet mode: the same rays and hits as the baseline, every step run once, stall attribution
// still accounts for every slot cycle, identical stats from a rerun and from a replayed trace.
TEST(TreeletMode, SameWorkAsBaselineDeterministicAndReplayable) {
    const std::string rays =
        "--scene " RTSIM_BUNNY_OBJ " --rays primary,diffuse --res 40x40 --set bvh.width=4 ";
    const std::string treelet =
        "--set bvh.treelet_bytes=4096 --set traversal.mode=treelet --set "
        "ray_buffer.capacity_rays=256 ";
    const fs::path base = work_dir() / "base", a = work_dir() / "a", b = work_dir() / "b",
                   replay = work_dir() / "replay", trace = work_dir() / "t.rtt";
    ASSERT_EQ(run_rtsim("run -q " + rays + "--out '" + base.string() + "'").status, 0);
    Result r = run_rtsim("run -q " + rays + treelet + "--out '" + a.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    ASSERT_EQ(run_rtsim("run -q " + rays + treelet + "--out '" + b.string() + "'").status, 0);
    r = run_rtsim("trace -q " + rays + treelet + "-o '" + trace.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    r = run_rtsim("run -q --trace '" + trace.string() + "' --set bvh.width=4 " + treelet +
                  "--out '" + replay.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json sb = stats_of(base), sa = stats_of(a);
    expect_complete_stats(sa);
    EXPECT_EQ(sa["rays"]["total"], sb["rays"]["total"]);
    EXPECT_EQ(sa["rays"]["hits_by_kind"], sb["rays"]["hits_by_kind"]);
    EXPECT_EQ(sa["rays"]["steps"], sb["rays"]["steps"]);
    uint64_t done = 0, steps = 0, latency = 0, charged = 0;
    for (int c = 0; c < 8; ++c) {
        const std::string core = fmt::format("core[{}]", c);
        done += sa["counters"][core + ".rays"].get<uint64_t>();
        steps += sa["counters"][core + ".steps"].get<uint64_t>();
        latency += sa["counters"][core + ".ray_latency_cycles"].get<uint64_t>();
        for (auto& [k, v] : sa["stalls"][core].items())
            if (k != "no_work" && k != "slot_cycles" && k != "share") charged += v.get<uint64_t>();
    }
    EXPECT_EQ(done, sa["rays"]["total"].get<uint64_t>());
    EXPECT_EQ(steps, sa["rays"]["steps"].get<uint64_t>());
    EXPECT_EQ(charged, latency);
    const json& rb = sa["ray_buffer"];
    EXPECT_GT(rb["crossings"].get<uint64_t>(), 0u);
    EXPECT_GT(rb["treelet_loads"].get<uint64_t>(), 0u);
    EXPECT_LE(rb["peak_rays"].get<uint64_t>(), 256u);
    EXPECT_GT(rb["admission_blocked"].get<uint64_t>(), 0u);  // 256 rays of room for ~2000
    EXPECT_GT(sa["stalls"]["total"]["ray_buffer"].get<uint64_t>(), 0u);
    EXPECT_EQ(without_host(sa), without_host(stats_of(b)));
    EXPECT_EQ(sa["counters"], stats_of(replay)["counters"]);
}

TEST(TreeletMode, SchedulersAndDemandFetchRunTheSameRays) {
    const std::string rays =
        "--scene " RTSIM_BUNNY_OBJ
        " --rays ao --res 32x32 --set bvh.width=8 --set bvh.treelet_bytes=8192 "
        "--set traversal.mode=treelet ";
    uint64_t total = 0;
    for (const char* extra : {"--set traversal.treelet_scheduler=round_robin",
                              "--set traversal.treelet_prefetch=false"}) {
        const fs::path out = work_dir() / (std::string("v") + std::to_string(total));
        const Result r = run_rtsim("run -q " + rays + extra + " --out '" + out.string() + "'");
        ASSERT_EQ(r.status, 0) << r.err;
        const json s = stats_of(out);
        if (total) {
            EXPECT_EQ(s["rays"]["total"].get<uint64_t>(), total);
        }
        total = s["rays"]["total"].get<uint64_t>();
        if (std::string(extra).find("prefetch") != std::string::npos) {
            EXPECT_EQ(s["ray_buffer"]["treelet_loads"].get<uint64_t>(), 0u);
        }
    }
}

TEST(TreeletMode, BadCombinationsAreRefused) {
    expect_one_line_error(run_rtsim("run -q --res 8x8 --set traversal.mode=treelet"),
                          "bvh.treelet_bytes is 0");
    const fs::path trace = work_dir() / "t.rtt";
    ASSERT_EQ(run_rtsim("trace -q --res 8x8 -o '" + trace.string() + "'").status, 0);
    expect_one_line_error(
        run_rtsim("run -q --trace '" + trace.string() + "' --set traversal.mode=packet"),
        "traversal.mode=packet needs rays generated on the fly");
    expect_one_line_error(run_rtsim("run -q --res 8x8 --set traversal.mode=wavefront"),
                          "traversal.mode");
}

// Packet mode: the same rays and hits; lanes are counted and operations occupy every lane, so
// unit work grows as utilisation falls, while node fetches are shared by the packet's rays.
TEST(PacketMode, SameRaysFewerFetchesLaneUtilisationReported) {
    const std::string rays = "--rays primary,diffuse --res 48x48 --set bvh.width=4 ";
    const fs::path base = work_dir() / "base", pk = work_dir() / "packet";
    ASSERT_EQ(run_rtsim("run -q " + rays + "--out '" + base.string() + "'").status, 0);
    const Result r = run_rtsim("run -q " + rays +
                               "--set traversal.mode=packet --set traversal.packet_size=8 --out '" +
                               pk.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json sb = stats_of(base), sp = stats_of(pk);
    expect_complete_stats(sp);
    EXPECT_EQ(sp["rays"]["total"], sb["rays"]["total"]);
    EXPECT_EQ(sp["rays"]["hits_by_kind"], sb["rays"]["hits_by_kind"]);
    const double util = sp["packets"]["lane_utilization"];
    EXPECT_GT(util, 0.05);
    EXPECT_LT(util, 1.0);
    uint64_t steps = 0;
    for (int c = 0; c < 8; ++c)
        steps += sp["counters"][fmt::format("core[{}].steps", c)].get<uint64_t>();
    EXPECT_EQ(sp["packets"]["lane_slots"].get<uint64_t>(), 8 * steps);
    EXPECT_LT(sp["bandwidth"]["l1"]["bytes"].get<uint64_t>(),
              sb["bandwidth"]["l1"]["bytes"].get<uint64_t>());
    EXPECT_FALSE(sb.contains("packets"));
}

TEST(Configs, EveryCommittedConfigLoads) {
    int checked = 0;
    for (const auto& e : fs::directory_iterator(fs::path(RTSIM_SOURCE_DIR) / "configs")) {
        if (e.path().extension() != ".json" || e.path().filename() == "schema.json") continue;
        const Result r = run_rtsim("config --config '" + e.path().string() + "'");
        EXPECT_EQ(r.status, 0) << e.path() << ": " << r.err;
        ++checked;
    }
    EXPECT_GE(checked, 3);
}

// A dedicated treelet cache takes the batch loads: the rays' fetches hit there.
TEST(TreeletMode, DedicatedTreeletCacheServesTheBatches) {
    const fs::path out = work_dir() / "tc";
    const Result r =
        run_rtsim("run -q --config '" + std::string(RTSIM_SOURCE_DIR) +
                  "/configs/treelet.json' --rays ao --res 32x32 "
                  "--set traversal.treelet_prefetch=true --set traversal.treelet_cache_kib=16 "
                  "--out '" +
                  out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    ASSERT_TRUE(s["caches"].contains("treelet_cache_total"));
    // Its hits never reach the L1: the L1 sees only its misses and the treelet loads.
    EXPECT_GT(s["caches"]["treelet_cache_total"]["hits"].get<uint64_t>(), 0u);
    EXPECT_LT(s["caches"]["l1_total"]["accesses"].get<uint64_t>(),
              s["caches"]["treelet_cache_total"]["accesses"].get<uint64_t>());
    EXPECT_GT(s["ray_buffer"]["treelet_loads"].get<uint64_t>(), 0u);
    expect_one_line_error(run_rtsim("run -q --config '" + std::string(RTSIM_SOURCE_DIR) +
                                    "/configs/treelet.json' --res 8x8 --set "
                                    "traversal.treelet_cache_kib=8 --set l1.split=true"),
                          "treelet_cache_kib");
}

// Two designs on the same rays, compared as an architect would.
TEST(Compare, TwoRunsSideBySide) {
    const fs::path a = work_dir() / "compare_small_l1";
    const fs::path b = work_dir() / "compare_big_l1";
    const std::string args = "run -q --rays primary,ao --res 32x32 --set core.count=2";
    ASSERT_EQ(run_rtsim(args + " --set l1.size_kib=4 --out '" + a.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(args + " --set l1.size_kib=64 --out '" + b.string() + "'").status, 0);
    const fs::path table = work_dir() / "compare.json", drawing = work_dir() / "compare.svg";
    const Result r = run_rtsim(
        fmt::format("compare '{}' '{}/stats.json' --labels small,big --json '{}' --svg '{}'",
                    a.string(), b.string(), table.string(), drawing.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("config: l1.size_kib"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("4 | 64"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("big vs small"), std::string::npos) << r.out;
    std::ifstream svg(drawing);
    const std::string svg_text((std::istreambuf_iterator<char>(svg)), {});
    EXPECT_EQ(svg_text.rfind("<svg", 0), 0u);
    EXPECT_NE(svg_text.find(">big</text>"), std::string::npos);
    // Only the L1 size differs: the JSON lists that one setting, and the bigger L1 hits more.
    const json j = json::parse(std::ifstream(table));
    EXPECT_EQ(j["differences"].size(), 1u) << j["differences"].dump();
    const json sa = stats_of(a), sb = stats_of(b);
    bool found = false;
    for (const auto& m : j["metrics"]) {
        if (m["name"] != "L1 hit rate") continue;
        found = true;
        EXPECT_DOUBLE_EQ(m["values"][0].get<double>(),
                         sa["caches"]["l1_total"]["hit_rate"].get<double>());
        EXPECT_DOUBLE_EQ(m["values"][1].get<double>(),
                         sb["caches"]["l1_total"]["hit_rate"].get<double>());
        EXPECT_GT(m["relative"][1].get<double>(), 0.0);
    }
    EXPECT_TRUE(found);
}

// Two sampled designs of one frame measured on the same units (same seed and design): compare
// estimates their difference from each unit's difference. With the same auxiliaries the GREG
// estimator is linear in y, so the difference of the cycles is exactly the difference of the two
// runs' estimates; its interval is narrower than either run's own, since the units where one
// design is slow are where the other is (at 1024x1024, 1 in 20: +-0.4 to 0.9 points of a 47%
// difference, against +-1.1 to 4.1% for each run). A run against itself differs by exactly 0; runs
// with other units are no pair, and compare says why.
TEST(Compare, MatchedSamplesGiveTheDifferenceAnInterval) {
    const std::string frame =
        "run -q --scene " RTSIM_BUNNY_OBJ
        " --rays ao --res 512x512 --set sim.sampled=true --set sim.sample_fast_forward=skip "
        "--set sim.sample_design=work --set sim.sample_period_units=10 ";
    const fs::path a = work_dir() / "match_a", b = work_dir() / "match_b",
                   other = work_dir() / "match_other", cmp = work_dir() / "match.json";
    ASSERT_EQ(run_rtsim(frame + "-o '" + a.string() + "'").status, 0);
    ASSERT_EQ(run_rtsim(frame +
                        "--set box_unit.latency_cycles=16 --set triangle_unit.latency_cycles=36 "
                        "-o '" +
                        b.string() + "'")
                  .status,
              0);
    ASSERT_EQ(run_rtsim(frame + "--set sim.sample_seed=77 -o '" + other.string() + "'").status, 0);
    const Result r = run_rtsim(fmt::format("compare '{}' '{}' '{}' '{}' --json '{}'", a.string(),
                                           b.string(), a.string(), other.string(), cmp.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("Matched samples"), std::string::npos) << r.out;
    const json c = json::parse(std::ifstream(cmp));
    ASSERT_EQ(c["matched"].size(), 3u) << c;
    const json sa = stats_of(a)["sampling"], sb = stats_of(b)["sampling"];
    const json& d = c["matched"][0]["differences"]["cycles"];
    const double separate =
        sb["total_cycles"]["value"].get<double>() - sa["total_cycles"]["value"].get<double>();
    EXPECT_NEAR(d["value"].get<double>(), separate, 1e-6 * std::fabs(separate));
    const double half = d["hi"].get<double>() - d["value"].get<double>();
    EXPECT_GT(half, 0.0);
    for (const json* s : {&sa, &sb}) {
        const json& t = (*s)["total_cycles"];
        EXPECT_LT(half, t["hi"].get<double>() - t["value"].get<double>());
    }
    const json& self = c["matched"][1]["differences"]["cycles"];
    EXPECT_EQ(self["value"].get<double>(), 0.0);
    EXPECT_EQ(self["hi"].get<double>(), 0.0);
    EXPECT_NE(c["matched"][2]["not_matched"].get<std::string>().find("different units"),
              std::string::npos)
        << c["matched"][2];
}

TEST(Compare, BadInputExitsTwoWithOneLineAndWritesNothing) {
    const fs::path other = work_dir() / "not_stats.json";
    std::ofstream(other) << "{\"hello\": 1}";
    const fs::path table = work_dir() / "never.json";
    expect_one_line_error(run_rtsim(fmt::format("compare '{}' '{}' --json '{}'", other.string(),
                                                other.string(), table.string())),
                          other.string() + ": not an rtsim stats.json");
    EXPECT_FALSE(fs::exists(table));
    expect_one_line_error(run_rtsim(fmt::format("compare '{}'", other.string())), "at least two");
    EXPECT_EQ(run_rtsim("compare").status, 2);
}

// A sweep as a user runs it: two points on two jobs, one table, each point's full stats.
TEST(Sweep, RunsEveryPointAndWritesOneTable) {
    const fs::path file = work_dir() / "sweep_ways.json";
    std::ofstream(file) << R"({"workload": {"rays": "primary", "res": "24x24"},
                               "set": {"core.count": 2},
                               "vary": {"l1.ways": [1, 8]}})";
    const fs::path out = work_dir() / "sweep_out";
    const Result r = run_rtsim(fmt::format("sweep '{}' -j 2 -o '{}'", file.string(), out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const json table = json::parse(std::ifstream(out / "results.json"));
    ASSERT_EQ(table["points"].size(), 2u);
    for (size_t i = 0; i < 2; ++i) {
        const json& p = table["points"][i];
        EXPECT_EQ(p["values"]["l1.ways"], i == 0 ? "1" : "8");
        const json s = stats_of(out / p["point"].get<std::string>());
        EXPECT_EQ(s["config"]["l1"]["ways"], i == 0 ? 1 : 8);
        EXPECT_EQ(s["config"]["core"]["count"], 2);
        EXPECT_EQ(p["figures"]["cycles"].get<double>(), s["total_cycles"].get<double>());
    }
    // The same rays on both points; the table lists them in order, and the CSV has a line each.
    EXPECT_EQ(stats_of(out / table["points"][0]["point"].get<std::string>())["rays"],
              stats_of(out / table["points"][1]["point"].get<std::string>())["rays"]);
    std::ifstream csv(out / "results.csv");
    int lines = 0;
    for (std::string line; std::getline(csv, line);) ++lines;
    EXPECT_EQ(lines, 3);
    EXPECT_NE(r.out.find("l1.ways"), std::string::npos) << r.out;
}

// A sampled sweep paired with its base design: the reference runs first into OUT/reference
// (every unit measured), each point's estimates come from the pair, and its interval holds the
// point's full run (checked for this frame and seed).
TEST(Sweep, APairedSweepRunsItsReferenceFirst) {
    const fs::path file = work_dir() / "sweep_paired.json";
    std::ofstream(file) << R"({"workload": {"scene": ")" RTSIM_BUNNY_OBJ R"(",
                                             "rays": "primary,ao", "res": "96x96"},
                               "set": {"sim.sampled": true, "sim.sample_fast_forward": "skip",
                                       "sim.sample_unit_tiles": 2, "sim.sample_period_units": 4},
                               "vary": {"triangle_unit.latency_cycles": [18, 36]},
                               "reference": true})";
    const fs::path out = work_dir() / "sweep_paired_out";
    const Result r = run_rtsim(fmt::format("sweep '{}' -j 2 -o '{}'", file.string(), out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const json ref = stats_of(out / "reference");
    EXPECT_EQ(ref["sampling"]["period_units"], 1);
    const json table = json::parse(std::ifstream(out / "results.json"));
    ASSERT_EQ(table["points"].size(), 2u);
    // Each sampled point's estimates carry their intervals into the table, JSON and CSV: the
    // cycles' half-width, as the point's own stats.json has it.
    const std::string csv = slurp(out / "results.csv");
    EXPECT_NE(csv.find(",cycles +-%"), std::string::npos) << csv.substr(0, 300);
    for (const json& p : table["points"]) {
        const json s = stats_of(out / p["point"].get<std::string>());
        EXPECT_DOUBLE_EQ(p["intervals"]["cycles"].get<double>(),
                         s["sampling"]["total_cycles"]["half_width_pct"].get<double>());
    }
    // The two points, running at once with one plan, ran the reference's sample once.
    int ran = 0;
    for (size_t i = 0; i < 2; ++i) {
        const json s = stats_of(out / table["points"][i]["point"].get<std::string>());
        ASSERT_TRUE(s["sampling"].contains("reference")) << i;
        ran += s["sampling"]["reference"]["matched_sample"] == "ran";
        EXPECT_EQ(s["sampling"]["reference"]["dir"], fs::absolute(out / "reference").string());
        const fs::path full = work_dir() / fmt::format("sweep_paired_full{}", i);
        ASSERT_EQ(run_rtsim(fmt::format("run --scene " RTSIM_BUNNY_OBJ
                                        " --rays primary,ao --res 96x96 --set "
                                        "triangle_unit.latency_cycles={} -o '{}'",
                                        i == 0 ? 18 : 36, full.string()))
                      .status,
                  0);
        const double truth = stats_of(full)["total_cycles"].get<double>();
        const json& c = s["sampling"]["total_cycles"];
        EXPECT_LE(c["lo"].get<double>(), truth) << i;
        EXPECT_GE(c["hi"].get<double>(), truth) << i;
    }
    EXPECT_EQ(ran, 1);
}

// Plots: a figure per varied axis and the Pareto front the file names, as SVG, and
// PNG when rsvg-convert is installed (setup.sh installs it; without it the PNG part is skipped,
// said so). A figure name that does not exist is refused before anything runs.
TEST(Sweep, WritesAFigurePerAxisAndTheParetoFront) {
    const fs::path file = work_dir() / "sweep_plots.json";
    std::ofstream(file) << R"J({"workload": {"rays": "primary", "res": "24x24"},
                               "vary": {"l1.ways": [1, 8], "core.count": [1, 2]},
                               "pareto": ["cycles", "energy per ray (nJ)"]})J";
    const fs::path out = work_dir() / "sweep_plots";
    const Result r = run_rtsim(fmt::format("sweep '{}' -j 2 -o '{}'", file.string(), out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    for (const char* stem : {"l1.ways", "core.count", "pareto"}) {
        const std::string svg = slurp(out / "plots" / (std::string(stem) + ".svg"));
        ASSERT_FALSE(svg.empty()) << stem;
        EXPECT_EQ(svg.rfind("<svg", 0), 0u) << stem;
        EXPECT_NE(svg.find("</svg>"), std::string::npos) << stem;
    }
    // Against l1.ways: a line per core count in each panel, labelled.
    const std::string ways = slurp(out / "plots" / "l1.ways.svg");
    EXPECT_NE(ways.find(">count=1<"), std::string::npos);
    EXPECT_NE(ways.find(">count=2<"), std::string::npos);
    EXPECT_NE(slurp(out / "plots" / "pareto.svg").find("energy per ray (nJ)"), std::string::npos);
    const Result bad = run_rtsim(fmt::format("sweep '{}' -o '{}' --pareto 'cycles,speed'",
                                             file.string(), (work_dir() / "never").string()));
    expect_one_line_error(bad, "--pareto: 'speed' is not a figure");
    EXPECT_FALSE(fs::exists(work_dir() / "never"));
    if (std::system("command -v rsvg-convert >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "rsvg-convert (librsvg2-bin) is not installed: PNGs not checked";
    for (const char* stem : {"l1.ways", "core.count", "pareto"}) {
        const std::string png = slurp(out / "plots" / (std::string(stem) + ".png"));
        ASSERT_GT(png.size(), 1000u) << stem;
        EXPECT_EQ(png.substr(1, 3), "PNG") << stem;
    }
}

// On a terminal (util-linux's `script` gives the run one), a run shows how far it is with the
// time left and a sweep its points done, running and failed; --quiet and a pipe show nothing.
TEST(Progress, ShownOnATerminalOnly) {
    if (std::system("command -v script >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "util-linux's script is not installed: no terminal to test on";
    const fs::path out = work_dir() / "progress", log = work_dir() / "progress.log";
    auto on_terminal = [&](const std::string& args) {
        const std::string cmd = fmt::format("script -qec \"'{}' {}\" /dev/null > '{}' 2>&1",
                                            RTSIM_BINARY, args, log.string());
        EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
        return slurp(log);
    };
    const std::string run = on_terminal(
        fmt::format("run --rays primary,ao --res 160x160 -o '{}'", (out / "run").string()));
    EXPECT_NE(run.find("[rtsim] "), std::string::npos) << run;
    EXPECT_NE(run.find("% of tiles"), std::string::npos) << run;
    EXPECT_EQ(on_terminal(fmt::format("run -q --rays primary --res 64x64 -o '{}'",
                                      (out / "quiet").string()))
                  .find("[rtsim]"),
              std::string::npos);
    const fs::path file = work_dir() / "sweep_progress.json";
    std::ofstream(file) << R"({"workload": {"rays": "primary", "res": "24x24"},
                               "vary": {"l1.ways": [1, 2, 4]}})";
    const std::string sweep =
        on_terminal(fmt::format("sweep '{}' -j 2 -o '{}'", file.string(), (out / "sw").string()));
    EXPECT_NE(sweep.find("of 3 points done"), std::string::npos) << sweep;
    EXPECT_NE(sweep.find("running, 0 failed"), std::string::npos) << sweep;
    EXPECT_EQ(on_terminal(
                  fmt::format("sweep '{}' -q -o '{}'", file.string(), (out / "sw_quiet").string()))
                  .find("points done"),
              std::string::npos);
    // Not a terminal: nothing, whatever the flags.
    const Result piped =
        run_rtsim(fmt::format("sweep '{}' -o '{}'", file.string(), (out / "sw_pipe").string()));
    EXPECT_EQ(piped.err.find("points done"), std::string::npos);
}

TEST(Sweep, BadSweepExitsTwoAndRunsNothing) {
    const fs::path file = work_dir() / "sweep_bad.json";
    std::ofstream(file) << R"({"vary": {"l1.size_kib": [8, 12]}})";
    const fs::path out = work_dir() / "sweep_never";
    expect_one_line_error(run_rtsim(fmt::format("sweep '{}' -o '{}'", file.string(), out.string())),
                          file.string() + ": point 001_l1.size_kib=12");
    EXPECT_FALSE(fs::exists(out));
}

TEST(Sweep, AGarbageTraceIsRefusedBeforeAnythingRuns) {
    const fs::path trace = work_dir() / "garbage.rtt";
    std::ofstream(trace) << "not a trace";
    const fs::path file = work_dir() / "sweep_garbage.json";
    std::ofstream(file) << fmt::format(R"({{"trace": "{}", "vary": {{"l1.ways": [2, 4]}}}})",
                                       trace.string());
    const fs::path out = work_dir() / "sweep_garbage_out";
    expect_one_line_error(run_rtsim(fmt::format("sweep '{}' -o '{}'", file.string(), out.string())),
                          trace.string() + ": byte 0");
    EXPECT_FALSE(fs::exists(out));
}

// A trace whose header is sound but whose data is damaged fails inside the runs: the sweep
// reports the first failed run in one line and writes no table.
TEST(Sweep, AFailedRunIsReportedAndNoTableWritten) {
    const fs::path trace = work_dir() / "damaged.rtt";
    ASSERT_EQ(run_rtsim(fmt::format("trace -q --rays primary --res 32x32 --chunk-rays 64 -o '{}'",
                                    trace.string()))
                  .status,
              0);
    std::fstream f(trace, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(0, std::ios::end);
    const auto middle = std::streamoff(f.tellg()) / 2;  // inside a chunk's compressed data
    f.seekg(middle);
    char byte = 0;
    f.read(&byte, 1);
    byte = char(~byte);
    f.seekp(middle);
    f.write(&byte, 1);
    f.close();
    const fs::path file = work_dir() / "sweep_damaged.json";
    std::ofstream(file) << fmt::format(R"({{"trace": "{}", "vary": {{"l1.ways": [2, 4]}}}})",
                                       trace.string());
    const fs::path out = work_dir() / "sweep_failed";
    const Result r = run_rtsim(fmt::format("sweep '{}' -o '{}'", file.string(), out.string()));
    EXPECT_EQ(r.status, 1);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("failed (status 2): rtsim: error: " + trace.string() + ": chunk"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(out / "results.json"));
}

// A combination run would refuse (treelet mode without treelets) is refused for the whole sweep.
TEST(Sweep, ACombinationRunRefusesIsRefusedUpFront) {
    const fs::path file = work_dir() / "sweep_modes.json";
    std::ofstream(file) << R"({"vary": {"traversal.mode": ["independent", "treelet"]}})";
    const fs::path out = work_dir() / "sweep_modes_out";
    expect_one_line_error(
        run_rtsim(fmt::format("sweep '{}' -o '{}'", file.string(), out.string())),
        "point 001_traversal.mode=treelet: --set: traversal.mode=treelet queues rays by treelet");
    EXPECT_FALSE(fs::exists(out));
}

// An interrupted sweep is finished with --resume: points that ran with the same arguments keep
// their stats (not run again), missing ones run; a point whose arguments changed runs again.
TEST(Sweep, ResumeRunsOnlyWhatIsMissing) {
    const fs::path file = work_dir() / "sweep_resume.json";
    std::ofstream(file) << R"({"workload": {"rays": "primary", "res": "16x16"},
                               "vary": {"l1.ways": [1, 2, 4]}})";
    const fs::path out = work_dir() / "sweep_resume_out";
    fs::remove_all(out);
    ASSERT_EQ(run_rtsim(fmt::format("sweep '{}' -j 2 -o '{}'", file.string(), out.string())).status,
              0);
    const json table = json::parse(std::ifstream(out / "results.json"));
    const fs::path kept = out / table["points"][0]["point"].get<std::string>();
    const fs::path lost = out / table["points"][2]["point"].get<std::string>();
    const std::string kept_stats = slurp(kept / "stats.json");  // host timings differ per run
    fs::remove(lost / "stats.json");
    fs::remove(out / "results.json");
    Result r =
        run_rtsim(fmt::format("sweep '{}' -j 2 -o '{}' --resume", file.string(), out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("3 runs (2 finished before"), std::string::npos) << r.out;
    EXPECT_EQ(slurp(kept / "stats.json"), kept_stats);
    EXPECT_EQ(stats_of(lost)["config"]["l1"]["ways"], 4);
    EXPECT_EQ(json::parse(std::ifstream(out / "results.json"))["points"].size(), 3u);
    // The same sweep at another resolution: every point's arguments changed, all run again.
    std::ofstream(file) << R"({"workload": {"rays": "primary", "res": "12x12"},
                               "vary": {"l1.ways": [1, 2, 4]}})";
    r = run_rtsim(fmt::format("sweep '{}' -j 2 -o '{}' --resume", file.string(), out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.out.find("finished before"), std::string::npos) << r.out;
    EXPECT_NE(slurp(kept / "stats.json"), kept_stats);
    EXPECT_EQ(stats_of(kept)["rays"]["total"], 144);
    // Resuming needs the sweep's folder.
    expect_one_line_error(run_rtsim(fmt::format("sweep '{}' --resume", file.string())),
                          "--resume: needs --out");
}

namespace {
json run_stats(const std::string& args, const std::string& name) {
    const fs::path out = work_dir() / name;
    const Result r = run_rtsim("run -q " + args + " --out '" + out.string() + "'");
    EXPECT_EQ(r.status, 0) << r.err;
    return stats_of(out);
}

// Runs `args` on the accurate engine: its every out-of-order count is 0, and `fast` (the same
// run on the fast engine) is within `tolerance_percent` of it on cycles and DRAM bytes.
void check_against_accurate(const json& fast, const std::string& args, const std::string& name,
                            double tolerance_percent) {
    const json acc = run_stats(args + " --set sim.fidelity=accurate", "acc_" + name);
    for (const auto& [kind, n] : acc["out_of_order"].items())
        EXPECT_EQ(n.get<uint64_t>(), 0u) << kind;
    EXPECT_EQ(acc["rays"]["total"], fast["rays"]["total"]);
    EXPECT_EQ(acc["config"]["sim"]["fidelity"], "accurate");
    const double cycles = acc["total_cycles"].get<double>();
    const double dram = acc["bandwidth"]["dram"]["bytes"].get<double>();
    const double tolerance = tolerance_percent / 100;
    EXPECT_NEAR(fast["total_cycles"].get<double>(), cycles, tolerance * cycles);
    EXPECT_NEAR(fast["bandwidth"]["dram"]["bytes"].get<double>(), dram, tolerance * dram);
}
}  // namespace

// The time-ordered reference serves every shared resource in time order by construction: every
// out-of-order count is 0, in every mode. The fast model runs the same rays and stays within
// 1% of it on cycles and DRAM bytes, or, where bench/results/fidelity.md lists a larger error
// with its cause, within that bound (a regression guard; the bench measures the full matrix).
TEST(Fidelity, AccurateServesInTimeOrderAndFastStaysClose) {
    const std::string rays = "--scene " RTSIM_BUNNY_OBJ " --rays primary,ao --res 32x32 ";
    struct Case {
        const char* name;
        std::string args;
        double tolerance_percent;
    };
    const Case cases[] = {
        {"default", "", 1},
        // Listed: a miss waiting for an MSHR holds back its core's other shared work (+2.7%).
        {"two_l1_mshrs",
         "--set l1.size_kib=4 --set l2.size_kib=64 --set l1.mshrs=2 --set l2.mshrs=8", 4},
        {"packet", "--set traversal.mode=packet --set bvh.width=4", 1},
        {"shared_units", "--set box_unit.shared_by=4 --set triangle_unit.shared_by=4", 1},
        {"split_one_channel", "--set l1.split=true --set dram.channels=1 --set l2.banks=1", 1},
        {"treelet",
         "--set traversal.mode=treelet --set bvh.width=4 --set bvh.treelet_bytes=4096 "
         "--set traversal.treelet_prefetch=false",
         1},
        // Listed: with treelet loads on 8 cores, the loaders' lines and the slots' misses meet
        // at the MSHRs in another order (+0.6% cycles, +4.3% DRAM bytes here).
        {"treelet_prefetch",
         "--set traversal.mode=treelet --set bvh.width=4 --set bvh.treelet_bytes=4096", 6},
        // One slot and its core's treelet loader, two L1 MSHRs: no other core to reorder, so the
        // engines' rules alone decide. A loader line that would miss waits while every MSHR is
        // taken, counting misses still in the lookup pipeline as taken (the reference once
        // counted only MSHRs held, so its loader queued lines ahead of the slot's misses: -20%).
        {"treelet_prefetch_one_slot",
         "--set traversal.mode=treelet --set bvh.width=4 --set bvh.treelet_bytes=4096 "
         "--set core.count=1 --set core.ray_slots=1 --set l1.mshrs=2",
         1},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const json fast = run_stats(rays + c.args, std::string("fast_") + c.name);
        check_against_accurate(fast, rays + c.args, c.name, c.tolerance_percent);
    }
}

// Two regimes where the fast engine once sent requests to the shared levels far ahead of other
// cores' (found by bench_fidelity.py --random): a BVH8 node's four lines through one L1 MSHR
// (each later line's miss left when the earlier fill freed the MSHR: +80% cycles here), and the
// command-level DRAM entering requests in the order they came rather than their time (+42%
// here). Sixteen cores make the order matter; the time-ordered engine is the truth.
TEST(Fidelity, FastEngineKeepsSharedRequestsInTimeOrder) {
    const std::string frame =
        "--scene builtin:cornell --rays primary --res 80x80 --set "
        "core.count=16 --set l1.mshrs=1 ";
    struct Case {
        const char* name;
        std::string args;
    };
    const Case cases[] = {
        {"bvh8_one_mshr", "--set bvh.width=8 --set core.ray_slots=2 --set l2.mshrs=8"},
        {"command_dram_one_mshr", "--set core.ray_slots=4 --set dram.model=command"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const json fast = run_stats(frame + c.args, std::string("fast_") + c.name);
        check_against_accurate(fast, frame + c.args, c.name, 3);
        if (fast["counters"].contains("dram.late_device_cycles")) {
            EXPECT_EQ(fast["counters"]["dram.late_device_cycles"].get<uint64_t>(), 0u);
        }
    }
}

namespace {
// A config key that no longer exists, set by --set KEY=VALUE and in a config file holding
// `file_json` (`file` names it): both refused with a one-line error containing `message`.
void expect_retired_key(const std::string& key_value, const std::string& file,
                        const std::string& file_json, const std::string& message) {
    expect_one_line_error(run_rtsim("run -q --res 8x8 --set " + key_value), message);
    const fs::path cfg = work_dir() / file;
    std::ofstream(cfg) << file_json;
    expect_one_line_error(run_rtsim("run -q --res 8x8 --config '" + cfg.string() + "'"), message);
}
}  // namespace

TEST(Fidelity, UnknownLevelAndRemovedQuantumAreRefused) {
    expect_one_line_error(run_rtsim("run -q --res 8x8 --set sim.fidelity=exact"), "sim.fidelity");
    // The quantum was removed for buying too little speed: a config that still sets it is told.
    expect_retired_key("sim.quantum_cycles=100", "old_quantum.json",
                       R"({"sim": {"quantum_cycles": 0}})", "sim.quantum_cycles: removed");
}

TEST(Sampled, TheWindowDrainSwitchIsReplacedByTheHoldWithAOneLineMessage) {
    // sim.sample_window_drain (a boolean) became sim.sample_window_hold (predicted, drain,
    // none): an old config is told what to write, not silently read otherwise.
    expect_retired_key("sim.sample_window_drain=true", "old_drain.json",
                       R"({"sim": {"sample_window_drain": false}})",
                       "sim.sample_window_drain: replaced by sim.sample_window_hold: write "
                       "\"drain\" for true, \"none\" for false");
    expect_one_line_error(run_rtsim("run -q --res 8x8 --set sim.sample_window_hold=always"),
                          "sim.sample_window_hold");
}

namespace {
// Runs `command` in the background, sends `signal` once `ready` exists (the command is then at
// work: a fixed delay raced a loaded machine's start-up and a fast machine's finish) and
// `after_seconds` more, and returns its exit status.
int interrupted_status(const std::string& command, const char* signal, const fs::path& ready,
                       double after_seconds) {
    const fs::path status = work_dir() / "interrupted_status.txt";
    const std::string script = fmt::format(
        "sh -c '{} >/dev/null 2>\"{}\" & p=$!; i=0; while [ ! -e \"{}\" ] && [ $i -lt 1200 ]; do "
        "sleep 0.05; i=$((i+1)); done; sleep {}; kill -{} $p; wait $p; echo $? > \"{}\"'",
        command, (work_dir() / "interrupted_err.txt").string(), ready.string(), after_seconds,
        signal, status.string());
    EXPECT_EQ(std::system(script.c_str()), 0);
    return std::stoi(slurp(status));
}
}  // namespace

// SIGINT or SIGTERM stops a long run, trace or sweep with one line and 128 + the
// signal, leaving no partial output; a sweep keeps its finished points and --resume completes it.
TEST(Interrupt, RunTraceAndSweepLeaveNoPartialOutput) {
    const std::string bin = RTSIM_BINARY;
    const std::string big = "--scene " RTSIM_BUNNY_OBJ " --rays diffuse --res 2048x2048";
    const fs::path run_dir = work_dir() / "interrupted_run";
    fs::remove_all(run_dir);
    // The run's folder is made once the workload is ready, before the simulation (2 s here).
    EXPECT_EQ(interrupted_status(bin + " run -q " + big + " --out " + run_dir.string(), "INT",
                                 run_dir, 0.3),
              130);
    EXPECT_FALSE(fs::exists(run_dir));  // the folder it made for its output is gone
    EXPECT_NE(slurp(work_dir() / "interrupted_err.txt").find("interrupted by SIGINT"),
              std::string::npos);

    const fs::path trace = work_dir() / "interrupted.rtt";
    fs::remove(trace);
    EXPECT_EQ(interrupted_status(bin + " trace -q " + big + " -o " + trace.string(), "TERM",
                                 trace.string() + ".tmp", 0.3),
              143);
    EXPECT_FALSE(fs::exists(trace));
    EXPECT_FALSE(fs::exists(trace.string() + ".tmp"));

    const fs::path sweep_file = work_dir() / "interrupted_sweep.json";
    std::ofstream(sweep_file) << R"({"workload": {"scene": ")" RTSIM_BUNNY_OBJ
                                 R"(", "rays": "diffuse", "res": "768x768"},
                                    "vary": {"l1.size_kib": [8, 16, 32, 64, 128, 256]}})";
    const fs::path out = work_dir() / "interrupted_sweep";
    fs::remove_all(out);
    const std::string sweep = bin + " sweep " + sweep_file.string() + " -j 2 --out " + out.string();
    // Signalled as its first point finishes: two more are under way, three not started.
    EXPECT_EQ(interrupted_status(sweep, "TERM", out / "000_l1.size_kib=8" / "stats.json", 0.0),
              143);
    EXPECT_FALSE(fs::exists(out / "results.json"));
    EXPECT_NE(slurp(work_dir() / "interrupted_err.txt").find("--resume"), std::string::npos);
    int finished = 0;
    for (const auto& point : fs::directory_iterator(out))
        finished += fs::exists(point.path() / "stats.json");
    EXPECT_GE(finished, 1);
    EXPECT_LT(finished, 6);  // the signal came before the end
    const Result resumed =
        run_rtsim("sweep " + sweep_file.string() + " -j 2 --out '" + out.string() + "' --resume");
    EXPECT_EQ(resumed.status, 0) << resumed.err;
    EXPECT_TRUE(fs::exists(out / "results.json"));
    EXPECT_NE(resumed.out.find(std::to_string(finished) + " finished before"), std::string::npos)
        << resumed.out;
}

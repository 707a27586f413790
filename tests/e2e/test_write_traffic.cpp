// The traversal's own memory traffic: short-stack spills and refills, hit records,
// the write-back L2 and DRAM writes, end to end, against an independent replay of the trace and
// against conservation of bytes between the levels.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "support/run_rtsim.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace rtsim::test;

namespace {

json stats_of(const fs::path& out) {
    return json::parse(slurp(out / "stats.json"));
}

uint64_t sum_over_cores(const json& s, const std::string& field) {
    uint64_t sum = 0;
    for (const auto& [name, v] : s["counters"].items())
        if (name.rfind("core[", 0) == 0 && name.size() > field.size() + 1 &&
            name.compare(name.size() - field.size() - 1, std::string::npos, "." + field) == 0)
            sum += v.get<uint64_t>();
    return sum;
}

uint64_t counter(const json& s, const std::string& name) {
    return s["counters"].at(name).get<uint64_t>();
}

const char* kWorkload = "--scene builtin:cornell --rays primary,ao,diffuse --res 48x48";

fs::path record_trace() {
    const fs::path rtt = work_dir() / "writes.rtt";
    const Result r =
        run_rtsim(fmt::format("trace -q {} --set bvh.width=4 -o '{}'", kWorkload, rtt.string()));
    EXPECT_EQ(r.status, 0) << r.err;
    return rtt;
}

}  // namespace

// Every spill and refill the cores made, summed, equals what an independent replay of the
// trace's recorded stack depths (tests/e2e/stack_replay.py, written apart from the model)
// finds, for several short-stack sizes.
TEST(WriteTraffic, StackTrafficMatchesAnIndependentReplayOfTheTrace) {
    const fs::path rtt = record_trace();
    for (int entries : {1, 2, 4}) {
        const fs::path out = work_dir() / fmt::format("stack{}", entries);
        const Result r = run_rtsim(fmt::format(
            "run -q --trace '{}' --set bvh.width=4 --set core.short_stack_entries={} -o '{}'",
            rtt.string(), entries, out.string()));
        ASSERT_EQ(r.status, 0) << r.err;
        const json s = stats_of(out);
        const fs::path replay_out = work_dir() / "replay.json";
        const std::string cmd =
            fmt::format("python3 '{}/tests/e2e/stack_replay.py' '{}' {} > '{}'", RTSIM_SOURCE_DIR,
                        rtt.string(), entries, replay_out.string());
        ASSERT_EQ(std::system(cmd.c_str()), 0);
        const json want = json::parse(slurp(replay_out));
        EXPECT_GT(want["spills"].get<uint64_t>(), 0u) << entries;
        EXPECT_EQ(sum_over_cores(s, "stack_spills"), want["spills"].get<uint64_t>()) << entries;
        EXPECT_EQ(sum_over_cores(s, "stack_spill_bytes"),
                  8 * want["spilled_entries"].get<uint64_t>())
            << entries;
        EXPECT_EQ(sum_over_cores(s, "stack_refills"), want["refills"].get<uint64_t>()) << entries;
        EXPECT_EQ(sum_over_cores(s, "stack_refill_bytes"),
                  8 * want["refilled_entries"].get<uint64_t>())
            << entries;
    }
}

// Bytes are conserved level by level: every spill and hit record crosses the crossbar's write
// link into the L2; what DRAM writes is the L2's dirty lines written back; every line the L2
// allocated for a write is written back or still dirty at the end. Waiting for refills is a stall
// cause of its own, and every slot cycle is still charged exactly once.
TEST(WriteTraffic, BytesAreConservedFromTheCoresToDram) {
    const fs::path out = work_dir() / "conserve";
    // A small L2 so that dirty lines are evicted during the frame.
    const Result r = run_rtsim(
        fmt::format("run -q {} --set core.short_stack_entries=1 --set core.hit_record_bytes=16 "
                    "--set l2.size_kib=16 --set l2.ways=4 -o '{}'",
                    kWorkload, out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    const uint64_t rays = s["rays"]["total"].get<uint64_t>();
    EXPECT_EQ(sum_over_cores(s, "hit_record_bytes"), 16 * rays);
    const uint64_t written =
        sum_over_cores(s, "stack_spill_bytes") + sum_over_cores(s, "hit_record_bytes");
    EXPECT_EQ(counter(s, "crossbar.write_bytes"), written);
    EXPECT_EQ(counter(s, "l2.write_bytes"), written);
    EXPECT_EQ(counter(s, "l2.write_requests"), counter(s, "crossbar.write_transfers"));
    EXPECT_GT(counter(s, "l2.writebacks"), 0u);
    EXPECT_EQ(counter(s, "dram.write_bytes"), 64 * counter(s, "l2.writebacks"));
    EXPECT_EQ(counter(s, "dram.writes"), counter(s, "l2.writebacks"));
    // DRAM's traffic by region: reads are BVH data or stack refills, writes stacks or hit
    // records, nothing falls outside the regions.
    const json& by = s["bandwidth"]["dram"]["by_region"];
    auto region = [&](const char* r, const char* dir) { return by[r][dir].get<uint64_t>(); };
    EXPECT_EQ(region("other", "read_bytes") + region("other", "write_bytes"), 0u);
    EXPECT_EQ(region("stack", "write_bytes") + region("hit_records", "write_bytes"),
              counter(s, "dram.write_bytes"));
    EXPECT_GT(region("hit_records", "write_bytes"), 0u);
    EXPECT_EQ(region("nodes", "read_bytes") + region("triangles", "read_bytes") +
                  region("stack", "read_bytes"),
              counter(s, "dram.bytes") - counter(s, "dram.write_bytes"));
    const uint64_t dirty_end = s["caches"]["l2"]["dirty_lines_at_end"].get<uint64_t>();
    EXPECT_GE(counter(s, "l2.writebacks") + dirty_end, counter(s, "l2.write_misses"));
    EXPECT_LE(counter(s, "l2.writebacks") + dirty_end,
              counter(s, "l2.write_misses") + counter(s, "l2.write_hits"));
    const json& stalls = s["stalls"]["total"];
    EXPECT_GT(stalls["stack"].get<uint64_t>(), 0u);
    EXPECT_EQ(stalls["unaccounted_cycles"].get<int64_t>(), 0);
    EXPECT_EQ(sum_over_cores(s, "stall_stack_cycles"), stalls["stack"].get<uint64_t>());
    // Energy counts the written lines in the L2 and the write link.
    EXPECT_GT(s["energy"]["blocks_pj"]["l2"].get<double>(), 0.0);
}

// The fast model and the time-ordered reference make the same writes (the counts depend on
// the rays alone), serve them in time order in the reference, and agree on cycles.
TEST(WriteTraffic, FastAndAccurateMakeTheSameWrites) {
    json s[2];
    const char* fidelity[2] = {"fast", "accurate"};
    for (int f = 0; f < 2; ++f) {
        const fs::path out = work_dir() / fidelity[f];
        const Result r = run_rtsim(
            fmt::format("run -q {} --set core.short_stack_entries=2 --set core.hit_record_bytes=16 "
                        "--set l2.size_kib=32 --set l2.ways=4 --set sim.fidelity={} -o '{}'",
                        kWorkload, fidelity[f], out.string()));
        ASSERT_EQ(r.status, 0) << r.err;
        s[f] = stats_of(out);
    }
    for (const char* field : {"stack_spills", "stack_refills", "hit_record_writes"})
        EXPECT_EQ(sum_over_cores(s[0], field), sum_over_cores(s[1], field)) << field;
    EXPECT_EQ(counter(s[0], "crossbar.write_bytes"), counter(s[1], "crossbar.write_bytes"));
    EXPECT_EQ(counter(s[0], "l2.write_requests"), counter(s[1], "l2.write_requests"));
    EXPECT_EQ(counter(s[1], "l2.lookup_out_of_order"), 0u);
    EXPECT_EQ(counter(s[1], "dram.bank_out_of_order"), 0u);
    const double fast = s[0]["total_cycles"].get<double>(),
                 ref = s[1]["total_cycles"].get<double>();
    EXPECT_NEAR(fast / ref, 1.0, 0.03);
    EXPECT_GT(counter(s[1], "dram.writes"), 0u);
}

// With the command-level DRAM, written lines go through its write queue; --mem-trace lists
// them as WRITE lines (one per burst), which rtsim dram replays as writes.
TEST(WriteTraffic, CommandDramTakesWritesAndMemoryTracesListThem) {
    const fs::path out = work_dir() / "cmd", mt = work_dir() / "writes.trace";
    const Result r = run_rtsim(
        fmt::format("run -q {} --set core.hit_record_bytes=16 --set l2.size_kib=16 --set l2.ways=4 "
                    "--set dram.model=command --mem-trace '{}' -o '{}'",
                    kWorkload, mt.string(), out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = stats_of(out);
    const std::string text = slurp(mt);
    uint64_t writes = 0, reads = 0;
    for (size_t p = 0; (p = text.find(" WRITE ", p)) != std::string::npos; ++p) ++writes;
    for (size_t p = 0; (p = text.find(" READ ", p)) != std::string::npos; ++p) ++reads;
    EXPECT_GT(writes, 0u);
    EXPECT_EQ(writes, counter(s, "dram.writes"));
    EXPECT_EQ(reads, counter(s, "dram.reads"));
    EXPECT_EQ(64 * writes, counter(s, "dram.write_bytes"));
    EXPECT_GT(s["bandwidth"]["dram"]["energy_pj"]["write"].get<double>(), 0.0);
    const fs::path replay = work_dir() / "cmd_replay";
    const Result d = run_rtsim("dram -q '" + mt.string() + "' -o '" + replay.string() + "'");
    ASSERT_EQ(d.status, 0) << d.err;
    EXPECT_EQ(json::parse(slurp(replay / "stats.json"))["writes"].get<uint64_t>(), writes);
}

TEST(WriteTraffic, AShortStackRefusesTracesWithoutDepthsAndOtherTraversalModes) {
    const std::string v1 = std::string(RTSIM_SOURCE_DIR) + "/tests/data/cornell_16x16_v1.rtt";
    expect_one_line_error(run_rtsim("run -q --trace '" + v1 +
                                    "' --set bvh.width=4 --set core.short_stack_entries=4 -o '" +
                                    (work_dir() / "v1").string() + "'"),
                          "version 1 does not record");
    expect_one_line_error(
        run_rtsim(fmt::format("run -q {} --set core.short_stack_entries=4 "
                              "--set traversal.mode=treelet --set bvh.treelet_bytes=4096",
                              kWorkload)),
        "core.short_stack_entries: a short stack is modelled for independent traversal only");
    expect_one_line_error(run_rtsim(fmt::format("run -q {} --set core.short_stack_entries=4 "
                                                "--set traversal.mode=packet",
                                                kWorkload)),
                          "packet traces record no per-ray stack");
}

// Treelet queues in memory (ray_buffer.storage = memory): every record the buffer writes
// reaches the L2 as a write of ray_bytes, every record read is an L2 request, and the fast model
// agrees with the time-ordered reference.
TEST(WriteTraffic, TreeletQueuesInMemoryMoveTheirRecordsThroughTheL2) {
    json s[2];
    const char* fidelity[2] = {"fast", "accurate"};
    for (int f = 0; f < 2; ++f) {
        const fs::path out = work_dir() / fmt::format("rbmem_{}", fidelity[f]);
        const Result r = run_rtsim(fmt::format(
            "run -q {} --config '{}/configs/treelet.json' --set ray_buffer.storage=memory "
            "--set sim.fidelity={} -o '{}'",
            kWorkload, RTSIM_SOURCE_DIR, fidelity[f], out.string()));
        ASSERT_EQ(r.status, 0) << r.err;
        s[f] = stats_of(out);
    }
    for (const json& x : s) {
        const uint64_t record = x["config"]["ray_buffer"]["ray_bytes"].get<uint64_t>();
        EXPECT_GT(counter(x, "ray_buffer.crossings"), 0u);
        EXPECT_EQ(counter(x, "l2.write_bytes"), record * counter(x, "ray_buffer.writes"));
        EXPECT_EQ(counter(x, "l2.write_requests"), counter(x, "ray_buffer.writes"));
        EXPECT_GT(x["stalls"]["total"]["ray_buffer"].get<uint64_t>(), 0u);
        EXPECT_EQ(x["stalls"]["total"]["unaccounted_cycles"].get<int64_t>(), 0);
        EXPECT_EQ(x["ray_buffer"]["storage"], "memory");
        // Whatever reaches DRAM is BVH data or ray records.
        const json& by = x["bandwidth"]["dram"]["by_region"];
        EXPECT_EQ(by["other"]["read_bytes"].get<uint64_t>(), 0u);
        EXPECT_EQ(by["ray_records"]["write_bytes"].get<uint64_t>(), counter(x, "dram.write_bytes"));
        // The SRAM is not there to spend energy.
        EXPECT_FALSE(x["energy"]["blocks_pj"].contains("ray_buffer"));
    }
    // The same records move in both; the L2 sees the same requests.
    EXPECT_EQ(counter(s[0], "ray_buffer.reads"), counter(s[1], "ray_buffer.reads"));
    EXPECT_EQ(counter(s[0], "l2.write_requests"), counter(s[1], "l2.write_requests"));
    EXPECT_EQ(counter(s[1], "l2.lookup_out_of_order"), 0u);
    const double fast = s[0]["total_cycles"].get<double>(),
                 ref = s[1]["total_cycles"].get<double>();
    EXPECT_NEAR(fast / ref, 1.0, 0.03);
}

// A one-entry write buffer makes writes wait for each other: both fidelities charge the wait to
// the write_buffer cause and agree on cycles; with more entries the waits shrink.
TEST(WriteTraffic, AFullWriteBufferStallsAndBothFidelitiesSeeIt) {
    json s[3];
    const char* runs[3][2] = {{"fast", "1"}, {"accurate", "1"}, {"fast", "64"}};
    for (int k = 0; k < 3; ++k) {
        const fs::path out = work_dir() / fmt::format("wb_{}_{}", runs[k][0], runs[k][1]);
        const Result r = run_rtsim(
            fmt::format("run -q {} --set core.short_stack_entries=1 --set core.hit_record_bytes=16 "
                        "--set core.write_buffer_entries={} --set sim.fidelity={} -o '{}'",
                        kWorkload, runs[k][1], runs[k][0], out.string()));
        ASSERT_EQ(r.status, 0) << r.err;
        s[k] = stats_of(out);
        EXPECT_EQ(s[k]["stalls"]["total"]["unaccounted_cycles"].get<int64_t>(), 0);
    }
    const double fast = s[0]["stalls"]["total"]["share"]["write_buffer"].get<double>();
    const double ref = s[1]["stalls"]["total"]["share"]["write_buffer"].get<double>();
    EXPECT_GT(fast, 0.0);
    EXPECT_GT(ref, 0.0);
    EXPECT_NEAR(fast, ref, 0.01);  // within a point of slot cycles
    EXPECT_NEAR(s[0]["total_cycles"].get<double>() / s[1]["total_cycles"].get<double>(), 1.0, 0.03);
    EXPECT_LT(s[2]["stalls"]["total"]["write_buffer"].get<uint64_t>(),
              s[0]["stalls"]["total"]["write_buffer"].get<uint64_t>());
}

// Blocks the config places in the memory path (memory_path.*, docs/extending.md) end to end, in
// both engines: a stream buffer's traffic is accounted for by the levels on either side of it.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>

#include "support/run_rtsim.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace rtsim::test;

namespace {

json run_with(const std::string& name, const std::string& engine, const std::string& sets) {
    const fs::path out = work_dir() / ("memory_path_" + name + "_" + engine);
    const Result r = run_rtsim(fmt::format(
        "run -q --scene builtin:cornell --rays primary,ao --res 48x48 --set sim.fidelity={} {} "
        "--out '{}'",
        engine, sets, out.string()));
    EXPECT_EQ(r.status, 0) << r.err;
    return r.status == 0 ? json::parse(slurp(out / "stats.json")) : json();
}

uint64_t u(const json& j) {
    return j.get<uint64_t>();
}

// Runs the frame with `sets` on both engines, checks each run's stats with `check`, and the
// engines' cycles within 5% of each other (they order the same requests differently in time).
void in_both_engines(const std::string& name, const std::string& sets,
                     const std::function<void(const json&)>& check) {
    json cycles;
    for (const char* engine : {"fast", "accurate"}) {
        SCOPED_TRACE(engine);
        const json s = run_with(name, engine, sets);
        ASSERT_TRUE(s.contains("memory_path")) << s.dump().substr(0, 200);
        check(s);
        cycles[engine] = s["total_cycles"];
    }
    EXPECT_NEAR(cycles["fast"].get<double>(), cycles["accurate"].get<double>(),
                0.05 * cycles["accurate"].get<double>());
}

// A block below the L2 on a frame with write-backs (a small write-back L2 and stack spills);
// `block` its settings.
std::string below_a_writing_l2(const std::string& block) {
    return fmt::format("--config '{}/configs/write_traffic.json' --set l2.size_kib=16 {}",
                       RTSIM_SOURCE_DIR, block);
}

}  // namespace

// Between the L2 and DRAM, with write-backs (a small write-back L2 and stack spills): every
// line DRAM reads is a read the buffer passed on (it held no line for it) or one it read ahead,
// and every write reaches DRAM. The engines agree within a few percent on cycles.
TEST(MemoryPath, AStreamBufferBelowTheL2AccountsForEveryDramRequestInBothEngines) {
    in_both_engines("l2", below_a_writing_l2("--set memory_path.below_l2=stream_buffer"),
                    [](const json& s) {
                        const json& b = s["memory_path"]["below_l2"];
                        const json& d = s["bandwidth"]["dram"];
                        EXPECT_GT(u(b["hits"]), 0u);
                        EXPECT_GT(u(b["writes"]), 0u);
                        const uint64_t line = 64;  // the L2's line and the DRAM's burst
                        EXPECT_EQ(u(d["bytes"]) - u(d["write_bytes"]),
                                  line * (u(b["reads"]) - u(b["hits"]) + u(b["read_aheads"])));
                        EXPECT_EQ(u(b["writes"]), u(s["caches"]["l2"]["writebacks"]));
                        EXPECT_EQ(u(d["write_bytes"]), u(s["caches"]["l2"]["writeback_bytes"]));
                    });
}

// One block per core between its L1 and the crossbar: the L2 sees each block's passed-on reads
// and read-aheads, and nothing else (no stack, hit-record or ray-record traffic here).
TEST(MemoryPath, StreamBuffersBelowTheL1sAccountForEveryL2AccessInBothEngines) {
    in_both_engines("l1", "--set core.count=4 --set memory_path.below_l1=stream_buffer",
                    [](const json& s) {
                        uint64_t passed_on = 0;
                        int blocks = 0;
                        for (const auto& [name, b] : s["memory_path"].items()) {
                            EXPECT_EQ(name, fmt::format("below_l1[{}]", blocks));
                            passed_on += u(b["reads"]) - u(b["hits"]) + u(b["read_aheads"]);
                            ++blocks;
                        }
                        EXPECT_EQ(blocks, 4);
                        EXPECT_EQ(passed_on, u(s["caches"]["l2"]["accesses"]));
                    });
}

// A cache level of its own below the L2 (an L3), with the L2's write-backs: it looks up every
// line the L2 fetches and every line it writes back, DRAM reads exactly its misses' lines and
// writes exactly its own write-backs, in both engines.
TEST(MemoryPath, AnL3BelowTheL2AccountsForEveryDramRequestInBothEngines) {
    in_both_engines(
        "l3",
        below_a_writing_l2("--set memory_path.below_l2=cache --set memory_path.cache.size_kib=64"),
        [](const json& s) {
            const json& l3 = s["memory_path"]["below_l2"];
            const json& l2 = s["caches"]["l2"];
            const json& d = s["bandwidth"]["dram"];
            EXPECT_EQ(l3["block"], "cache");
            EXPECT_GT(u(l3["hits"]), 0u);
            EXPECT_GT(u(l3["writebacks"]), 0u);
            EXPECT_EQ(u(l3["accesses"]), u(l2["misses"]));
            EXPECT_EQ(u(l3["write_requests"]), u(l2["writebacks"]));
            const uint64_t line = 64;
            EXPECT_EQ(u(d["bytes"]) - u(d["write_bytes"]), line * u(l3["misses"]));
            EXPECT_EQ(u(d["write_bytes"]), u(l3["writeback_bytes"]));
        });
}

// A block's geometry that its section's ranges allow but the block cannot build is one line
// naming the field, and no output.
TEST(MemoryPath, ABlockRefusesItsBadGeometryInOneLine) {
    const fs::path out = work_dir() / "memory_path_bad";
    const Result r = run_rtsim(fmt::format(
        "run -q --set memory_path.below_l2=cache --set memory_path.cache.size_kib=3 --out '{}'",
        out.string()));
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("memory_path.cache.size_kib: "), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(out / "stats.json"));
}

// dram.model = tlm end to end: the reference TLM-2.0 target (tests/support/
// tlm_reference_target.cpp, written to the base protocol alone) stands in for the DRAM in both
// engines, with reads and posted writes (a small write-back L2 evicting stack spills and hit
// records). What the target says it served, printed by the target itself, is what stats.json
// counts.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "support/run_rtsim.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace rtsim::test;

namespace {

struct Served {
    unsigned long long reads = 0, writes = 0, bytes_read = 0, bytes_written = 0;
};

Served parse_target_line(const std::string& err) {
    Served s;
    const size_t at = err.find("reference target:");
    EXPECT_NE(at, std::string::npos) << err;
    if (at != std::string::npos) {
        EXPECT_EQ(std::sscanf(err.c_str() + at,
                              "reference target: %llu reads, %llu writes, %llu bytes read, %llu "
                              "bytes written",
                              &s.reads, &s.writes, &s.bytes_read, &s.bytes_written),
                  4);
    }
    return s;
}

}  // namespace

TEST(DramTlm, TheTargetServesWhatStatsCountInBothEngines) {
    json cycles;
    for (const char* engine : {"fast", "accurate"}) {
        SCOPED_TRACE(engine);
        const fs::path out = work_dir() / (std::string("tlm_") + engine);
        const Result r = run_rtsim(fmt::format(
            "run -q --config '{}/configs/write_traffic.json' --scene builtin:cornell --rays "
            "primary,ao --res 48x48 --set l2.size_kib=16 --set dram.model=tlm --set "
            "dram.tlm_target='{}' --set "
            "sim.fidelity={} --out '{}'",
            RTSIM_SOURCE_DIR, RTSIM_TLM_REFERENCE_TARGET, engine, out.string()));
        ASSERT_EQ(r.status, 0) << r.err;
        const Served served = parse_target_line(r.err);
        const json s = json::parse(slurp(out / "stats.json"));
        const json& d = s["bandwidth"]["dram"];
        EXPECT_EQ(d["reads"].get<unsigned long long>(), served.reads);
        EXPECT_EQ(d["writes"].get<unsigned long long>(), served.writes);
        EXPECT_EQ(d["bytes"].get<unsigned long long>(), served.bytes_read + served.bytes_written);
        EXPECT_EQ(d["write_bytes"].get<unsigned long long>(), served.bytes_written);
        EXPECT_GT(served.reads, 0u);
        EXPECT_GT(served.writes, 0u);
        // Every read waits at least the target's 100 ns latency (100 cycles at 1 GHz).
        EXPECT_GE(d["mean_read_latency_cycles"].get<double>(), 100.0);
        cycles[engine] = s["total_cycles"];
    }
    // The engines order the same requests differently in time, so they differ a little.
    EXPECT_NEAR(cycles["fast"].get<double>(), cycles["accurate"].get<double>(),
                0.05 * cycles["accurate"].get<double>());
}

TEST(DramTlm, AMissingTargetIsRefusedInOneLine) {
    const Result r = run_rtsim("run -q --res 8x8 --set dram.model=tlm");
    expect_one_line_error(r, "dram.tlm_target");
    const Result bad = run_rtsim(
        "run -q --res 8x8 --set dram.model=tlm --set "
        "dram.tlm_target=/nonexistent/libtarget.so");
    expect_one_line_error(bad, "/nonexistent/libtarget.so");
}

// dram.model = tlm against the reference target (tests/support/tlm_reference_target.cpp, written
// to the TLM-2.0 base protocol alone): completions worked out by hand from that target's stated
// timing (16 bytes per ns on one data path taken in arrival order, ready 100 ns after the last
// byte), at two chip clocks, with a request behind the kernel's time, and an error response.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "models/dram.h"
#include "support/input_error.h"

using namespace rtsim;

namespace {

std::unique_ptr<DramModel> tlm_dram(double clock_ghz, const std::string& target) {
    DramParams p;
    p.chip_clock_ghz = clock_ghz;
    p.tlm_target = target;
    return DramModelRegistry::at("tlm").make("dram", p);
}

}  // namespace

TEST(DramTlm, CompletionsFollowTheTargetsTimingAt1GHz) {
    auto dram = tlm_dram(1.0, RTSIM_TLM_REFERENCE_TARGET);
    // 64 bytes take 4 ns on the path; the first read has it free.
    EXPECT_EQ(dram->access(0, 64, 0), 0u + 4 + 100);
    // Arrives at 2 ns, waits for the path until 4, moves until 8.
    EXPECT_EQ(dram->access(64, 64, 2), 8u + 100);
    // A posted write is accepted at its cycle, but takes the path from 8 to 12.
    EXPECT_EQ(dram->write(128, 64, 3), 3u);
    EXPECT_EQ(dram->access(192, 32, 5), 12u + 2 + 100);
    // The split-phase interface of the time-ordered engine: one stage, the same answer.
    DramRequest r;
    r.addr = 256;
    r.size_bytes = 64;
    bool done = false;
    EXPECT_EQ(dram->advance(r, 200, done), 200u + 4 + 100);
    EXPECT_TRUE(done);
    const nlohmann::json rep = dram->report(ReportContext{400, 1.0, 0});
    EXPECT_EQ(rep["reads"], 4);
    EXPECT_EQ(rep["writes"], 1);
    EXPECT_EQ(rep["bytes"], 64 * 4 + 32);
    EXPECT_DOUBLE_EQ(rep["mean_read_latency_cycles"].get<double>(),
                     (104.0 + 106.0 + 109.0 + 104.0) / 4);
}

TEST(DramTlm, ChipCyclesConvertAtTheChipsClock) {
    auto dram = tlm_dram(2.0, RTSIM_TLM_REFERENCE_TARGET);
    // Cycle 10 at 2 GHz is 5 ns; ready at 5 + 4 + 100 = 109 ns, cycle 218.
    EXPECT_EQ(dram->access(0, 64, 10), 218u);
}

TEST(DramTlm, RequestsBehindTheKernelAreSentWithoutDelayAndCounted) {
    auto dram = tlm_dram(1.0, RTSIM_TLM_REFERENCE_TARGET);
    sc_core::sc_start(50, sc_core::SC_NS);
    // Cycle 10 lies behind the kernel's 50 ns: sent at 50 ns, ready at 154.
    EXPECT_EQ(dram->access(0, 64, 10), 154u);
    StatsRegistry reg;
    dram->register_stats(reg);
    EXPECT_EQ(reg.get("dram.late_requests"), 1u);
}

TEST(DramTlm, AnErrorResponseEndsTheRunNamingTheAddress) {
    auto dram = tlm_dram(1.0, RTSIM_TLM_REFERENCE_TARGET);
    try {
        dram->access(uint64_t(1) << 40, 64, 0);
        ADD_FAILURE() << "no error for a read past the target's memory";
    } catch (const std::runtime_error& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("TLM_ADDRESS_ERROR_RESPONSE"), std::string::npos) << msg;
        EXPECT_NE(msg.find("0x10000000000"), std::string::npos) << msg;
    }
}

TEST(DramTlm, AMissingOrWrongLibraryIsAnInputError) {
    test::expect_input_error([] { tlm_dram(1.0, "/nonexistent/libtarget.so"); }, "dram.tlm_target",
                             "/nonexistent/libtarget.so");
    test::expect_input_error([] { tlm_dram(1.0, ""); }, "dram.tlm_target", "shared library");
}

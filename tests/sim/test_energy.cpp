// The energy section (sim/energy.cpp) against hand arithmetic on stated counters: the SRAM
// energy curve through Horowitz's three points, line and operation costs, and each block's
// energy as its counters times its cost.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "sim/config.h"
#include "sim/energy.h"

using namespace rtsim;
using nlohmann::json;

namespace {
Params defaults(const std::vector<std::string>& sets = {}) {
    return load_config("", sets).typed;
}
}  // namespace

TEST(Energy, SramCurvePassesThroughItsPointsAndIsLinearInLogSize) {
    const EnergyParams e = defaults().energy;
    EXPECT_NEAR(sram_word_pj(e, 8 * 1024), 10.0, 1e-9);
    EXPECT_NEAR(sram_word_pj(e, 32 * 1024), 20.0, 1e-9);
    EXPECT_NEAR(sram_word_pj(e, 1024 * 1024), 100.0, 1e-9);
    // 128 KiB: 2 of the 5 doublings from 32 KiB to 1 MiB: 20 + 0.4 x 80.
    EXPECT_NEAR(sram_word_pj(e, 128 * 1024), 52.0, 1e-9);
    // 16 KiB: halfway from 8 to 32 KiB in log size.
    EXPECT_NEAR(sram_word_pj(e, 16 * 1024), 15.0, 1e-9);
    // Below 8 KiB, the power law through the first two points (4x the size, 2x the energy):
    // 2 KiB, a quarter of 8 KiB, costs half of 10 pJ; 512 bytes a quarter; never zero.
    EXPECT_NEAR(sram_word_pj(e, 2 * 1024), 5.0, 1e-9);
    EXPECT_NEAR(sram_word_pj(e, 512), 2.5, 1e-9);
    EXPECT_GT(sram_word_pj(e, 1), 0.0);
}

// The ray buffer's record costs a bank's access: 8192 records of 64 bytes in 4 banks are
// 128 KiB banks (52 pJ a word, 8 words a record); queues in memory cost no SRAM energy, and the
// L2's writes and write-backs count as line accesses.
TEST(Energy, RayBufferBanksAndWrites) {
    const Params P = defaults({"ray_buffer.capacity_rays=8192", "ray_buffer.ray_bytes=64",
                               "ray_buffer.banks=4", "l2.banks=8"});
    json stats = {{"rays", {{"total", 10}}},
                  {"simulated_seconds", 1e-6},
                  {"counters",
                   {{"ray_buffer.reads", 30},
                    {"ray_buffer.writes", 20},
                    {"l2.accesses", 5},
                    {"l2.misses", 1},
                    {"l2.write_hits", 2},
                    {"l2.write_misses", 3},
                    {"l2.writebacks", 4},
                    {"crossbar.bytes", 100},
                    {"crossbar.write_bytes", 60}}}};
    const json e = energy_report(P, stats);
    EXPECT_NEAR(e["blocks_pj"]["ray_buffer"].get<double>(), 50 * 8 * 52.0, 1e-6);
    EXPECT_NEAR(e["blocks_pj"]["l2"].get<double>(), (5 + 2 + 3 + 1 + 4) * 416.0, 1e-6);
    const double mm = std::sqrt(double(P.core_count));
    EXPECT_NEAR(e["blocks_pj"]["crossbar"].get<double>(), 160 * 8 * 0.1 * mm, 1e-6);
    const Params in_memory = defaults({"ray_buffer.storage=memory"});
    EXPECT_FALSE(energy_report(in_memory, stats)["blocks_pj"].contains("ray_buffer"));
}

TEST(Energy, BlocksAreTheirCountersTimesTheirCosts) {
    // 2 cores; L1 32 KiB in 1 bank (64-byte lines: 8 words of 20 pJ = 160 pJ); L2 1 MiB in 8
    // banks (128 KiB each: 52 pJ a word, 416 pJ a line); box tests 6 x 3.7 + 12 x 0.9 = 33 pJ
    // on 8-wide units; triangle tests (one per operation) 20 x 3.7 + 20 x 0.9 = 92 pJ; crossbar
    // sqrt(2) mm x 0.1 pJ/bit-mm; DRAM 162.5 pJ a byte.
    const Params P = defaults({"core.count=2", "l1.banks=1", "l2.banks=8", "box_unit.width=8"});
    json stats = {{"rays", {{"total", 1000}}},
                  {"simulated_seconds", 1e-6},
                  {"counters",
                   {{"l1[0].accesses", 100},
                    {"l1[0].misses", 10},
                    {"l1[1].accesses", 50},
                    {"l1[1].misses", 5},
                    {"l2.accesses", 15},
                    {"l2.misses", 3},
                    {"box_unit[0].ops", 40},
                    {"box_unit[1].ops", 20},
                    {"triangle_unit[0].ops", 7},
                    {"crossbar.bytes", 960},
                    {"dram.bytes", 192}}}};
    const json e = energy_report(P, stats);
    const json& b = e["blocks_pj"];
    EXPECT_NEAR(b["l1"].get<double>(), (150 + 15) * 160.0, 1e-6);
    EXPECT_NEAR(b["l2"].get<double>(), (15 + 3) * 416.0, 1e-6);
    EXPECT_NEAR(b["box_unit"].get<double>(), 60 * 8 * 33.0, 1e-6);
    EXPECT_NEAR(b["triangle_unit"].get<double>(), 7 * 1 * 92.0, 1e-6);
    EXPECT_NEAR(b["crossbar"].get<double>(), 960 * 8 * 0.1 * std::sqrt(2.0), 1e-6);
    EXPECT_NEAR(b["dram"].get<double>(), 192 * 162.5, 1e-6);
    double total = 0;
    for (const auto& [k, v] : b.items()) total += v.get<double>();
    EXPECT_NEAR(e["total_pj"].get<double>(), total, 1e-6);
    EXPECT_NEAR(e["per_ray_nj"].get<double>(), total / 1000 / 1e3, 1e-9);
    EXPECT_NEAR(e["average_power_w"].get<double>(), total * 1e-12 / 1e-6, 1e-9);
}

TEST(Energy, NarrowBoxUnitsSpendLess) {
    // 11 stored mantissa bits: 12 of fp32's 24, so multiplies cost a quarter and adds half:
    // 6 x 3.7 / 4 + 12 x 0.9 / 2 = 10.95 pJ a box test.
    const Params P = defaults({"box_unit.mantissa_bits=11"});
    const json stats = {{"rays", {{"total", 1}}}, {"counters", json::object()}};
    EXPECT_NEAR(energy_report(P, stats)["per_access_pj"]["box_test_pj"].get<double>(), 10.95, 1e-9);
}

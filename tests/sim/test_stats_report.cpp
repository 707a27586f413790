#include <gtest/gtest.h>

#include "sim/stats_report.h"

using namespace rtsim;

namespace {

struct Blocks {
    // Counters of one core's blocks plus L2 and DRAM, as the chip registers them.
    uint64_t box[3] = {500, 500, 0}, tri[3] = {100, 200, 0};
    uint64_t l1[6] = {1000, 900, 100, 10, 64000, 6400};
    uint64_t l2[6] = {100, 60, 40, 0, 6400, 2560};
    uint64_t dram[7] = {40, 2560, 80, 0, 30, 6, 4};
    uint64_t stalls[7] = {100, 200, 300, 400,
                          500, 600, 0};  // one core of 3 slots: 2100 of 3000 cycles
    StatsRegistry reg;
    Blocks() {
        const char* unit[] = {"ops", "busy_cycles", "queue_cycles"};
        const char* cache[] = {"accesses",        "hits",      "misses", "merged_misses",
                               "bytes_requested", "fill_bytes"};
        const char* mem[] = {"reads",    "bytes",     "busy_cycles",  "queue_cycles",
                             "row_hits", "row_empty", "row_conflicts"};
        for (int i = 0; i < 3; ++i) reg.add("box_unit[0]", unit[i], &box[i], "");
        for (int i = 0; i < 3; ++i) reg.add("triangle_unit[0]", unit[i], &tri[i], "");
        for (int i = 0; i < 6; ++i) reg.add("l1[0]", cache[i], &l1[i], "");
        for (int i = 0; i < 6; ++i) reg.add("l2", cache[i], &l2[i], "");
        for (int i = 0; i < 7; ++i) reg.add("dram", mem[i], &dram[i], "");
        const char* cause[] = {"issue",         "l1",        "l2", "dram", "box_unit",
                               "triangle_unit", "ray_buffer"};
        for (int i = 0; i < 7; ++i)
            reg.add("core[0]", std::string("stall_") + cause[i] + "_cycles", &stalls[i], "");
    }
};

}  // namespace

TEST(StatsReport, DerivedFiguresFromCounters) {
    Blocks b;
    ReportInputs in;
    in.stats = &b.reg;
    in.total_cycles = 1000;
    in.clock_ghz = 2.0;  // 1000 cycles = 0.5 us
    in.cores = 1;
    in.triangle_pipelines_per_core = 2;
    in.ray_slots_per_core = 3;
    const auto r = timing_report(in);
    EXPECT_DOUBLE_EQ(r["simulated_seconds"].get<double>(), 0.5e-6);
    EXPECT_DOUBLE_EQ(r["units"]["box_unit[0]"]["utilization"].get<double>(), 0.5);
    EXPECT_DOUBLE_EQ(r["units"]["triangle_unit[0]"]["utilization"].get<double>(),
                     0.1);  // 200 / (1000 * 2)
    EXPECT_DOUBLE_EQ(r["caches"]["l1[0]"]["hit_rate"].get<double>(), 0.9);
    EXPECT_DOUBLE_EQ(r["caches"]["l2"]["hit_rate"].get<double>(), 0.6);
    EXPECT_EQ(r["bandwidth"]["l2"]["bytes"].get<uint64_t>(), 6400u);
    EXPECT_DOUBLE_EQ(r["bandwidth"]["dram"]["gbps"].get<double>(), 2560 / 0.5e-6 / 1e9);
    EXPECT_EQ(r["counters"]["l1[0].misses"].get<uint64_t>(), 100u);
    EXPECT_DOUBLE_EQ(r["bandwidth"]["dram"]["row_hit_rate"].get<double>(), 0.75);
    // 3 slots x 1000 cycles, 2100 charged: 900 without work.
    EXPECT_EQ(r["stalls"]["total"]["no_work"].get<uint64_t>(), 900u);
    EXPECT_DOUBLE_EQ(r["stalls"]["core[0]"]["share"]["dram"].get<double>(), 400.0 / 3000.0);
}

TEST(StatsReport, RegistryRejectsDuplicatesAndSums) {
    StatsRegistry reg;
    uint64_t a = 3, b = 4;
    reg.add("l1[0]", "hits", &a, "");
    reg.add("l1[1]", "hits", &b, "");
    EXPECT_THROW(reg.add("l1[0]", "hits", &b, ""), std::logic_error);
    EXPECT_EQ(reg.sum("l1[", "hits"), 7u);
    EXPECT_EQ(reg.get("l1[1].hits"), 4u);
    EXPECT_THROW(reg.get("l1[2].hits"), std::out_of_range);
}

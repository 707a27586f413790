#include <gtest/gtest.h>

#include "../models/fixed_memory.h"
#include "models/cache.h"
#include "models/core.h"
#include "models/crossbar.h"
#include "models/dram.h"
#include "models/unit.h"
#include "sim/stats_report.h"

using namespace rtsim;

// Each block's report section from its own counters, against figures worked by hand: 1000
// cycles at 2 GHz are 0.5 us.
TEST(StatsReport, BlocksDeriveTheirFiguresFromTheirCounters) {
    ReportContext ctx;
    ctx.total_cycles = 1000;
    ctx.clock_ghz = 2.0;
    ctx.rays = 50;
    EXPECT_DOUBLE_EQ(ctx.seconds(), 0.5e-6);

    UnitParams up;
    up.count = 1;
    PipelinedUnit box("box_unit[0]", up);
    box.ops = box.busy_cycles = 500;
    up.count = 2;
    PipelinedUnit tri("triangle_unit[0]", up);
    tri.busy_cycles = 200;
    EXPECT_DOUBLE_EQ(box.report(ctx)["utilization"].get<double>(), 0.5);
    EXPECT_DOUBLE_EQ(tri.report(ctx)["utilization"].get<double>(), 0.1);  // 200 / (1000 * 2)
    // Together: 700 busy of 3 pipelines x 1000 cycles.
    EXPECT_DOUBLE_EQ(PipelinedUnit::report_total({&box, &tri}, ctx)["utilization"].get<double>(),
                     700.0 / 3000.0);

    test::FixedLatencyMemory mem(10);
    Cache l1("l1[0]", CacheParams{}, &mem.up), l1b("l1[1]", CacheParams{}, &mem.up);
    l1.accesses = 1000, l1.hits = 900, l1.misses = 100, l1.fill_bytes = 6400;
    l1b.accesses = 1000, l1b.hits = 500, l1b.misses = 500, l1b.fill_bytes = 32000;
    EXPECT_DOUBLE_EQ(l1.report(ctx)["hit_rate"].get<double>(), 0.9);
    EXPECT_DOUBLE_EQ(Cache::report_total({&l1, &l1b}, ctx)["hit_rate"].get<double>(), 0.7);
    EXPECT_EQ(sum_of<Cache>({&l1, &l1b}, &Cache::fill_bytes), 38400u);

    DramParams dp;
    dp.channels = 2;
    Dram dram("dram", dp);
    dram.reads = 40, dram.bytes = 2560, dram.busy_cycles = 80, dram.row_hits = 30;
    const auto d = dram.report(ctx);
    EXPECT_DOUBLE_EQ(d["gbps"].get<double>(), 2560 / 0.5e-6 / 1e9);
    EXPECT_DOUBLE_EQ(d["row_hit_rate"].get<double>(), 0.75);
    EXPECT_DOUBLE_EQ(d["utilization"].get<double>(), 80.0 / 2000.0);  // two channels' buses

    Crossbar xbar("crossbar", 64.0, &mem.up);
    xbar.bytes = 5000, xbar.busy_cycles = 250;
    EXPECT_DOUBLE_EQ(xbar.report(ctx)["utilization"].get<double>(), 0.25);
}

// Stall attribution: a core of 3 slots over 1000 cycles has 3000 slot cycles. No-work cycles are
// counted as slots idle, not inferred: a core that never ran has none, so what its causes do not
// claim shows as unaccounted instead of hiding as no_work.
TEST(StatsReport, StallSharesAndUnaccountedCycles) {
    test::FixedLatencyMemory mem(0);
    PipelinedUnit box("box", UnitParams{}), tri("tri", UnitParams{});
    struct None : RayWorkSource {
        bool next(RayWork&, Cycle) override { return false; }
    } none;
    CoreParams cp;
    cp.ray_slots = 3;
    Core core("core[0]", cp, {&mem.up, &mem.up}, {&box.up, &tri.up}, &none);
    // issue, l1, l2, dram, crossbar, box_unit, triangle_unit, ray_buffer: 2100 charged.
    const uint64_t charged[Core::kStallKinds] = {100, 200, 300, 400, 0, 500, 600, 0};
    for (int k = 0; k < Core::kStallKinds; ++k) core.stall_cycles[k] = charged[k];
    ReportContext ctx;
    ctx.total_cycles = 1000;
    const auto e = core.stall_report(ctx);
    EXPECT_EQ(e["slot_cycles"].get<uint64_t>(), 3000u);
    EXPECT_EQ(e["no_work"].get<uint64_t>(), 0u);
    EXPECT_EQ(e["unaccounted_cycles"].get<int64_t>(), 900);
    EXPECT_DOUBLE_EQ(e["share"]["dram"].get<double>(), 400.0 / 3000.0);
    EXPECT_EQ(Core::stall_report_total({&core}, ctx), e);
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

#include <gtest/gtest.h>

#include "models/dram.h"

using namespace rtsim;

TEST(Dram, StreamsAtPeakBytesPerCycle) {
    Dram d("dram", DramParams{100, 32.0});
    const uint64_t n = 1000;
    Cycle last = 0;
    for (uint64_t i = 0; i < n; ++i) last = d.access(i * 64, 64, 0);
    // 64 bytes at 32 bytes per cycle: 2 cycles each, back to back, plus the access latency.
    EXPECT_EQ(last, 2 * n + 100);
    EXPECT_EQ(d.bytes, 64 * n);
    EXPECT_EQ(d.busy_cycles, 2 * n);
}

TEST(Dram, FractionalBandwidthIsExactOverTime) {
    Dram d("dram", DramParams{10, 12.8});
    Cycle last = 0;
    for (int i = 0; i < 10; ++i) last = d.access(0, 64, 0);
    EXPECT_EQ(last, 50u + 10);  // 640 bytes / 12.8 = 50 cycles
}

TEST(Dram, IdleChannelServesAtLatency) {
    Dram d("dram", DramParams{100, 32.0});
    EXPECT_EQ(d.access(0, 64, 1000), 1000u + 2 + 100);
    EXPECT_EQ(d.queue_cycles, 0u);
}

#include <gtest/gtest.h>

#include "models/dram.h"

using namespace rtsim;

namespace {
// A bandwidth-only DRAM: one channel, one bank, no row timings; `latency` after the bus.
DramParams bus_only(Cycle latency, double bytes_per_cycle) {
    DramParams p;
    p.latency_cycles = latency;
    p.bytes_per_cycle = bytes_per_cycle;
    p.channels = 1;
    p.banks = 1;
    p.t_rcd_cycles = p.t_cas_cycles = p.t_rp_cycles = p.t_ccd_cycles = 0;
    return p;
}
}  // namespace

TEST(Dram, StreamsAtPeakBytesPerCycle) {
    Dram d("dram", bus_only(100, 32.0));
    const uint64_t n = 1000;
    Cycle last = 0;
    for (uint64_t i = 0; i < n; ++i) last = d.access(i * 64, 64, 0);
    // 64 bytes at 32 bytes per cycle: 2 cycles each, back to back, plus the access latency.
    EXPECT_EQ(last, 2 * n + 100);
    EXPECT_EQ(d.bytes, 64 * n);
    EXPECT_EQ(d.busy_cycles, 2 * n);
}

TEST(Dram, FractionalBandwidthIsExactOverTime) {
    Dram d("dram", bus_only(10, 12.8));
    Cycle last = 0;
    for (int i = 0; i < 10; ++i) last = d.access(0, 64, 0);
    EXPECT_EQ(last, 50u + 10);  // 640 bytes / 12.8 = 50 cycles
}

TEST(Dram, IdleChannelServesAtLatency) {
    Dram d("dram", bus_only(100, 32.0));
    EXPECT_EQ(d.access(0, 64, 1000), 1000u + 2 + 100);
    EXPECT_EQ(d.queue_cycles, 0u);
}

namespace {
DramParams rows(int channels, int banks) {
    DramParams p;
    p.latency_cycles = 10;
    p.bytes_per_cycle = 64.0;  // one burst per cycle: the bus stays out of the way
    p.channels = channels;
    p.banks = banks;
    p.row_bytes = 1024;
    p.t_rcd_cycles = 20;
    p.t_cas_cycles = 10;
    p.t_rp_cycles = 15;
    p.t_ccd_cycles = 4;
    return p;
}
}  // namespace

TEST(Dram, RowHitEmptyAndConflictLatencies) {
    Dram d("dram", rows(1, 2));
    // Empty bank: tRCD + tCAS, one burst, controller latency.
    EXPECT_EQ(d.access(0, 64, 0), 0u + 20 + 10 + 1 + 10);
    // Same row, later: a row hit costs tCAS only.
    EXPECT_EQ(d.access(64, 64, 1000), 1000u + 10 + 1 + 10);
    // Row 2 maps to bank 0 again (rows interleave over 2 banks): a conflict, tRP + tRCD + tCAS.
    EXPECT_EQ(d.access(2 * 1024, 64, 2000), 2000u + 15 + 20 + 10 + 1 + 10);
    EXPECT_EQ(d.row_empty, 1u);
    EXPECT_EQ(d.row_hits, 1u);
    EXPECT_EQ(d.row_conflicts, 1u);
}

TEST(Dram, BanksWorkInParallelOneBankSerialises) {
    // Two reads at once to different banks overlap; to different rows of one bank they serialise.
    Dram two("dram2", rows(1, 2));
    two.access(0, 64, 0);
    EXPECT_EQ(two.access(1024, 64, 0), 0u + 30 + 2 + 10);  // waits only for the bus (1 cycle)
    Dram one("dram1", rows(1, 1));
    one.access(0, 64, 0);  // column command at 20: the bank takes the next one at 24
    EXPECT_EQ(one.access(1024, 64, 0), 24u + 15 + 20 + 10 + 1 + 10);  // a conflict after it
    // Reads to the open row pipeline tCCD apart: the third read's data follows 2 * tCCD later.
    Dram open("dram3", rows(1, 1));
    open.access(0, 64, 0);
    open.access(64, 64, 0);
    EXPECT_EQ(open.access(128, 64, 0), 20u + 2 * 4 + 10 + 1 + 10);
}

TEST(Dram, RowLocalityStreamsAtPeakAcrossChannels) {
    // A long sequential stream hits open rows and keeps both channels' buses busy: 2 channels of
    // 16 bytes per cycle move 64-byte bursts at 32 bytes per cycle overall.
    DramParams p = rows(2, 4);
    p.bytes_per_cycle = 16.0;
    Dram d("dram", p);
    const uint64_t n = 4096;
    Cycle last = 0;
    for (uint64_t i = 0; i < n; ++i) last = std::max(last, d.access(i * 64, 64, 0));
    EXPECT_NEAR(double(last), double(n * 64) / 32.0, 0.02 * double(n * 64) / 32.0 + 60);
    EXPECT_GT(d.row_hits, n * 9 / 10);  // 16 bursts per 1 KiB row: one activate per row
}

// A bank keeps one next-free cycle and its open row: a request reaching it after a later one is
// served out of time order, and counted (a probe with one bank).
TEST(Dram, BankRequestsOutOfTimeOrderAreCounted) {
    Dram d("dram_ooo", rows(1, 1));
    d.access(0, 64, 1000);
    d.access(64, 64, 2000);
    EXPECT_EQ(d.bank_out_of_order, 0u);
    d.access(128, 64, 0);
    EXPECT_EQ(d.bank_out_of_order, 1u);
    EXPECT_EQ(d.out_of_order_requests(), 1u);
}

// A write takes its bank and the bus as a read would (the write data crosses the same bus), and
// is accepted at once: a read behind it in the same bank waits for the write's column command.
TEST(Dram, WritesTakeTheBankAndTheBusAndAreCounted) {
    Dram d("dram", rows(1, 2));
    EXPECT_EQ(d.write(0, 64, 0), 0u);  // posted
    // The write: empty bank, column at 20, the bank free for the next column at 24; its data
    // on the bus 30..31. The read of the same row: a row hit at 24, data at 34, bus 34..35.
    EXPECT_EQ(d.access(64, 64, 0), 24u + 10 + 1 + 10);
    EXPECT_EQ(d.writes, 1u);
    EXPECT_EQ(d.reads, 1u);
    EXPECT_EQ(d.write_bytes, 64u);
    EXPECT_EQ(d.bytes, 128u);
    EXPECT_EQ(d.row_empty, 1u);
    EXPECT_EQ(d.row_hits, 1u);
}

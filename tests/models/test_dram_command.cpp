// The command-level DRAM controller against timelines computed by hand from the DDR4-3200
// timings (tRCD = CL = 22, CWL = 16, burst 4 cycles, tCCD_S/L = 4/8, tRRD_S/L = 4/8,
// tFAW = 34, tRAS = 52, tRP = 22, tRTP = 12, tWTR_S/L = 4/12, tREFI = 12480, tRFC = 560).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "models/dram.h"
#include "models/dram_command.h"
#include "models/dram_device.h"

using namespace rtsim;

namespace {

DramDeviceSpec ddr4(const char* mapping = "rochrababgco", bool refresh = false) {
    DramDeviceSpec s;
    s.address_mapping = mapping;
    s.refresh = refresh;
    return s;
}

// Offers n reads of consecutive bursts from address 0, all arriving at cycle 0 (each waits
// for queue room), and runs to the end; returns the last data cycle.
uint64_t stream_reads(DramController& d, uint64_t n, uint64_t stride_bytes = 64) {
    uint64_t t = 0;
    for (uint64_t i = 0; i < n; ++i)
        while (!d.enqueue(i, i * stride_bytes, false, t)) t = d.now() + 1;
    d.drain();
    uint64_t last = 0;
    for (const auto& c : d.completions()) last = std::max(last, c.cycle);
    return last;
}

std::vector<DramCommandRecord> of_kind(const DramController& d, DramCommand k) {
    std::vector<DramCommandRecord> out;
    for (const auto& c : d.commands())
        if (c.cmd == k) out.push_back(c);
    return out;
}

}  // namespace

TEST(DramCommand, AddressMappingSplitsFieldsFromTheLowBitsUp) {
    // rochrababgco, 64-byte bursts: 6 offset bits, 7 column bits (1024 columns / BL 8), 2 bank
    // group bits, 2 bank bits, 16 row bits. 0x12345678 >> 6 = 0x48D159: column 0x59, then
    // 0x91A2: bank group 2, then 0x2468: bank 0, row 0x91A.
    const DramAddress a = DramAddressMap(ddr4()).map(0x12345678);
    EXPECT_EQ(a.column, 0x59u);
    EXPECT_EQ(a.bankgroup, 2);
    EXPECT_EQ(a.bank, 0);
    EXPECT_EQ(a.row, 0x91Au);
    EXPECT_EQ(a.channel, 0);
    EXPECT_EQ(a.rank, 0);
}

TEST(DramCommand, IdleReadIsActivateThenReadAfterTrcd) {
    DramController d(ddr4());
    d.record_commands(true);
    ASSERT_TRUE(d.enqueue(7, 0x1000, false, 100));
    d.drain();
    ASSERT_EQ(d.completions().size(), 1u);
    // ACT at 100, RD at 100 + tRCD, last data CL + burst later.
    EXPECT_EQ(d.completions()[0].cycle, 100u + 22 + 22 + 4);
    ASSERT_EQ(d.commands().size(), 2u);
    EXPECT_EQ(d.commands()[0].cmd, DramCommand::Act);
    EXPECT_EQ(d.commands()[0].cycle, 100u);
    EXPECT_EQ(d.commands()[1].cmd, DramCommand::Rd);
    EXPECT_EQ(d.commands()[1].cycle, 122u);
    EXPECT_EQ(d.counters().row_misses, 1u);
    EXPECT_EQ(d.counters().read_latency_sum, 48u);
}

TEST(DramCommand, StreamAcrossBankGroupsRunsAtPeakBandwidth) {
    // Bank group in the lowest bits: consecutive bursts alternate groups, so reads issue every
    // tCCD_S = burst = 4 cycles. N reads (over several rows, opened ahead while streaming) end
    // at tRCD + CL + 4 N: the pipeline of latency tRCD + CL + burst and interval 4.
    DramController d(ddr4("rorabachcobg"));
    const uint64_t n = 4096;  // 8 rows of 512 bursts
    EXPECT_EQ(stream_reads(d, n), 22u + 22u + 4u * n);
    EXPECT_EQ(d.counters().reads, n);
    EXPECT_EQ(d.counters().acts, 8u * 4u);  // each row once per bank group
    EXPECT_EQ(d.counters().row_hits, n - 32);
}

TEST(DramCommand, StreamWithinOneBankGroupIsLimitedByTccdL) {
    // Column in the lowest bits: one bank, reads every tCCD_L = 8 cycles: half the peak.
    DramController d(ddr4("rochrababgco"));
    const uint64_t n = 128;  // one row
    EXPECT_EQ(stream_reads(d, n), 22u + 8u * (n - 1) + 22u + 4u);
}

TEST(DramCommand, FourActivatesPerTfawWindow) {
    // Eight reads to eight banks, two per bank group, all closed. Activates: 0, 4, 8, 12
    // (tRRD_S between groups), then the fifth waits for tFAW after the first: 34, 38, 42, 46.
    // tRCD is raised so no read competes for the command bus meanwhile.
    DramDeviceSpec s = ddr4("rochrababgco");
    s.t_rcd = 100;
    DramController d(s);
    d.record_commands(true);
    const uint64_t bank_group_bytes = 64 * 128, bank_bytes = bank_group_bytes * 4;
    int id = 0;
    for (int ba = 0; ba < 2; ++ba)
        for (int bg = 0; bg < 4; ++bg)
            ASSERT_TRUE(d.enqueue(uint64_t(id++),
                                  uint64_t(ba) * bank_bytes + uint64_t(bg) * bank_group_bytes,
                                  false, 0));
    d.drain();
    const auto acts = of_kind(d, DramCommand::Act);
    ASSERT_EQ(acts.size(), 8u);
    const uint64_t expected[] = {0, 4, 8, 12, 34, 38, 42, 46};
    for (size_t i = 0; i < 8; ++i) EXPECT_EQ(acts[i].cycle, expected[i]) << i;
}

TEST(DramCommand, GraphicsMemoriesAllowThirtyTwoActivatesPerT32aw) {
    // 64 banks, tFAW and tRRD out of the way (0 and 1): 33 reads to 33 banks arriving at 0
    // activate at 0, 1, ..., 31; the 33rd waits for the first + t_32aw = 100. Without the
    // window it goes at 32.
    for (const int t32aw : {0, 100}) {
        DramDeviceSpec s = ddr4("rochrababgco");
        s.banks_per_group = 16;
        s.rows = 1 << 14;
        s.t_faw = 0;
        s.t_rrd_s = s.t_rrd_l = 1;
        s.t_rcd = 1000;  // no read competes for the command bus meanwhile
        s.read_queue = 64;
        s.t_32aw = t32aw;
        DramController d(s);
        d.record_commands(true);
        for (uint64_t i = 0; i < 33; ++i) ASSERT_TRUE(d.enqueue(i, i * 64 * 128, false, 0));
        d.drain();
        const auto acts = of_kind(d, DramCommand::Act);
        ASSERT_EQ(acts.size(), 33u);
        EXPECT_EQ(acts[31].cycle, 31u);
        EXPECT_EQ(acts[32].cycle, t32aw ? 100u : 32u);
    }
}

TEST(DramCommand, ActivateToWriteTakesTrcdWrWhereTheDeviceHasOne) {
    // GDDR and HBM time an activate to a write by tRCDWR: ACT at 100, WR at 100 + 15, not
    // 100 + tRCD (22).
    for (const int rcd_wr : {0, 15}) {
        DramDeviceSpec s = ddr4();
        s.t_rcd_wr = rcd_wr;
        DramController d(s);
        d.record_commands(true);
        ASSERT_TRUE(d.enqueue(1, 0x1000, true, 100));
        d.drain();
        const auto wr = of_kind(d, DramCommand::Wr);
        ASSERT_EQ(wr.size(), 1u);
        EXPECT_EQ(wr[0].cycle, rcd_wr ? 115u : 122u);
    }
}

TEST(DramCommand, RefreshCostsAboutTrfcOverTrefi) {
    // A long peak-rate stream loses the refresh's share of time: tRFC / tREFI = 4.5%, plus the
    // precharge and re-activation around each refresh.
    const uint64_t n = 60000;  // 240,000 cycles: 19 refreshes
    DramController without(ddr4("rorabachcobg", false)), with(ddr4("rorabachcobg", true));
    const double t0 = double(stream_reads(without, n)), t1 = double(stream_reads(with, n));
    const double overhead = t1 / t0 - 1.0, share = 560.0 / 12480.0;
    EXPECT_GT(overhead, share);
    EXPECT_LT(overhead, share + (22.0 + 22.0 + 52.0) / 12480.0);  // + tRP + tRCD + tRAS
    // One refresh per tREFI, each rank's first one tREFI in.
    EXPECT_NEAR(double(with.counters().refs), t1 / 12480.0, 1.0);
    EXPECT_EQ(without.counters().refs, 0u);
}

TEST(DramCommand, WriteToReadTurnaroundIsTwtrAfterTheWriteData) {
    // A write to bank group 0 (ACT at 0, WR at tRCD = 22, its data ends at 22 + CWL 16 + 4 =
    // 42); a read arriving after it waits tWTR after that: tWTR_L = 12 in the same group (54),
    // tWTR_S = 4 in another (46; its own ACT at 23 would allow 45).
    for (const bool same_group : {true, false}) {
        DramController d(ddr4("rochrababgco"));
        d.record_commands(true);
        ASSERT_TRUE(d.enqueue(1, 0, true, 0));
        d.run_until(22);
        ASSERT_EQ(of_kind(d, DramCommand::Wr).size(), 1u);
        const uint64_t read_addr = same_group ? 64 : 64 * 128;  // next column, or bank group 1
        ASSERT_TRUE(d.enqueue(2, read_addr, false, 23));
        d.drain();
        const auto rd = of_kind(d, DramCommand::Rd);
        ASSERT_EQ(rd.size(), 1u);
        EXPECT_EQ(rd[0].cycle, same_group ? 54u : 46u);
    }
}

TEST(DramCommand, AStoppedDataClockCostsAWckSyncBeforeTheColumnCommand) {
    // LPDDR5's rule on the DDR4 timings: WCK sync 1 cycle, postamble 1. Read A (arrives 100):
    // ACT 100, column ready at 122, WCK stopped: sync at 122, RD 123, data ends 149, WCK runs to
    // 150. Read B (same row, arrives 140): WCK running, RD at 140 (tCCD_L from 123 allows 131).
    // Read C (same row, arrives 300): WCK stopped since 167: sync at 300, RD 301.
    DramDeviceSpec s = ddr4();
    s.wck_sync_cycles = 1;
    s.wck_postamble_cycles = 1;
    DramController d(s);
    d.record_commands(true);
    ASSERT_TRUE(d.enqueue(1, 0, false, 100));
    d.run_until(139);
    ASSERT_TRUE(d.enqueue(2, 64, false, 140));
    d.run_until(299);
    ASSERT_TRUE(d.enqueue(3, 128, false, 300));
    d.drain();
    const auto rd = of_kind(d, DramCommand::Rd);
    ASSERT_EQ(rd.size(), 3u);
    EXPECT_EQ(rd[0].cycle, 123u);
    EXPECT_EQ(rd[1].cycle, 140u);
    EXPECT_EQ(rd[2].cycle, 301u);
    EXPECT_EQ(d.counters().wck_syncs, 2u);
    EXPECT_EQ(d.counters().read_latency_sum, (149u - 100) + (140 + 26 - 140) + (301 + 26 - 300));
}

// Two ranks share the data bus, with tRTRS (1) between bursts of different ranks. Reads to rank 0
// and rank 1 at cycle 0: ACT r0 at 0, ACT r1 at 1 (one command a cycle); RD r0 at tRCD = 22 (data
// 44..48); r1's bank is ready at 23, but its data may start only at 48 + 1 = 49, so RD r1 at
// 49 - CL = 27 (data 49..53). Its cycles in between the controller skips as idle: this is the
// one wait that ends on a rank switch's gap.
TEST(DramCommand, ARankSwitchWaitsTrtrsOnTheDataBus) {
    DramDeviceSpec spec = ddr4("rochrababgco");
    spec.ranks = 2;
    ASSERT_EQ(spec.check(), "");
    const uint64_t rank1 = uint64_t(1) << (6 + 7 + 2 + 2);  // offset, column, bank group, bank
    ASSERT_EQ(DramAddressMap(spec).map(rank1).rank, 1);
    DramController d(spec);
    d.record_commands(true);
    ASSERT_TRUE(d.enqueue(1, 0, false, 0));
    ASSERT_TRUE(d.enqueue(2, rank1, false, 0));
    d.drain();
    const auto act = of_kind(d, DramCommand::Act), rd = of_kind(d, DramCommand::Rd);
    ASSERT_EQ(act.size(), 2u);
    ASSERT_EQ(rd.size(), 2u);
    EXPECT_EQ(act[1].cycle, 1u);
    EXPECT_EQ(rd[0].cycle, 22u);
    EXPECT_EQ(rd[0].rank, 0);
    EXPECT_EQ(rd[1].cycle, 27u);
    EXPECT_EQ(rd[1].rank, 1);
    std::map<uint64_t, uint64_t> done;
    for (const auto& c : d.completions()) done[c.id] = c.cycle;
    EXPECT_EQ(done[1], 48u);
    EXPECT_EQ(done[2], 53u);
}

TEST(DramCommand, ReadToWriteLeavesTheBusTurnaround) {
    // A read at 22 (data 44..48) then a write to the open row: its data may start tRTRS after
    // the read's, so WR >= 22 + CL + burst + tRTRS - CWL = 33.
    DramController d(ddr4("rochrababgco"));
    d.record_commands(true);
    ASSERT_TRUE(d.enqueue(1, 0, false, 0));
    d.run_until(22);
    ASSERT_TRUE(d.enqueue(2, 64, true, 23));
    d.drain();
    const auto wr = of_kind(d, DramCommand::Wr);
    ASSERT_EQ(wr.size(), 1u);
    EXPECT_EQ(wr[0].cycle, 33u);
}

TEST(DramCommand, ClosedPageActivatesForEveryAccess) {
    // Two reads of one row: auto-precharge closes it after the first (at tRAS = 52, later than
    // RD + tRTP = 34), so the second activates again at 52 + tRP = 74 (= tRC), reads at 96.
    DramDeviceSpec s = ddr4("rochrababgco");
    s.open_page = false;
    DramController d(s);
    d.record_commands(true);
    ASSERT_TRUE(d.enqueue(1, 0, false, 0));
    ASSERT_TRUE(d.enqueue(2, 64, false, 0));
    d.drain();
    const auto acts = of_kind(d, DramCommand::Act), rds = of_kind(d, DramCommand::Rd);
    ASSERT_EQ(acts.size(), 2u);
    EXPECT_EQ(acts[1].cycle, 74u);
    EXPECT_EQ(rds[1].cycle, 96u);
    EXPECT_EQ(d.counters().row_hits, 0u);
    // Open page: the second read is a row hit at 22 + tCCD_L.
    DramController o(ddr4("rochrababgco"));
    o.record_commands(true);
    ASSERT_TRUE(o.enqueue(1, 0, false, 0));
    ASSERT_TRUE(o.enqueue(2, 64, false, 0));
    o.drain();
    EXPECT_EQ(of_kind(o, DramCommand::Rd)[1].cycle, 30u);
    EXPECT_EQ(o.counters().row_hits, 1u);
}

TEST(DramCommand, FrFcfsServesAYoungerRowHitBeforeAnOlderConflict) {
    // Row A is open (read at 0). At 30 a read of row B arrives, then one of row A: the hit
    // reads at 30; the conflict precharges at tRAS = 52, activates at 74, reads at 96.
    DramController d(ddr4("rochrababgco"));
    d.record_commands(true);
    const uint64_t row_bytes = 64 * 128 * 16;  // a row spans columns, bank groups and banks
    ASSERT_TRUE(d.enqueue(1, 0, false, 0));
    ASSERT_TRUE(d.enqueue(2, row_bytes, false, 30));  // row B, same bank
    ASSERT_TRUE(d.enqueue(3, 128, false, 30));        // row A
    d.drain();
    std::map<uint64_t, uint64_t> done;
    for (const auto& c : d.completions()) done[c.id] = c.cycle;
    EXPECT_EQ(done[3], 30u + 22 + 4);
    EXPECT_EQ(done[2], 96u + 22 + 4);
    EXPECT_EQ(of_kind(d, DramCommand::Pre).at(0).cycle, 52u);
    EXPECT_EQ(d.counters().row_misses, 1u);
    EXPECT_EQ(d.counters().row_hits, 1u);
    EXPECT_EQ(d.counters().row_conflicts, 1u);
}

TEST(DramCommand, WritesDrainAtTheHighWatermark) {
    // Writes wait while reads flow; at 24 queued they drain down to 8.
    DramController d(ddr4("rorabachcobg"));
    uint64_t id = 0;
    for (int i = 0; i < 24; ++i) ASSERT_TRUE(d.enqueue(id++, 1 << 20 | uint64_t(i) * 64, true, 0));
    EXPECT_EQ(d.counters().write_drains, 0u);
    d.run_until(0);
    EXPECT_EQ(d.counters().write_drains, 1u);
    d.drain();
    EXPECT_EQ(d.counters().writes, 24u);
}

TEST(DramCommand, ReadOfAQueuedWriteIsServedFromTheQueue) {
    DramController d(ddr4());
    ASSERT_TRUE(d.enqueue(1, 4096, true, 0));
    ASSERT_TRUE(d.enqueue(2, 4096, false, 0));
    ASSERT_EQ(d.completions().size(), 1u);
    EXPECT_EQ(d.completions()[0].id, 2u);
    EXPECT_EQ(d.completions()[0].cycle, 1u);
}

TEST(DramCommand, EnergyPerCommandFollowsTheCurrents) {
    // DDR4-3200 x8, 8 devices a rank, 1.2 V, 0.625 ns: an activate-precharge pair costs
    // VDD (IDD0 tRC - IDD3N tRAS - IDD2N tRP) tCK x 8 = 6 (57*74 - 52*52 - 37*22) = 4200 pJ;
    // a read burst 6 (IDD4R - IDD3N) 4 = 2784 pJ; background until cycle 1000 is active
    // standby while the row is open: 6 x 52 = 312 pJ a cycle, precharged 6 x 37 = 222.
    DramController d(ddr4());
    ASSERT_TRUE(d.enqueue(1, 0, false, 0));
    d.run_until(999);
    d.settle_background();
    EXPECT_NEAR(d.counters().act_pj, 4200.0, 1e-6);
    EXPECT_NEAR(d.counters().read_pj, 2784.0, 1e-6);
    EXPECT_NEAR(d.counters().background_pj, 1000 * 312.0, 1e-6);  // the row stays open
}

TEST(DramCommand, InconsistentSpecsAreNamed) {
    DramDeviceSpec s = ddr4();
    EXPECT_EQ(s.check(), "");
    s.rows = 1000;
    EXPECT_NE(s.check().find("rows: expected a power of two"), std::string::npos);
    s = ddr4("rochrababgch");
    EXPECT_NE(s.check().find("field 'ch' appears 2 times"), std::string::npos);
    s = ddr4();
    s.write_low = 30;
    EXPECT_NE(s.check().find("write_low < write_high"), std::string::npos);
}

// FR-FCFS alone lets a stream of row hits hold back an older request to another row of the same
// bank for as long as the stream lasts. With a cap of 100 cycles (the conflict arrived at 1) hits
// stop overtaking it from 101: the hits read at 22, 30, ..., 94 (tCCD_L apart; one is always
// queued), the precharge waits for the last one's tRTP (106), then ACT at 128 (tRP), RD at 150
// (tRCD), last data at 150 + CL 22 + 4 = 176.
TEST(DramCommand, StarvationCapBoundsHowLongRowHitsOvertake) {
    const uint64_t row_bytes = 64 * 128 * 16;  // the next row of the same bank
    for (const int cap : {0, 100}) {
        DramDeviceSpec s = ddr4("rochrababgco");
        s.starvation_cycles = cap;
        DramController d(s);
        ASSERT_TRUE(d.enqueue(0, 0, false, 0));          // opens row A
        ASSERT_TRUE(d.enqueue(1, row_bytes, false, 1));  // row B: a conflict
        uint64_t id = 2;
        // Row-A hits, one every 8 cycles (tCCD_L) for 800 cycles, kept in the queue.
        for (uint64_t t = 2; t < 800; t += 8, ++id)
            ASSERT_TRUE(d.enqueue(id, ((id % 127) + 1) * 64, false, t));
        d.drain();
        uint64_t done_b = 0;
        for (const auto& c : d.completions())
            if (c.id == 1) done_b = c.cycle;
        if (cap == 0) {
            EXPECT_GT(done_b, 800u);  // after the whole stream
        } else {
            EXPECT_EQ(done_b, 176u);
        }
    }
}

namespace {

// DDR4 timings with per-bank refresh: one bank every 1000 cycles, 100 cycles to refresh it,
// 8 from a refresh to another bank's activate, 50 between refreshes.
DramDeviceSpec ddr4_per_bank(int banks_per_refresh = 1) {
    DramDeviceSpec s = ddr4("rochrababgco", true);
    s.refresh_mode = "per_bank";
    s.t_refi_pb = 1000;
    s.t_rfc_pb = 100;
    s.t_pbr2act = 8;
    s.t_pbr2pbr = 50;
    s.refresh_pb_banks = banks_per_refresh;
    return s;
}

constexpr uint64_t kBank1 = 1u << 15, kBank2 = 2u << 15;  // bank group 0, banks 1 and 2
constexpr uint64_t kBank8 = 2u << 13;                     // bank group 2, bank 0

}  // namespace

// Bank 0 is open (ACT 0, RD 22) when its refresh falls due at 1000: PRE at 1000 (tRAS and tRTP
// long past), REFpb at 1022 (tRP). A read to bank 0 arriving at 1001 waits for tRFCpb: ACT at
// 1122. A read to bank 1 arriving at 1001 is not held: ACT 1001. A read to bank 2 arriving at
// 1023 waits tpbR2act after the refresh: ACT 1030. The next refresh (2000) is bank 1's, open
// since 1001: PRE 2000, REFpb 2022. No all-bank REF at all.
TEST(DramCommand, PerBankRefreshClosesAndHoldsOnlyItsBank) {
    DramController d(ddr4_per_bank());
    d.record_commands(true);
    ASSERT_TRUE(d.enqueue(1, 0, false, 0));
    d.run_until(1000);
    ASSERT_TRUE(d.enqueue(2, 64, false, 1001));  // bank 0, the open row
    ASSERT_TRUE(d.enqueue(3, kBank1, false, 1001));
    d.run_until(1022);
    ASSERT_TRUE(d.enqueue(4, kBank2, false, 1023));
    d.run_until(2500);
    const auto ref = of_kind(d, DramCommand::RefPb);
    ASSERT_EQ(ref.size(), 2u);
    EXPECT_EQ(ref[0].cycle, 1022u);
    EXPECT_EQ(ref[0].bankgroup * 4 + ref[0].bank, 0);
    EXPECT_EQ(ref[1].cycle, 2022u);
    EXPECT_EQ(ref[1].bankgroup * 4 + ref[1].bank, 1);
    std::map<uint64_t, uint64_t> act_of_bank;  // bank index -> last ACT cycle
    for (const auto& a : of_kind(d, DramCommand::Act))
        act_of_bank[uint64_t(a.bankgroup * 4 + a.bank)] = a.cycle;
    EXPECT_EQ(act_of_bank[0], 1122u);
    EXPECT_EQ(act_of_bank[1], 1001u);
    EXPECT_EQ(act_of_bank[2], 1030u);
    const auto pre = of_kind(d, DramCommand::Pre);
    ASSERT_GE(pre.size(), 2u);
    EXPECT_EQ(pre[0].cycle, 1000u);
    EXPECT_EQ(pre[1].cycle, 2000u);
    EXPECT_EQ(d.counters().refs, 0u);
    EXPECT_EQ(d.counters().refs_per_bank, 2u);
    // Energy: with no IDD5PB, a refresh of one bank of 16 costs a sixteenth of an all-bank
    // refresh: 6 (IDD5AB - IDD3N) tRFC / 16 = 6 x 198 x 560 / 16 = 41580 pJ.
    EXPECT_NEAR(d.counters().refresh_pj, 2 * 41580.0, 1e-6);
}

// LPDDR5 refreshes a pair of banks per REFpb: bank k with bank k + 8. The first refresh (1000)
// holds bank 8 as well as bank 0: a read to bank 8 arriving at 1001 activates after tRFCpb
// (REFpb at 1000, both banks closed: ACT 1100), one to bank 1 after tpbR2act only (1008). With
// IDD5PB = 100 mA (the average current refreshing every t_refi_pb) the refresh costs
// 6 (IDD5PB - IDD2N) t_refi_pb = 6 (100 - 37) 1000 = 378000 pJ.
TEST(DramCommand, PerBankRefreshOfABankPairHoldsBoth) {
    DramDeviceSpec s = ddr4_per_bank(2);
    s.idd5pb = 100;
    DramController d(s);
    d.record_commands(true);
    d.run_until(1000);
    ASSERT_TRUE(d.enqueue(1, kBank8, false, 1001));
    ASSERT_TRUE(d.enqueue(2, kBank1, false, 1001));
    d.run_until(1500);
    const auto ref = of_kind(d, DramCommand::RefPb);
    ASSERT_EQ(ref.size(), 1u);
    EXPECT_EQ(ref[0].cycle, 1000u);
    std::map<int, uint64_t> act_of_bank;
    for (const auto& a : of_kind(d, DramCommand::Act))
        act_of_bank[a.bankgroup * 4 + a.bank] = a.cycle;
    EXPECT_EQ(act_of_bank[8], 1100u);
    EXPECT_EQ(act_of_bank[1], 1008u);
    EXPECT_NEAR(d.counters().refresh_pj, 378000.0, 1e-6);
    // A round is 8 refreshes: 8 x 1000 cycles must exceed tRFCpb, and the pair must divide 16.
    s.refresh_pb_banks = 3;
    EXPECT_NE(s.check().find("refresh_pb_banks (3) must divide the 16 banks"), std::string::npos);
    s = ddr4_per_bank();
    s.t_rfc_pb = 0;
    EXPECT_NE(s.check().find("needs t_rfc_pb"), std::string::npos);
}

namespace {

// One channel split into two pseudo-channels on the DDR4 timings; the pseudo-channel bit sits
// just under the row: 6 offset + 7 column + 2 bank group + 2 bank bits, so at bit 17.
DramDeviceSpec two_pseudo_channels(bool dual_command_bus) {
    DramDeviceSpec s = ddr4("ropcchrababgco");
    s.pseudo_channels = 2;
    s.dual_command_bus = dual_command_bus;
    return s;
}

constexpr uint64_t kPc1 = 1u << 17;

}  // namespace

// Two reads to bank 0 of each pseudo-channel, row 0, both at cycle 0: 32 banks in the channel,
// so neither conflicts with the other. One command bus: ACT 0 (pseudo-channel 0 goes first on
// even cycles) and ACT 1, not tRRD_L (8) apart, since each pseudo-channel has its own banks and
// activate windows; RD 22 and 23, and their bursts overlap (44-48 and 45-49) on the two data
// buses.
TEST(DramCommand, PseudoChannelsHaveTheirOwnBanksAndDataBuses) {
    const DramDeviceSpec s = two_pseudo_channels(false);
    EXPECT_EQ(s.check(), "");
    EXPECT_EQ(s.capacity_bytes(), 2 * ddr4().capacity_bytes());
    EXPECT_EQ(DramAddressMap(s).map(kPc1).channel, 1);
    EXPECT_EQ(DramAddressMap(s).map(kPc1 - 64).channel, 0);
    DramController d(s);
    d.record_commands(true);
    ASSERT_TRUE(d.enqueue(1, 0, false, 0));
    ASSERT_TRUE(d.enqueue(2, kPc1, false, 0));
    d.drain();
    const auto act = of_kind(d, DramCommand::Act);
    ASSERT_EQ(act.size(), 2u);
    EXPECT_EQ(act[0].cycle, 0u);
    EXPECT_EQ(act[0].channel, 0);
    EXPECT_EQ(act[1].cycle, 1u);
    EXPECT_EQ(act[1].channel, 1);
    EXPECT_EQ(d.counters().row_conflicts, 0u);
    EXPECT_EQ(d.counters().row_misses, 2u);
    std::map<uint64_t, uint64_t> done;
    for (const auto& c : d.completions()) done[c.id] = c.cycle;
    EXPECT_EQ(done[1], 48u);
    EXPECT_EQ(done[2], 49u);
    // Without the pc field the mapping is refused.
    DramDeviceSpec bad = s;
    bad.address_mapping = "rochrababgco";
    EXPECT_NE(bad.check().find("expected 7 two-letter fields"), std::string::npos);
}

// Read A (pseudo-channel 0) arrives at 0: ACT 0, RD 22. Read C (pseudo-channel 1) arrives at
// 22. With one command bus A's RD takes cycle 22 and C activates at 23; with HBM's separate row
// and column buses both issue at 22.
TEST(DramCommand, DualCommandBusIssuesARowAndAColumnCommandTogether) {
    for (const bool dual : {false, true}) {
        DramController d(two_pseudo_channels(dual));
        d.record_commands(true);
        ASSERT_TRUE(d.enqueue(1, 0, false, 0));
        d.run_until(21);
        ASSERT_TRUE(d.enqueue(2, kPc1, false, 22));
        d.drain();
        const auto rd = of_kind(d, DramCommand::Rd);
        const auto act = of_kind(d, DramCommand::Act);
        ASSERT_EQ(act.size(), 2u);
        EXPECT_EQ(rd[0].cycle, 22u);
        EXPECT_EQ(act[1].cycle, dual ? 22u : 23u) << (dual ? "dual" : "single");
    }
}

// DRAMPower's bank-wise background with rho = 0.5 on the DDR4 currents: I_rho = IDD2N + 0.5
// (IDD3N - IDD2N) = 44.5 mA. Read as IDD3N with one bank open (its LPDDR5 model), each open bank
// adds IDD3N - I_rho = 7.5 mA: one bank open draws IDD3N as before (6 x 52 = 312 pJ a cycle),
// two 59.5 mA (357 pJ a cycle). Reads to bank groups 0 and 1 at cycle 0: ACT 0 and ACT 4
// (tRRD_S), both rows stay open: to cycle 1000, 4 x 312 + 996 x 357 pJ. With rho = 1 (the
// default) it is IDD3N throughout: 1000 x 312. Read as IDD3N with all 16 banks open (its DDR5
// model), each open bank adds 7.5 / 16 mA: 6 (44.5 + 7.5 / 16) = 269.8125 pJ a cycle with one,
// 272.625 with two.
TEST(DramCommand, BankWiseBackgroundChargesEachOpenBank) {
    // Background energy to cycle 1000 with two rows opened at cycle 0 (ACT 0 and 4).
    auto background_pj = [](double rho, int idd3n_open_banks) {
        DramDeviceSpec s = ddr4();
        s.bankwise_rho = rho;
        s.idd3n_open_banks = idd3n_open_banks;
        DramController d(s);
        EXPECT_TRUE(d.enqueue(1, 0, false, 0));
        EXPECT_TRUE(d.enqueue(2, 64 * 128, false, 0));
        d.run_until(999);
        d.settle_background();
        return d.counters().background_pj;
    };
    EXPECT_NEAR(background_pj(0.5, 1), 4 * 312.0 + 996 * 357.0, 1e-6);
    EXPECT_NEAR(background_pj(1.0, 1), 1000 * 312.0, 1e-6);
    EXPECT_NEAR(background_pj(0.5, 0), 4 * 269.8125 + 996 * 272.625, 1e-6);
    DramDeviceSpec bad = ddr4();
    bad.bankwise_rho = 1.5;
    EXPECT_NE(bad.check().find("bankwise_rho"), std::string::npos);
}

// The fast engine's use of the controller (dram.model = command, MemoryPort calls under a time
// floor): a request is held until the floor passes it, and its completion is predicted on a copy
// of the controller given every held request that arrived before it. The model starts its copies
// from snapshots; the reference here is the rule as stated, replaying every held request into a
// fresh copy for each prediction. Requests come out of time order (up to 400 cycles back, as
// the cores of the fast engine send them), with row conflicts, writes and refresh.
TEST(DramCommand, FastModelPredictsWhatAReplayOfEveryHeldRequestWould) {
    DramParams p;
    p.chip_clock_ghz = 1.0;
    p.latency_cycles = 20;
    const DramDeviceSpec spec = command_dram_spec(p);
    auto model = DramModelRegistry::at("command").make("fast_replay_dram", p);
    TimeFloor floor;
    model->follow(&floor);

    struct Held {
        uint64_t chip, seq, addr;
        uint32_t size_bytes;
        bool write;
    };
    std::vector<Held> held;  // the reference's, in (cycle, arrival) order
    DramController real(spec);
    uint64_t next_id = 0;
    const double device_per_chip = 1.0 / p.chip_clock_ghz / spec.tck_ns;
    auto to_device = [&](uint64_t chip) {
        return uint64_t(std::ceil(double(chip) * device_per_chip - 1e-9));
    };
    auto to_chip = [&](uint64_t device) {
        return uint64_t(std::ceil(double(device) / device_per_chip - 1e-9));
    };
    // A request's bursts enter `c` from its cycle on, each waiting for room in a full queue;
    // returns the device cycle the last one entered.
    auto put = [&](DramController& c, uint64_t& id, const Held& h) {
        const uint64_t burst = spec.burst_bytes();
        const uint64_t count = std::max<uint64_t>(1, (h.size_bytes + burst - 1) / burst);
        uint64_t entered = to_device(h.chip);
        for (uint64_t k = 0; k < count; ++k, ++id) {
            uint64_t at = std::max(to_device(h.chip), c.now());
            while (!c.enqueue(id, h.addr / burst * burst + k * burst, h.write, at))
                at = c.now() + 1;
            entered = std::max(entered, at);
        }
        return entered;
    };

    std::mt19937_64 rng(20261208);
    uint64_t front = 1000, addr = 0, seq = 0;
    size_t most_held_before = 0;
    for (int n = 0; n < 1500; ++n) {
        front += rng() % 6;
        const uint64_t chip = rng() % 10 < 3 ? front - rng() % 400 : front;
        if (rng() % 10 < 7)
            addr += 64;  // streams along a row
        else
            addr = (rng() % (1u << 26)) & ~uint64_t(63);  // anywhere: conflicts
        const Held h{chip, seq++, addr, uint32_t(rng() % 4 == 0 ? 128 : 64), rng() % 5 == 0};
        floor.cycle = front - 400;  // no request comes from before it

        // The reference: release what the floor passed, then replay for this one.
        size_t k = 0;
        for (; k < held.size() && held[k].chip < floor.cycle; ++k) put(real, next_id, held[k]);
        held.erase(held.begin(), held.begin() + std::ptrdiff_t(k));
        real.completions().clear();
        const auto at =
            std::upper_bound(held.begin(), held.end(), h, [](const Held& a, const Held& b) {
                return a.chip != b.chip ? a.chip < b.chip : a.seq < b.seq;
            });
        const size_t before = size_t(at - held.begin());
        most_held_before = std::max(most_held_before, before);
        DramController copy = real;
        copy.completions().clear();
        uint64_t id = next_id;
        for (size_t j = 0; j < before; ++j) put(copy, id, held[j]);
        const uint64_t first = id;
        const uint64_t entered = put(copy, id, h);
        uint64_t expected;
        if (h.write) {
            expected = std::max(h.chip, to_chip(entered));
        } else {
            uint64_t last = 0, seen = 0;
            while (seen < id - first && copy.pending() > 0) {
                copy.run_until(copy.now());
                for (const auto& c : copy.completions())
                    if (c.id >= first && c.id < id) last = std::max(last, c.cycle), ++seen;
                copy.completions().clear();
            }
            expected = std::max(h.chip + 1, to_chip(last) + p.latency_cycles);
        }
        held.insert(at, h);

        const uint64_t got = h.write ? model->write(h.addr, h.size_bytes, h.chip)
                                     : model->access(h.addr, h.size_bytes, h.chip);
        ASSERT_EQ(got, expected) << "request " << n << (h.write ? " (write)" : " (read)")
                                 << " at chip cycle " << h.chip << ", " << before
                                 << " held before it";
    }
    EXPECT_GT(most_held_before, 100u);  // predictions started far past the model's snapshots
}

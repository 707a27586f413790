// `rtsim dram`: memory traces through the command-level DRAM model, device presets, device
// files and DRAMsim3 .ini imports, against figures worked out by hand.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/run_rtsim.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace rtsim::test;

namespace {

fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = work_dir() / name;
    std::ofstream(p) << text;
    return p;
}

}  // namespace

// 512 reads of consecutive bursts, all wanted at cycle 0, with the bank group in the lowest
// address bits: reads issue every tCCD_S = 4 cycles from tRCD = 22 (DDR4-3200), so the last
// data beat is at 22 + CL 22 + 4 x 512 = 2092 cycles, 32 KiB in 2092 x 0.625 ns.
TEST(DramTrace, StreamRunsAtTheHandComputedRate) {
    std::string text;
    for (int i = 0; i < 512; ++i) text += fmt::format("0x{:x} READ 0\n", i * 64);
    const fs::path trace = write("stream.trace", text), out = work_dir() / "stream";
    const Result r = run_rtsim("dram '" + trace.string() +
                               "' --set address_mapping=rorabachcobg --set refresh=false -o '" +
                               out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = json::parse(slurp(out / "stats.json"));
    EXPECT_EQ(s["cycles"].get<uint64_t>(), 2092u);
    EXPECT_NEAR(s["bandwidth_gbps"].get<double>(), 512.0 * 64 / (2092 * 0.625), 1e-9);
    EXPECT_NEAR(s["peak_gbps"].get<double>(), 64.0 / 4 / 0.625, 1e-9);  // 25.6 GB/s
    EXPECT_EQ(s["commands"]["act"].get<int>(), 4);                      // one row per bank group
    EXPECT_NEAR(s["row_hit_rate"].get<double>(), 508.0 / 512, 1e-12);
    EXPECT_EQ(s["reads"].get<int>(), 512);
    EXPECT_NE(r.out.find("GB/s"), std::string::npos);
}

TEST(DramTrace, BadLinesAndDevicesAreOneLineErrors) {
    const fs::path bad = write("bad.trace", "0x40 READ 0\n0x80 FETCH 3\n"),
                   out = work_dir() / "bad_out";
    expect_one_line_error(run_rtsim("dram '" + bad.string() + "' -o '" + out.string() + "'"),
                          "bad.trace:2: expected '0x<address> READ|WRITE <cycle>', got '0x80 "
                          "FETCH 3'");
    EXPECT_FALSE(fs::exists(out / "stats.json"));
    const fs::path ok = write("ok.trace", "0x40 READ 0\n");
    expect_one_line_error(run_rtsim("dram '" + ok.string() + "' --device DDR9"),
                          "DDR9: not a DRAM device preset (DDR4_8Gb_x8_3200");
    expect_one_line_error(run_rtsim("dram '" + ok.string() + "' --set rows=1000"),
                          "--set rows=1000: rows: expected a power of two, got 1000");
    expect_one_line_error(run_rtsim("dram '" + ok.string() + "' --set t_rcdd=3"),
                          "--set t_rcdd=3: t_rcdd: unknown device field");
    const fs::path dev = write("dev.json", R"({"name": "x", "t_rcd": "fast"})");
    expect_one_line_error(run_rtsim("dram '" + ok.string() + "' --device '" + dev.string() + "'"),
                          "dev.json: t_rcd: expected a whole number");
}

// A DRAMsim3 device config (the format of its configs/*.ini, written out here) reads into the
// same device as the DDR4-3200 preset; its channel_size of 16 GiB over 8 GiB ranks (8 devices
// of 65536 x 1024 x 8 bits x 16 banks) makes 2 ranks.
TEST(DramTrace, Dramsim3IniImportMatchesThePreset) {
    const fs::path ini = write("DDR4_test.ini", R"([dram_structure]
protocol = DDR4
bankgroups = 4
banks_per_group = 4
rows = 65536
columns = 1024
device_width = 8
BL = 8

[timing]
tCK = 0.625
AL = 0
CL = 22
CWL = 16
tRCD = 22
tRP = 22
tRAS = 52
tRFC = 560
tREFI = 12480
tRRD_S = 4
tRRD_L = 8
tWTR_S = 4
tWTR_L = 12
tFAW = 34
tWR = 24
tRTP = 12
tCCD_S = 4
tCCD_L = 8
tCKE = 8
tRTRS = 1 ; rank switch

[power]
VDD = 1.2
IDD0 = 57
IDD2N = 37
IDD3N = 52
IDD4W = 150
IDD4R = 168
IDD5AB = 250
IDD6x = 30

[system]
channel_size = 16384
channels = 1
bus_width = 64
address_mapping = rochrababgco
row_buf_policy = OPEN_PAGE
)");
    const fs::path trace = write("one.trace", "0x1000 READ 5\n");
    const fs::path a = work_dir() / "ini", b = work_dir() / "preset";
    ASSERT_EQ(run_rtsim("dram -q '" + trace.string() + "' --device '" + ini.string() + "' -o '" +
                        a.string() + "'")
                  .status,
              0);
    ASSERT_EQ(run_rtsim("dram -q '" + trace.string() + "' -o '" + b.string() + "'").status, 0);
    json da = json::parse(slurp(a / "stats.json"))["device"],
         db = json::parse(slurp(b / "stats.json"))["device"];
    EXPECT_EQ(da["ranks"].get<int>(), 2);
    EXPECT_EQ(da["name"].get<std::string>(), "DDR4_test");
    // DRAMsim3's controller takes a cycle to schedule an arrival; the preset's takes none.
    EXPECT_EQ(da["frontend_cycles"].get<int>(), 1);
    EXPECT_EQ(db["frontend_cycles"].get<int>(), 0);
    for (const char* k : {"ranks", "name", "frontend_cycles"}) {
        da.erase(k);
        db.erase(k);
    }
    EXPECT_EQ(da, db);
    const fs::path broken = write("broken.ini", "[timing]\ntCK = fast\n");
    expect_one_line_error(
        run_rtsim("dram '" + trace.string() + "' --device '" + broken.string() + "'"),
        "broken.ini: timing.tCK: expected a number, got 'fast'");
}

// DRAMsim3's configs folder reads as DRAMsim3 reads it (its Config class): a key that is missing
// or empty takes DRAMsim3's default (tREFI 7800, tRFC 74, tRTP 5, tRCDRD 24, ...), a number is
// its leading numeric text ("0.666 (1/1.5)", GDDR5X's tCK), graphics and HBM memories time an
// activate to a read by tRCDRD and count columns as DRAMsim3 does (BL words for GDDR, two for
// HBM), and what is not modelled is refused in one line naming it.
TEST(DramTrace, Dramsim3IniFilesReadAsDramsim3ReadsThem) {
    const fs::path trace = write("one_read.trace", "0x1000 READ 5\n");
    auto device = [&](const std::string& name, const std::string& text) {
        const fs::path ini = write(name, text), out = work_dir() / (name + "_out");
        const Result r = run_rtsim("dram -q '" + trace.string() + "' --device '" + ini.string() +
                                   "' -o '" + out.string() + "'");
        EXPECT_EQ(r.status, 0) << r.err;
        return json::parse(slurp(out / "stats.json"));
    };
    // A DDR3 file with no tREFI, tWTR_L, tRTP or power section (as DRAMsim3's DDR3 files).
    const json ddr3_stats = device("ddr3_defaults.ini", R"([dram_structure]
protocol = DDR3
bankgroups = 1
banks_per_group = 8
rows = 65536
columns = 2048
device_width = 8
BL = 8
[timing]
tCK = 1.25
CL = 11
CWL = 8
tRCD = 11
tRP = 11
tRAS = 28
tRFC = 280
tWTR_S = 6
)");
    const json& ddr3 = ddr3_stats["device"];
    EXPECT_EQ(ddr3["t_refi"].get<int>(), 7800);
    EXPECT_EQ(ddr3["t_rtp"].get<int>(), 5);
    EXPECT_EQ(ddr3["t_wtr_l"].get<int>(), 6);  // one bank group: the _S timing
    EXPECT_EQ(ddr3["t_rfc"].get<int>(), 280);
    EXPECT_DOUBLE_EQ(ddr3["idd5ab"].get<double>(), 250.0);
    EXPECT_EQ(ddr3["address_mapping"].get<std::string>(), "chrobabgraco");
    EXPECT_EQ(ddr3["t_rcd_wr"].get<int>(), 0);  // DDR times a write's activate by tRCD too
    EXPECT_EQ(ddr3["t_32aw"].get<int>(), 0);    // DRAMsim3: a graphics memory's window only
    // DRAMsim3's controller issues a transaction's first command the cycle after it arrives:
    // one read on an idle bank is back 1 + tRCD 11 + CL 11 + BL/2 4 = 27 cycles after it came.
    EXPECT_EQ(ddr3["frontend_cycles"].get<int>(), 1);
    EXPECT_EQ(ddr3_stats["read_latency_cycles"]["mean"].get<double>(), 27.0);
    // HBM with an empty tRFC; GDDR5X's tCK with its derivation beside it; tRCDRD over tRCD.
    const json hbm_stats = device("hbm_empty.ini", R"([dram_structure]
protocol = HBM
bankgroups = 4
banks_per_group = 2
rows = 16384
columns = 64
device_width = 128
BL = 4
[system]
bus_width = 128
[timing]
tCK = 2
tRCD = 9
tRCDRD = 7
tRFC =
)");
    const json& hbm = hbm_stats["device"];
    EXPECT_EQ(hbm["t_rfc"].get<int>(), 74);
    EXPECT_EQ(hbm["t_rcd"].get<int>(), 7);
    EXPECT_EQ(hbm["columns"].get<int>(), 128);  // DRAMsim3: an HBM column is two words
    EXPECT_EQ(hbm["t_rcd_wr"].get<int>(), 20);  // DRAMsim3's tRCDWR default
    EXPECT_EQ(hbm["t_32aw"].get<int>(), 0);
    EXPECT_TRUE(hbm["dual_command_bus"].get<bool>());  // DRAMsim3's hbm_dual_cmd default
    EXPECT_EQ(hbm["pseudo_channels"].get<int>(), 1);   // DRAMsim3 runs legacy mode
    // DRAMsim3's per-bank refresh policy (no file of its own sets it): tREFIb, tRFCb, IDD5PB.
    const json lpddr4_stats = device("lpddr4_per_bank.ini", R"([dram_structure]
protocol = LPDDR4
bankgroups = 2
banks_per_group = 4
rows = 65536
columns = 1024
device_width = 16
BL = 16
[timing]
tCK = 0.83
tREFI = 8660
tREFIb = 1082
tRFCb = 168
[power]
IDD5PB = 60
[system]
refresh_policy = BANK_LEVEL_STAGGERED
)");
    const json& lpddr4 = lpddr4_stats["device"];
    EXPECT_EQ(lpddr4["refresh_mode"].get<std::string>(), "per_bank");
    EXPECT_EQ(lpddr4["t_refi_pb"].get<int>(), 1082);
    EXPECT_EQ(lpddr4["t_rfc_pb"].get<int>(), 168);
    EXPECT_DOUBLE_EQ(lpddr4["idd5pb"].get<double>(), 60.0);
    EXPECT_FALSE(lpddr4["dual_command_bus"].get<bool>());
    const json gddr5x_stats = device("gddr5x_tck.ini", R"([dram_structure]
protocol = GDDR5X
bankgroups = 4
banks_per_group = 4
rows = 16384
columns = 64
device_width = 32
BL = 16
bankgroup_enable = false
[system]
bus_width = 32
[timing]
tCK = 0.666 (1/1.5)
)");
    const json& gddr5x = gddr5x_stats["device"];
    EXPECT_DOUBLE_EQ(gddr5x["tck_ns"].get<double>(), 0.666);
    EXPECT_EQ(gddr5x["t_rcd"].get<int>(), 24);         // DRAMsim3's tRCDRD default
    EXPECT_EQ(gddr5x["burst_cycles"].get<int>(), 2);   // BL / 8
    EXPECT_EQ(gddr5x["columns"].get<int>(), 64 * 16);  // DRAMsim3: a GDDR column is BL words
    EXPECT_EQ(gddr5x["bankgroups"].get<int>(), 1);
    EXPECT_EQ(gddr5x["banks_per_group"].get<int>(), 16);
    EXPECT_EQ(gddr5x["t_32aw"].get<int>(), 330);  // DRAMsim3's t32AW default
    EXPECT_EQ(gddr5x["t_rcd_wr"].get<int>(), 20);

    // GDDR6 as DRAMsim3's file has it: a 128-bit channel, BL16, so one 64-byte request moves a
    // whole 256-byte burst in BL/16 = 1 cycle; its read is back 1 + tRCDRD 24 + CL 24 + 1 = 50
    // cycles after it came; tRCDWR and t32AW are read for it.
    const json gddr6_stats = device("gddr6_burst.ini", R"([dram_structure]
protocol = GDDR6
bankgroups = 4
banks_per_group = 4
rows = 16384
columns = 128
device_width = 16
BL = 16
bankgroup_enable = false
[system]
bus_width = 128
[timing]
tCK = 0.66
CL = 24
tRCDRD = 24
tRCDWR = 20
t32AW = 420
)");
    EXPECT_EQ(gddr6_stats["bytes"].get<int>(), 256);
    EXPECT_EQ(gddr6_stats["device"]["burst_cycles"].get<int>(), 1);
    EXPECT_EQ(gddr6_stats["read_latency_cycles"]["mean"].get<double>(), 50.0);
    EXPECT_EQ(gddr6_stats["device"]["t_rcd_wr"].get<int>(), 20);
    EXPECT_EQ(gddr6_stats["device"]["t_32aw"].get<int>(), 420);

    const fs::path hmc = write("hmc.ini", "[dram_structure]\nprotocol = HMC\n");
    expect_one_line_error(
        run_rtsim("dram '" + trace.string() + "' --device '" + hmc.string() + "'"),
        "protocol HMC: a hybrid memory cube");
    const fs::path ideal = write("ideal.ini", "[dram_structure]\nprotocol = DDR4\nBL = 0\n");
    expect_one_line_error(
        run_rtsim("dram '" + trace.string() + "' --device '" + ideal.string() + "'"),
        "dram_structure.BL = 0");
    const fs::path odd = write("odd.ini", "[dram_structure]\nprotocol = RDRAM\n");
    expect_one_line_error(
        run_rtsim("dram '" + trace.string() + "' --device '" + odd.string() + "'"),
        "protocol RDRAM: not a protocol");
}

// --commands writes the issued commands: one read of 0x2000 (bank group 1: above 6 offset and 7
// column bits) on an idle DDR4-3200 bank is ACT at its cycle and RD tRCD (22) later; a per-bank
// refresh setting that needs another field names both the device and the settings.
TEST(DramTrace, CommandLogAndSettingsCheckedTogether) {
    const fs::path trace = write("one_read_cmd.trace", "0x2000 READ 10\n");
    const fs::path csv = work_dir() / "commands.csv";
    const Result r =
        run_rtsim("dram -q '" + trace.string() + "' --commands '" + csv.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(slurp(csv),
              "cycle,command,channel,rank,bankgroup,bank,row\n10,ACT,0,0,1,0,0\n32,RD,0,0,1,0,0\n");
    expect_one_line_error(run_rtsim("dram -q '" + trace.string() +
                                    "' --device DDR4_8Gb_x8_3200 --set refresh_mode=per_bank"),
                          "DDR4_8Gb_x8_3200 with --set refresh_mode=per_bank: refresh_mode "
                          "per_bank needs t_rfc_pb");
    const Result ok = run_rtsim("dram -q '" + trace.string() +
                                "' --set refresh_mode=per_bank --set t_rfc_pb=100");
    EXPECT_EQ(ok.status, 0) << ok.err;
}

TEST(DramTrace, EveryPresetLoadsAndRuns) {
    const fs::path trace = write("mix.trace", "0x0 READ 0\n0x40 WRITE 1\n0x100000 READ 2\n");
    for (const char* device : {"DDR4_8Gb_x8_3200", "DDR5_16Gb_x8_4800", "LPDDR5_8Gb_x16_6400",
                               "GDDR6_8Gb_x16_12000", "HBM2_8Gb_x128_2000"}) {
        const fs::path out = work_dir() / device;
        const Result r = run_rtsim("dram -q '" + trace.string() + "' --device " + device + " -o '" +
                                   out.string() + "'");
        ASSERT_EQ(r.status, 0) << device << r.err;
        const json s = json::parse(slurp(out / "stats.json"));
        EXPECT_EQ(s["reads"].get<int>() + s["writes"].get<int>(), 3) << device;
        EXPECT_GT(s["energy_pj"]["total"].get<double>(), 0.0) << device;
        EXPECT_EQ(s["device"]["name"].get<std::string>(), device);
    }
}

// rtsim run --mem-trace: one line per burst that reached DRAM, in time order, which rtsim dram
// replays into the same number of reads.
TEST(DramTrace, RunWritesTheRequestsThatReachDram) {
    const fs::path trace = work_dir() / "run.memtrace", out = work_dir() / "memtrace_run";
    const Result r = run_rtsim(
        "run -q --scene builtin:sphere --res 32x32 --rays primary,ao "
        "--set dram.model=command --mem-trace '" +
        trace.string() + "' -o '" + out.string() + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const json s = json::parse(slurp(out / "stats.json"));
    std::ifstream in(trace);
    std::string addr, op;
    uint64_t cycle = 0, last = 0, lines = 0;
    while (in >> addr >> op >> cycle) {
        EXPECT_EQ(op, "READ");
        EXPECT_EQ(addr.rfind("0x", 0), 0u);
        EXPECT_GE(cycle, last);
        last = cycle;
        ++lines;
    }
    EXPECT_EQ(lines, s["counters"]["dram.reads"].get<uint64_t>());
    EXPECT_EQ(lines * 64, s["bandwidth"]["dram"]["bytes"].get<uint64_t>());
    const fs::path replay = work_dir() / "memtrace_replay";
    ASSERT_EQ(run_rtsim("dram -q '" + trace.string() + "' -o '" + replay.string() + "'").status, 0);
    EXPECT_EQ(json::parse(slurp(replay / "stats.json"))["reads"].get<uint64_t>(), lines);
}

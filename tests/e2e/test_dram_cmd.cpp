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
    for (const char* k : {"ranks", "name"}) {
        da.erase(k);
        db.erase(k);
    }
    EXPECT_EQ(da, db);
    const fs::path broken = write("broken.ini", "[timing]\ntCK = fast\n");
    expect_one_line_error(
        run_rtsim("dram '" + trace.string() + "' --device '" + broken.string() + "'"),
        "broken.ini: missing dram_structure.bankgroups");
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

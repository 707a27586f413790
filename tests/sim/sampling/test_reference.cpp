// sim/sampling/reference.h: reading sampled_units.csv, and the columns counters are summed into.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "sim/sampling/reference.h"
#include "workloads/error.h"

namespace rtsim {
namespace {

TEST(Reference, ParsesAUnitTable) {
    const UnitTable t = parse_units_csv("unit,work,cycles\n0,10,5.5\n1,0,0\n", "u.csv");
    EXPECT_EQ(t.rows, 2u);
    EXPECT_EQ(t.names, (std::vector<std::string>{"unit", "work", "cycles"}));
    EXPECT_EQ(t.cols.at("cycles"), (std::vector<double>{5.5, 0}));
    EXPECT_TRUE(t.has("work"));
    EXPECT_FALSE(t.has("rays"));
}

TEST(Reference, RefusesADamagedTable) {
    auto message = [](const std::string& text) {
        try {
            parse_units_csv(text, "u.csv");
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    EXPECT_EQ(message(""), "u.csv: not a sampled_units.csv (no 'unit,...' header)");
    EXPECT_EQ(message("cycles,unit\n1,2\n"),
              "u.csv: not a sampled_units.csv (no 'unit,...' header)");
    EXPECT_EQ(message("unit,a,a\n0,1,2\n"), "u.csv: a column name appears twice");
    EXPECT_EQ(message("unit,a\n0,1\n1\n"), "u.csv: line 3: 1 fields, the header has 2");
    EXPECT_EQ(message("unit,a\n0,1e999\n"), "u.csv: line 2: '1e999' is not a number");
    EXPECT_EQ(message("unit,a\n0,\n"), "u.csv: line 2: '' is not a number");
    EXPECT_EQ(message("unit,a\n0,1,2\n"), "u.csv: line 2: 3 fields, the header has 2");
    EXPECT_EQ(message("unit,a\n0,3x\n"), "u.csv: line 2: '3x' is not a number");
}

TEST(Reference, LikeBlocksShareAColumn) {
    EXPECT_EQ(summed_counter_name("core[3].stall_l1_cycles"), "core.stall_l1_cycles");
    EXPECT_EQ(summed_counter_name("l2.misses"), "l2.misses");
    EXPECT_EQ(summed_counter_name("triangle_unit[12].ops"), "triangle_unit.ops");
}

// A run that measured every unit, as read_unit_order reads it: stats.json's sampling section
// and sampled_units.csv.
struct EveryUnitRun {
    std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("rtsim_unit_order_" + std::to_string(getpid()));
    EveryUnitRun(const std::string& sampling, const std::string& table) {
        std::filesystem::create_directories(dir);
        std::ofstream(dir / "stats.json") << "{\"sampling\": " << sampling << "}\n";
        std::ofstream(dir / "sampled_units.csv") << table;
    }
    ~EveryUnitRun() { std::filesystem::remove_all(dir); }
    std::string error(uint64_t unit_tiles = 2) const {
        try {
            read_unit_order(dir.string(), "--sample-order", unit_tiles);
        } catch (const InputError& e) {
            return e.what();
        }
        return "accepted";
    }
};

const char* const kEveryUnit =
    R"({"fast_forward": "skip", "period_units": 1, "unit_tiles": 2, "units": 4})";

// Units by their cycles, ties in unit order (by hand: 3 has none, 1 has 10, 0 and 2 have 30).
TEST(Reference, UnitOrderIsByCycles) {
    const EveryUnitRun run(kEveryUnit,
                           "unit,work,cycles,l2.misses\n0,5,30,1\n1,5,10,9\n"
                           "2,1,30,0\n3,0,0,0\n");
    EXPECT_EQ(read_unit_order(run.dir.string(), "--sample-order", 2),
              (std::vector<uint32_t>{3, 1, 0, 2}));
    // The rows may come in any order.
    const EveryUnitRun shuffled(kEveryUnit, "unit,cycles\n2,30\n3,0\n0,30\n1,10\n");
    EXPECT_EQ(read_unit_order(shuffled.dir.string(), "--sample-order", 2),
              (std::vector<uint32_t>{3, 1, 0, 2}));
    // Cycles that are not whole numbers sort among the others (by hand: 0, 10, 10.5, 11).
    const EveryUnitRun fractions(kEveryUnit, "unit,cycles\n0,11\n1,10.5\n2,10\n3,0\n");
    EXPECT_EQ(read_unit_order(fractions.dir.string(), "--sample-order", 2),
              (std::vector<uint32_t>{3, 2, 1, 0}));
}

// A run whose units are several of the every-unit run's (a paired run's larger units) orders
// them by their summed cycles, the last one short if they do not divide the frame.
TEST(Reference, UnitOrderMergesUnits) {
    const EveryUnitRun run(kEveryUnit, "unit,cycles\n0,30\n1,10\n2,30\n3,0\n");
    // By hand: units of 4 tiles hold 30 + 10 = 40 and 30 + 0 = 30.
    EXPECT_EQ(read_unit_order(run.dir.string(), "--sample-order", 4),
              (std::vector<uint32_t>{1, 0}));
    // Read again from the digest the first read left: the same.
    EXPECT_EQ(read_unit_order(run.dir.string(), "--sample-order", 4),
              (std::vector<uint32_t>{1, 0}));
    EXPECT_EQ(read_unit_order(run.dir.string(), "--sample-order", 2),
              (std::vector<uint32_t>{3, 1, 0, 2}));
    // Five units of 2 tiles, by hand: units of 4 tiles hold 10, 2 and 3 (the last one unit);
    // units of 6 tiles 11 and 4; one unit of 10 tiles holds them all.
    const EveryUnitRun odd(
        R"({"fast_forward": "skip", "period_units": 1, "unit_tiles": 2, "units": 5})",
        "unit,cycles\n0,5\n1,5\n2,1\n3,1\n4,3\n");
    EXPECT_EQ(read_unit_order(odd.dir.string(), "--sample-order", 4),
              (std::vector<uint32_t>{1, 2, 0}));
    EXPECT_EQ(read_unit_order(odd.dir.string(), "--sample-order", 6),
              (std::vector<uint32_t>{1, 0}));
    EXPECT_EQ(read_unit_order(odd.dir.string(), "--sample-order", 10), (std::vector<uint32_t>{0}));
}

// Within each run of 4 strata of the cycles' order, units go by work per cycle (worked out by
// hand here), so that each group's strata span its work per cycle.
TEST(Reference, BalancedOrderSortsEachGroupByWorkPerCycle) {
    // Units 0-9's work per cycle: 3, 1, 2, none (no cycles: 0), 4, 1, 2, 3, 5, 5 (8 and 9 a tie,
    // by unit); the order given (as by cycles): 3, 1, 0, 2, 4, 6, 5, 7, 9, 8.
    const std::vector<uint32_t> by_cycles = {3, 1, 0, 2, 4, 6, 5, 7, 9, 8};
    const std::vector<double> cycles = {10, 10, 10, 0, 10, 10, 10, 10, 10, 10};
    std::vector<AuxFigures> units(10, AuxFigures{});
    const double work_per_cycle[10] = {3, 1, 2, 7, 4, 1, 2, 3, 5, 5};
    for (size_t u = 0; u < 10; ++u) units[u][kAuxWork] = uint64_t(work_per_cycle[u] * cycles[u]);
    units[3][kAuxWork] = 70;  // work but no cycles: counts 0
    std::vector<uint32_t> order = by_cycles;
    // One unit per stratum (period 1): groups of 4 units, {3, 1, 0, 2}, {4, 6, 5, 7}, {9, 8}.
    balance_unit_order(order, cycles, units, 1);
    EXPECT_EQ(order, (std::vector<uint32_t>{3, 1, 2, 0, 5, 6, 7, 4, 8, 9}));
    // Period 2: groups of 8 units.
    order = by_cycles;
    balance_unit_order(order, cycles, units, 2);
    EXPECT_EQ(order, (std::vector<uint32_t>{3, 1, 5, 2, 6, 0, 7, 4, 8, 9}));
    // Period 3 and more: one group, the whole frame.
    order = by_cycles;
    balance_unit_order(order, cycles, units, 3);
    EXPECT_EQ(order, (std::vector<uint32_t>{3, 1, 5, 2, 6, 0, 7, 4, 8, 9}));
    EXPECT_THROW(balance_unit_order(order, std::vector<double>(9, 1.0), units, 1),
                 std::invalid_argument);
}

// The order and the fields a paired run reads are kept in a digest beside the run's files: read
// from it while they are unchanged, made again when they change (a rerun into the folder) or
// when it is damaged, never trusted otherwise.
TEST(Reference, TheDigestFollowsTheRunsFiles) {
    namespace fs = std::filesystem;
    const EveryUnitRun run(kEveryUnit, "unit,cycles\n0,30\n1,10\n2,20\n3,0\n");
    const fs::path digest = run.dir / "every_unit_digest.bin";
    const std::vector<uint32_t> first = {3, 1, 2, 0}, second = {0, 3, 2, 1};
    EXPECT_EQ(read_unit_order(run.dir.string(), "--sample-order", 2), first);
    ASSERT_TRUE(fs::exists(digest));
    const auto made = fs::last_write_time(digest);
    EXPECT_EQ(read_unit_order(run.dir.string(), "--sample-order", 2), first);
    EXPECT_EQ(fs::last_write_time(digest), made);  // read, not made again
    // The table rewritten (by hand: 0 has 1 cycle, 3 has 2, 2 has 20, 1 has 40).
    std::ofstream(run.dir / "sampled_units.csv") << "unit,cycles\n0,1\n1,40\n2,20\n3,2\n";
    EXPECT_EQ(read_unit_order(run.dir.string(), "--sample-order", 2), second);
    // A damaged digest is made again.
    const auto size = fs::file_size(digest);
    std::ofstream(digest, std::ios::binary) << std::string(size_t(size), 'x');
    EXPECT_EQ(read_unit_order(run.dir.string(), "--sample-order", 2), second);
    EXPECT_EQ(fs::file_size(digest), size);
    char magic = 'x';
    std::ifstream(digest, std::ios::binary).read(&magic, 1);
    EXPECT_EQ(magic, 'R');
    // The digest does not stand for a stats.json that changed: it is checked again.
    std::ofstream(run.dir / "stats.json")
        << R"({"sampling": {"fast_forward": "skip", "period_units": 1, "unit_tiles": 4, "units": 4}})";
    EXPECT_NE(run.error(2).find("its units are 4 tiles, this run's 2"), std::string::npos)
        << run.error(2);
}

TEST(Reference, UnitOrderRefusesWhatIsNotAnEveryUnitRun) {
    const std::string ok = "unit,cycles\n0,1\n1,2\n2,3\n3,4\n";
    {
        const EveryUnitRun run(R"({"fast_forward": "skip", "period_units": 4, "unit_tiles": 2})",
                               ok);
        EXPECT_NE(run.error().find("not a run that measured every unit"), std::string::npos)
            << run.error();
    }
    const std::string where = "--sample-order ";
    {
        const EveryUnitRun run(kEveryUnit, ok);
        EXPECT_EQ(run.error(3),
                  where + run.dir.string() +
                      ": its units are 2 tiles, this run's 3 (a multiple of them is "
                      "needed: sim.sample_unit_tiles, or sim.sample_paired_unit_tiles "
                      "in a paired run)");
        EXPECT_EQ(run.error(1),
                  where + run.dir.string() +
                      ": its units are 2 tiles, this run's 1 (a multiple of them is "
                      "needed: sim.sample_unit_tiles, or sim.sample_paired_unit_tiles "
                      "in a paired run)");
        EXPECT_EQ(run.error(2), "accepted");
        EXPECT_EQ(run.error(4), "accepted");  // two of its units make one
    }
    auto table_error = [&](const std::string& table) {
        const EveryUnitRun run(kEveryUnit, table);
        const std::string e = run.error(), path = (run.dir / "sampled_units.csv").string();
        return e.rfind(path + ": ", 0) == 0 ? e.substr(path.size() + 2) : e;
    };
    EXPECT_EQ(table_error("unit,work\n0,1\n"), "not a sampled_units.csv with a cycles column");
    EXPECT_EQ(table_error("cycles,unit\n0,1\n"), "not a sampled_units.csv with a cycles column");
    EXPECT_EQ(table_error("unit,cycles\n0,1\n1,2\n2,3\n"),
              "3 units listed, its stats.json counts 4");
    EXPECT_EQ(table_error("unit,cycles\n0,1\n1,2\n1,3\n3,4\n"),
              "line 4: unit 1 is not one of the frame's 4 units, or comes twice");
    EXPECT_EQ(table_error("unit,cycles\n0,1\n1,2\n4,3\n3,4\n"),
              "line 4: unit 4 is not one of the frame's 4 units, or comes twice");
    EXPECT_EQ(table_error("unit,cycles\n0,1\n1,x\n"), "line 3: 'x' is not a number");
    EXPECT_EQ(table_error("unit,work,cycles\n0,1\n"), "line 2: no cycles field");
}

}  // namespace
}  // namespace rtsim

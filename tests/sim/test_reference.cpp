// sim/reference.h: reading sampled_units.csv, and the columns counters are summed into.
#include <gtest/gtest.h>

#include "sim/reference.h"
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

}  // namespace
}  // namespace rtsim

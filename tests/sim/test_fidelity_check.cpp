// The fast engine's self-check on hand-built reports: each regime is named exactly when its
// measure crosses its threshold, and the run's expected error is the largest of its regimes'.
#include <gtest/gtest.h>

#include "sim/config.h"
#include "sim/fidelity_check.h"

namespace rtsim {
namespace {

using nlohmann::json;

json report(double l1_share, double crossbar_busy_cycles, double cycles) {
    return {{"total_cycles", cycles},
            {"stalls", {{"total", {{"share", {{"l1", l1_share}}}}}}},
            {"counters", {{"crossbar.busy_cycles", crossbar_busy_cycles}}}};
}

std::vector<std::string> names(const json& check) {
    std::vector<std::string> out;
    for (const json& r : check["regimes"]) out.push_back(r["name"]);
    return out;
}

TEST(FidelityCheck, RegimesFollowTheirMeasures) {
    const Params plain = load_config("", {}).typed;
    const json none = fidelity_check(plain, report(0.30, 200, 1000));
    EXPECT_FALSE(none["flagged"].get<bool>());
    EXPECT_TRUE(names(none).empty());
    EXPECT_EQ(none["expected_error_pct"].get<double>(), 1.0);
    EXPECT_FALSE(none.contains("note"));

    // L1 stalls of 41% of slot cycles cross 40%; a crossbar busy 31% of cycles crosses 30%.
    const json l1 = fidelity_check(plain, report(0.41, 200, 1000));
    EXPECT_TRUE(l1["flagged"].get<bool>());
    EXPECT_EQ(names(l1), std::vector<std::string>{"l1_bound"});
    EXPECT_EQ(l1["expected_error_pct"].get<double>(), 14.0);
    EXPECT_NE(l1["note"].get<std::string>().find("sim.fidelity=accurate"), std::string::npos);
    const json both = fidelity_check(plain, report(0.41, 310, 1000));
    EXPECT_EQ(names(both), (std::vector<std::string>{"l1_bound", "crossbar_bound"}));
    EXPECT_EQ(both["expected_error_pct"].get<double>(), 16.0);  // the larger

    // Treelet loads are a regime by config; treelets without loads are not.
    const Params loads =
        load_config("", {"traversal.mode=treelet", "bvh.width=4", "bvh.treelet_bytes=4096"}).typed;
    EXPECT_EQ(names(fidelity_check(loads, report(0.1, 0, 1000))),
              std::vector<std::string>{"treelet_loads"});
    const Params no_loads =
        load_config("", {"traversal.mode=treelet", "bvh.width=4", "bvh.treelet_bytes=4096",
                         "traversal.treelet_prefetch=false"})
            .typed;
    EXPECT_TRUE(names(fidelity_check(no_loads, report(0.1, 0, 1000))).empty());

    // Command-level DRAM is a regime once the cores' writes reach the L2; the default DRAM
    // with writes, or command DRAM without them, is not.
    const Params command = load_config("", {"dram.model=command"}).typed;
    json writes = report(0.1, 0, 1000);
    writes["counters"]["l2.write_requests"] = 5;
    EXPECT_EQ(names(fidelity_check(command, writes)),
              std::vector<std::string>{"command_dram_writes"});
    EXPECT_EQ(fidelity_check(command, writes)["expected_error_pct"].get<double>(), 11.0);
    EXPECT_TRUE(names(fidelity_check(command, report(0.1, 0, 1000))).empty());
    EXPECT_TRUE(names(fidelity_check(plain, writes)).empty());

    // Memory-path blocks that met over 1% of their requests out of time order, over all of them
    // (2 + 1 of 200 is 1.5%); 2 of 200 (1%) is not over.
    json path = report(0.1, 0, 1000);
    path["memory_path"]["below_l1[0]"] = {{"requests", 100}, {"out_of_order_requests", 2}};
    path["memory_path"]["below_l2"] = {{"requests", 100}, {"out_of_order_requests", 1}};
    EXPECT_EQ(names(fidelity_check(plain, path)), std::vector<std::string>{"memory_path_order"});
    EXPECT_EQ(fidelity_check(plain, path)["expected_error_pct"].get<double>(), 14.0);
    path["memory_path"]["below_l2"]["out_of_order_requests"] = 0;
    EXPECT_TRUE(names(fidelity_check(plain, path)).empty());

    // The accurate engine is the reference: it makes no claim about itself.
    const json acc =
        fidelity_check(load_config("", {"sim.fidelity=accurate"}).typed, report(0.9, 900, 1000));
    EXPECT_TRUE(acc["reference"].get<bool>());
    EXPECT_FALSE(acc.contains("flagged"));
}

}  // namespace
}  // namespace rtsim

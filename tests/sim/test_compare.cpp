#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "sim/compare.h"
#include "support/scratch_dir.h"
#include "workloads/error.h"

using namespace rtsim;
using nlohmann::json;

namespace {

// A minimal stats.json with the figures compare reads.
json stats(uint64_t cycles, uint64_t rays, double l1_hit_rate, uint64_t dram_bytes, int l1_kib) {
    json s;
    s["total_cycles"] = cycles;
    s["rays_per_second"] = 1e6;
    s["rays"] = {{"total", rays}, {"steps", rays * 10}};
    s["caches"] = {{"l1_total", {{"hit_rate", l1_hit_rate}}}};
    s["bandwidth"] = {{"dram", {{"bytes", dram_bytes}}}};
    s["units"] = {{"box_unit[0]", {{"utilization", 0.2}}}, {"box_unit[1]", {{"utilization", 0.4}}}};
    s["config"] = {{"l1", {{"size_kib", l1_kib}, {"ways", 4}}}, {"core", {{"count", 8}}}};
    s["workload"] = {{"rays", "diffuse"}, {"resolution", "64x64"}};
    s["scene"] = {{"name", "bunny.obj"}, {"hash", "abc"}};
    return s;
}

const Comparison::Row* row(const Comparison& c, const std::string& name) {
    for (const auto& r : c.rows)
        if (r.name == name) return &r;
    return nullptr;
}

std::string write(const std::string& name, const std::string& text) {
    const std::string path = (test::scratch_dir() / name).string();
    std::ofstream(path) << text;
    return path;
}

}  // namespace

TEST(Compare, ListsOnlyTheSettingsThatDiffer) {
    const Comparison c = compare_runs(
        {{"A", "a", stats(1000, 100, 0.5, 6400, 32)}, {"B", "b", stats(800, 100, 0.6, 3200, 64)}});
    ASSERT_EQ(c.differences.size(), 1u);
    EXPECT_EQ(c.differences[0].first, "config: l1.size_kib");
    EXPECT_EQ(c.differences[0].second, (std::vector<std::string>{"32", "64"}));
}

TEST(Compare, FiguresAreReadAndDerivedPerRun) {
    const Comparison c = compare_runs(
        {{"A", "a", stats(1000, 100, 0.5, 6400, 32)}, {"B", "b", stats(800, 200, 0.6, 3200, 32)}});
    EXPECT_EQ(row(c, "cycles")->values, (std::vector<double>{1000, 800}));
    EXPECT_EQ(row(c, "DRAM bytes per ray")->values, (std::vector<double>{64, 16}));
    EXPECT_EQ(row(c, "steps per ray")->values, (std::vector<double>{10, 10}));
    EXPECT_DOUBLE_EQ(row(c, "box unit utilisation")->values[0], 0.3);  // mean over units
    EXPECT_EQ(row(c, "L1 hit rate")->relative, Comparison::Relative::Points);
    // A figure no run has is left out; one some runs lack is NaN for them.
    EXPECT_EQ(row(c, "DRAM row hit rate"), nullptr);
    json partial = stats(900, 100, 0.5, 6400, 32);
    partial["bandwidth"]["dram"]["row_hit_rate"] = 0.75;
    const Comparison p =
        compare_runs({{"A", "a", stats(1000, 100, 0.5, 6400, 32)}, {"B", "b", partial}});
    ASSERT_NE(row(p, "DRAM row hit rate"), nullptr);
    EXPECT_TRUE(std::isnan(row(p, "DRAM row hit rate")->values[0]));
}

TEST(Compare, TextAndJsonShowEachRunRelativeToTheFirst) {
    const Comparison c = compare_runs({{"base", "a", stats(1000, 100, 0.5, 6400, 32)},
                                       {"big", "b", stats(800, 100, 0.6, 3200, 64)}});
    const std::string text = format_comparison(c);
    EXPECT_NE(text.find("big vs base"), std::string::npos);
    EXPECT_NE(text.find("0.800x"), std::string::npos);     // cycles
    EXPECT_NE(text.find("+10.0 pts"), std::string::npos);  // L1 hit rate 50% -> 60%
    EXPECT_NE(text.find("32 | 64"), std::string::npos);
    const json j = comparison_json(c);
    EXPECT_EQ(j["runs"][1]["label"], "big");
    EXPECT_EQ(j["differences"]["config: l1.size_kib"][1], "64");
    bool found = false;
    for (const auto& m : j["metrics"]) {
        if (m["name"] != "cycles") continue;
        found = true;
        EXPECT_DOUBLE_EQ(m["relative"][1].get<double>(), 0.8);
    }
    EXPECT_TRUE(found);
}

TEST(Compare, BadFilesAreNamedInOneLine) {
    auto message = [](const std::string& path) {
        try {
            load_compared_run(path, "A");
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const std::string missing = (test::scratch_dir() / "no_such_stats.json").string();
    EXPECT_EQ(message(missing), missing + ": cannot open stats file");
    const std::string broken = write("broken_stats.json", "{\"total_cycles\": 1,");
    EXPECT_EQ(message(broken).rfind(broken + ": invalid JSON at byte 20: ", 0), 0u)
        << message(broken);
    const std::string other = write("other.json", "{\"total_cycles\": 1}");
    EXPECT_EQ(message(other), other + ": not an rtsim stats.json (no \"rays\")");
    CompareOptions one;
    one.paths = {other};
    EXPECT_THROW(compare_command(one), InputError);
    CompareOptions labels;
    labels.paths = {other, other};
    labels.labels = {"only one"};
    EXPECT_THROW(compare_command(labels), InputError);
}

namespace {
size_t count_of(const std::string& text, const std::string& what) {
    size_t n = 0;
    for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
    return n;
}
}  // namespace

TEST(Compare, DrawsStallSharesAndBandwidthOverTime) {
    json a = stats(1000, 100, 0.5, 6400, 32), b = stats(800, 100, 0.6, 3200, 64);
    a["stalls"]["total"]["share"] = {{"issue", 0.25}, {"dram", 0.75}};
    b["stalls"]["total"]["share"] = {{"l2", 0.5}, {"box_unit", 0.25}, {"no_work", 0.25}};
    const std::string bars = comparison_svg(compare_runs({{"A", "a", a}, {"B", "b", b}}));
    EXPECT_EQ(bars.rfind("<svg", 0), 0u);
    EXPECT_EQ(count_of(bars, "<title>"), 5u);  // one bar segment per share above zero
    EXPECT_NE(bars.find("<title>DRAM 75.0%</title>"), std::string::npos);
    EXPECT_NE(bars.find(">box unit</text>"), std::string::npos);  // the legend names every cause
    EXPECT_EQ(count_of(bars, "<polyline"), 0u);                   // no time series recorded
    for (json* s : {&a, &b})
        (*s)["time_series"] = {{"window_cycles", 100},
                               {"l2_to_l1_gbps", {1.0, 2.0, 3.0}},
                               {"dram_gbps", {0.5, 0.25, 0.0}}};
    const std::string lines = comparison_svg(compare_runs({{"A", "a", a}, {"B", "b", b}}));
    EXPECT_EQ(count_of(lines, "<polyline"), 4u);  // two charts, a line per run
    // With the box units' utilisation per window too: a third chart.
    for (json* s : {&a, &b}) (*s)["time_series"]["box_unit_utilization"] = {0.5, 0.75, 0.25};
    const std::string util = comparison_svg(compare_runs({{"A", "a", a}, {"B", "b", b}}));
    EXPECT_EQ(count_of(util, "<polyline"), 6u);
    EXPECT_NE(util.find("Box unit utilisation per window"), std::string::npos);
}

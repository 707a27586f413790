#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>

#include "sim/sweep.h"
#include "support/scratch_dir.h"
#include "workloads/error.h"

using namespace rtsim;

namespace {

std::string write_sweep(const std::string& name, const std::string& text) {
    const std::string path = (test::scratch_dir() / name).string();
    std::ofstream(path) << text;
    return path;
}

// The one-line message plan_sweep refuses a file with ("no error" if it accepts it).
std::string refusal(const std::string& text) {
    const std::string path = write_sweep("refused.json", text);
    try {
        plan_sweep(path);
    } catch (const InputError& e) {
        const std::string m = e.what();
        EXPECT_EQ(m.rfind(path + ": ", 0), 0u) << m;  // names the file
        EXPECT_EQ(m.find('\n'), std::string::npos) << m;
        return m.substr(path.size() + 2);
    }
    return "no error";
}

bool has(const std::vector<std::string>& args, const std::string& a, const std::string& b) {
    for (size_t i = 0; i + 1 < args.size(); ++i)
        if (args[i] == a && args[i + 1] == b) return true;
    return false;
}

}  // namespace

TEST(Sweep, EveryCombinationTheLastKeyFastest) {
    const std::string path = write_sweep("grid.json", R"({
        "workload": {"scene": "builtin:cornell", "rays": "primary", "res": "16x16", "seed": 3},
        "set": {"core.count": 2},
        "vary": {"l1.size_kib": [8, 16, 32], "l2.replacement": ["lru", "fifo"]}})");
    const SweepPlan plan = plan_sweep(path);
    EXPECT_EQ(plan.keys, (std::vector<std::string>{"l1.size_kib", "l2.replacement"}));
    ASSERT_EQ(plan.points.size(), 6u);
    EXPECT_EQ(plan.points[1].values[0].second, "8");
    EXPECT_EQ(plan.points[1].values[1].second, "fifo");
    EXPECT_EQ(plan.points[5].name, "005_l1.size_kib=32_l2.replacement=fifo");
    const auto& args = plan.points[5].run_args;
    EXPECT_TRUE(has(args, "--set", "core.count=2"));
    EXPECT_TRUE(has(args, "--set", "l1.size_kib=32"));
    EXPECT_TRUE(has(args, "--set", "l2.replacement=\"fifo\""));
    EXPECT_TRUE(has(args, "--scene", "builtin:cornell"));
    EXPECT_TRUE(has(args, "--res", "16x16"));
    EXPECT_TRUE(has(args, "--seed", "3"));
}

TEST(Sweep, PathsAreRelativeToTheSweepFile) {
    const std::string path = write_sweep("relative.json", R"({
        "config": "base.json", "vary": {"l1.ways": [2]}})");
    std::ofstream(test::scratch_dir() / "base.json") << R"({"l1": {"size_kib": 64}})";
    const SweepPlan plan = plan_sweep(path);
    EXPECT_TRUE(
        has(plan.points[0].run_args, "--config", (test::scratch_dir() / "base.json").string()));
}

TEST(Sweep, BadFilesAreRefusedBeforeAnythingRuns) {
    EXPECT_EQ(refusal(R"({"vary": {"l1.size_kib": [8]}, "colour": 1})"),
              "colour: unknown key (expected config, set, workload, trace, vary, pareto, "
              "reference)");
    EXPECT_EQ(refusal(R"({"vary": {"l1.size_kib": [8]}, "pareto": ["cycles"]})"),
              "pareto: expected two figure names, e.g. [\"cycles\", \"energy per ray (nJ)\"]");
    EXPECT_NE(refusal(R"({"vary": {"l1.size_kib": [8]}, "pareto": ["cycles", "speed"]})")
                  .find("pareto: 'speed' is not a figure"),
              std::string::npos);
    EXPECT_EQ(refusal(R"({"vary": {}})").rfind("vary: expected an object", 0), 0u);
    EXPECT_EQ(refusal(R"({"vary": {"l1.size_kib": 8}})"),
              "vary.l1.size_kib: expected a non-empty array of values");
    // A value the config schema refuses fails the whole sweep up front, naming the point.
    const std::string bad_value = refusal(R"({"vary": {"l1.size_kib": [8, 12]}})");
    EXPECT_NE(bad_value.find("point 001_l1.size_kib=12"), std::string::npos) << bad_value;
    EXPECT_NE(refusal(R"({"vary": {"l1.colour": [1]}})").find("unknown key"), std::string::npos);
    EXPECT_EQ(refusal(R"({"workload": {"res": "0x4"}, "vary": {"l1.ways": [2]}})")
                  .rfind("workload: --res", 0),
              0u);
    EXPECT_EQ(refusal(R"({"workload": {"colour": 1}, "vary": {"l1.ways": [2]}})"),
              "workload.colour: unknown key");
    EXPECT_EQ(refusal(R"({"workload": {}, "trace": "x.rtt", "vary": {"l1.ways": [2]}})")
                  .rfind("trace and workload", 0),
              0u);
    EXPECT_NE(refusal(R"({"trace": "no_such.rtt", "vary": {"l1.ways": [2]}})").find("no such file"),
              std::string::npos);
    EXPECT_EQ(refusal(R"({"vary": {"l1.ways": [2]}, "workload": {"scene": "/no/mesh.obj"}})"),
              "workload.scene: /no/mesh.obj: no such file");
    // The offset is the end of the text, where the array should have closed.
    EXPECT_EQ(refusal("[1, 2").rfind("invalid JSON at byte 6: ", 0), 0u) << refusal("[1, 2");
    // Found by fuzz_sweep (fuzz/corpus/sweep/number_overflow.json): a number beyond double's
    // range escaped as an uncaught exception.
    EXPECT_EQ(
        refusal(R"({"vary": {"l1.ways": [2e99999]}})").rfind("invalid JSON: number overflow", 0),
        0u);
}

// "reference": the base design measuring every unit, and every point paired with it.
TEST(Sweep, AReferencePairsEveryPointWithTheBaseDesign) {
    const std::string path = write_sweep("paired.json", R"({
        "workload": {"scene": "builtin:cornell", "rays": "primary", "res": "32x32"},
        "set": {"sim.sampled": true, "sim.sample_fast_forward": "skip",
                "sim.sample_period_units": 4},
        "vary": {"l1.size_kib": [8, 16]}, "reference": true})");
    SweepPlan plan = plan_sweep(path);
    ASSERT_TRUE(plan.reference.has_value());
    const auto& ref = plan.reference->run_args;
    EXPECT_EQ(plan.reference->name, "reference");
    EXPECT_TRUE(has(ref, "--set", "sim.sample_period_units=1"));
    EXPECT_TRUE(has(ref, "--scene", "builtin:cornell"));
    for (const auto& a : ref) EXPECT_EQ(a.find("l1.size_kib"), std::string::npos) << a;
    pair_with_reference(plan, "/tmp/sweep-out");
    for (const auto& p : plan.points)
        EXPECT_TRUE(has(p.run_args, "--reference", "/tmp/sweep-out/reference")) << p.name;

    EXPECT_EQ(refusal(R"({"workload": {"res": "8x8"}, "vary": {"l1.ways": [2]},
                          "reference": 1})"),
              "reference: expected true or false");
    EXPECT_EQ(refusal(R"({"workload": {"res": "8x8"}, "vary": {"l1.ways": [2]},
                          "reference": true})"),
              "reference: the base design must set sim.sampled=true and "
              "sim.sample_fast_forward=skip");
    // Without "reference" nothing is paired.
    SweepPlan alone = plan_sweep(write_sweep("alone.json", R"({
        "workload": {"res": "8x8"}, "vary": {"l1.ways": [2]}, "reference": false})"));
    EXPECT_FALSE(alone.reference.has_value());
    pair_with_reference(alone, "/tmp/x");
    for (const auto& a : alone.points[0].run_args) EXPECT_NE(a, "--reference");
}

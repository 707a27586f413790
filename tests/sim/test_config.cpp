#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "sim/config.h"
#include "support/scratch_dir.h"
#include "workloads/error.h"

namespace fs = std::filesystem;
using namespace rtsim;
using nlohmann::json;

namespace {

const fs::path& temp_dir() {
    return test::scratch_dir();
}

std::string write_cfg(const std::string& name, const std::string& text) {
    const fs::path p = temp_dir() / name;
    std::ofstream(p) << text;
    return p.string();
}

// Loading must fail with one line that contains every fragment.
void expect_error(const std::string& path, const std::vector<std::string>& sets,
                  const std::vector<std::string>& fragments) {
    try {
        load_config(path, sets);
        FAIL() << "accepted " << path;
    } catch (const InputError& e) {
        const std::string msg = e.what();
        EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
        for (const auto& f : fragments)
            EXPECT_NE(msg.find(f), std::string::npos) << "'" << f << "' not in: " << msg;
    }
}

const std::string kBaseline = std::string(RTSIM_SOURCE_DIR) + "/configs/baseline.json";

}  // namespace

TEST(Config, DefaultsAreValidAndBaselineSpellsThemOut) {
    const Config d = load_config("", {});
    const Config b = load_config(kBaseline, {});
    // baseline.json writes every field out; it must not drift from the schema's defaults.
    EXPECT_EQ(d.values, b.values);
    EXPECT_EQ(d.hash(), b.hash());
    EXPECT_EQ(b.typed.l1.size_bytes, 32u * 1024);
}

TEST(Config, EveryShippedConfigLoads) {
    for (const auto& e : fs::directory_iterator(std::string(RTSIM_SOURCE_DIR) + "/configs")) {
        if (e.path().extension() != ".json" || e.path().filename() == "schema.json") continue;
        EXPECT_NO_THROW(load_config(e.path().string(), {})) << e.path();
    }
}

TEST(Config, EverySchemaFieldIsDocumented) {
    std::function<void(const json&, const std::string&)> walk = [&](const json& n,
                                                                    const std::string& path) {
        ASSERT_TRUE(n.contains("description")) << path;
        ASSERT_FALSE(n["description"].get<std::string>().empty()) << path;
        if (n.contains("fields")) {
            for (auto& [k, v] : n["fields"].items()) walk(v, path.empty() ? k : path + "." + k);
        } else {
            ASSERT_TRUE(n.contains("default")) << path;
            ASSERT_TRUE(n.contains("type")) << path;
        }
    };
    walk(config_schema(), "");
    EXPECT_NE(config_reference_markdown().find("`l2.hit_latency_cycles`"), std::string::npos);
}

TEST(Config, UnknownKeyNamesFileAndPath) {
    const auto p = write_cfg("unknown.json", R"({"l1": {"size_kb": 64}})");
    expect_error(p, {}, {p, "l1.size_kb", "unknown key", "size_kib"});
}

TEST(Config, WrongTypeNamesExpectation) {
    const auto p = write_cfg("type.json", R"({"core": {"count": "eight"}})");
    expect_error(p, {}, {p, "core.count", "expected an integer", "\"eight\""});
    const auto q = write_cfg("float.json", R"({"core": {"count": 2.5}})");
    expect_error(q, {}, {q, "core.count", "expected an integer"});
    const auto r = write_cfg("section.json", R"({"l2": 5})");
    expect_error(r, {}, {r, "l2", "expected an object"});
}

TEST(Config, ImpossibleValuesAreRejected) {
    const auto zero = write_cfg("zero.json", R"({"l1": {"size_kib": 0}})");
    expect_error(zero, {}, {zero, "l1.size_kib", "an integer from 1 to 1048576", "got 0"});
    const auto units = write_cfg("units.json", R"({"box_unit": {"count": 0}})");
    expect_error(units, {}, {units, "box_unit.count", "from 1 to 64"});
    const auto cores = write_cfg("cores.json", R"({"core": {"count": 0}})");
    expect_error(cores, {}, {cores, "core.count"});
    const auto sets = write_cfg("sets.json", R"({"l1": {"size_kib": 24, "ways": 4}})");
    expect_error(sets, {}, {sets, "l1", "power-of-two number of sets", "96 sets"});
    const auto line = write_cfg("line.json", R"({"l2": {"line_bytes": 96}})");
    expect_error(line, {}, {line, "l2.line_bytes", "power of two"});
    const auto bw = write_cfg("bw.json", R"({"dram": {"bytes_per_cycle": 0}})");
    expect_error(bw, {}, {bw, "dram.bytes_per_cycle", "a number > 0 and <= 65536"});
    const auto builder = write_cfg("builder.json", R"({"bvh": {"builder": "magic"}})");
    expect_error(builder, {}, {builder, "bvh.builder", "\"sah\""});
    const auto l2line =
        write_cfg("l2line.json", R"({"l1": {"line_bytes": 128}, "l2": {"line_bytes": 64}})");
    expect_error(l2line, {}, {l2line, "l2.line_bytes", "at least l1.line_bytes"});
}

TEST(Config, InvalidJsonGivesByteOffset) {
    const auto p = write_cfg("broken.json", "{\"core\": {\"count\": 4,}}");
    expect_error(p, {}, {p, "invalid JSON at byte"});
    expect_error("/no/such/config.json", {}, {"/no/such/config.json", "cannot open"});
    // Found by fuzz_sweep: a number beyond double's range is not a parse error to the JSON
    // library, and escaped as an uncaught exception.
    const auto huge = write_cfg("huge.json", "{\"core\": {\"count\": 2e99999}}");
    expect_error(huge, {}, {huge, "invalid JSON", "number overflow"});
}

TEST(Config, ExtendsInheritsAndOverrides) {
    write_cfg("parent.json", R"({"name": "parent", "l1": {"size_kib": 64, "ways": 8}})");
    const auto child = write_cfg(
        "child.json", R"({"extends": "parent.json", "name": "child", "l1": {"ways": 2}})");
    const Config c = load_config(child, {});
    EXPECT_EQ(c.typed.name, "child");
    EXPECT_EQ(c.typed.l1.size_bytes, 64u * 1024);    // from the parent
    EXPECT_EQ(c.typed.l1.ways, 2);                   // overridden
    EXPECT_EQ(c.typed.l2.size_bytes, 1024u * 1024);  // default
    ASSERT_EQ(c.files.size(), 2u);
    EXPECT_NE(c.files[0].find("parent.json"), std::string::npos);
}

TEST(Config, ExtendsCycleAndMissingParent) {
    write_cfg("a.json", R"({"extends": "b.json"})");
    const auto b = write_cfg("b.json", R"({"extends": "a.json"})");
    expect_error(b, {}, {"extends", "cycle"});
    const auto orphan = write_cfg("orphan.json", R"({"extends": "nope.json"})");
    expect_error(orphan, {}, {"nope.json", "cannot open"});
    const auto bad = write_cfg("badext.json", R"({"extends": 3})");
    expect_error(bad, {}, {bad, "extends", "expected a file name"});
}

TEST(Config, SetOverridesOnTop) {
    const Config c =
        load_config(kBaseline, {"l1.size_kib=64", "bvh.builder=sah", "dram.bytes_per_cycle=12.8"});
    EXPECT_EQ(c.typed.l1.size_bytes, 64u * 1024);
    EXPECT_DOUBLE_EQ(c.typed.dram.bytes_per_cycle, 12.8);
    EXPECT_NE(c.hash(), load_config(kBaseline, {}).hash());
    EXPECT_EQ(c.hash(),
              load_config(kBaseline, {"l1.size_kib=64", "dram.bytes_per_cycle=12.8"}).hash());
    expect_error(kBaseline, {"l1.size_kib"}, {"--set l1.size_kib", "KEY=VALUE"});
    expect_error(kBaseline, {"l1.nope=3"}, {"--set l1.nope=3", "unknown key"});
    expect_error(kBaseline, {"l1=3"}, {"is a section"});
    expect_error(kBaseline, {"l1.ways=many"}, {"l1.ways", "expected an integer", "\"many\""});
    expect_error(kBaseline, {"l1.ways=3"}, {"power-of-two number of sets"});
}

// Engine and sampling are two choices; a config written when "sampled" was a fidelity level
// still means what it meant: the fast engine, sampled.
TEST(Config, LegacySampledFidelityReadsAsTheFastEngineSampled) {
    const Config plain = load_config("", {});
    EXPECT_EQ(plain.typed.sim.fidelity, "fast");
    EXPECT_FALSE(plain.typed.sim.sampled);

    const auto old = write_cfg("old_sampled.json", R"({"sim": {"fidelity": "sampled"}})");
    const Config from_file = load_config(old, {});
    EXPECT_EQ(from_file.typed.sim.fidelity, "fast");
    EXPECT_TRUE(from_file.typed.sim.sampled);

    const Config from_set = load_config("", {"sim.fidelity=sampled"});
    EXPECT_EQ(from_set.typed.sim.fidelity, "fast");
    EXPECT_TRUE(from_set.typed.sim.sampled);
    EXPECT_EQ(from_set.hash(), load_config("", {"sim.sampled=true"}).hash());

    // An explicit sim.sampled beside the old value wins.
    const auto both =
        write_cfg("old_both.json", R"({"sim": {"fidelity": "sampled", "sampled": false}})");
    EXPECT_FALSE(load_config(both, {}).typed.sim.sampled);

    // The new spelling samples either engine.
    const Config accurate = load_config("", {"sim.fidelity=accurate", "sim.sampled=true"});
    EXPECT_EQ(accurate.typed.sim.fidelity, "accurate");
    EXPECT_TRUE(accurate.typed.sim.sampled);
    expect_error("", {"sim.fidelity=sampledd"}, {"sim.fidelity", "accurate", "fast"});
}

TEST(Config, CommittedReferenceMatchesSchema) {
    // docs/config.md is generated; regenerate with: build/rtsim config --doc > docs/config.md
    std::ifstream in(std::string(RTSIM_SOURCE_DIR) + "/docs/config.md");
    std::stringstream ss;
    ss << in.rdbuf();
    EXPECT_EQ(ss.str(), config_reference_markdown());
}

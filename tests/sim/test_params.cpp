// The typed config binding (sim/params.cpp): one table from schema path to member. Every schema
// field is bound exactly once, each row writes its own member and no other, and the model
// structs' C++ default initializers equal the schema's defaults (the schema is their only home).
#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <nlohmann/json.hpp>

#include "sim/config.h"
#include "sim/params.h"

using namespace rtsim;
using nlohmann::json;

namespace {

// Every leaf of the schema with its entry.
std::map<std::string, json> schema_leaves() {
    std::map<std::string, json> out;
    std::function<void(const json&, const std::string&)> walk = [&](const json& node,
                                                                    const std::string& path) {
        if (node.contains("fields")) {
            for (auto& [k, v] : node["fields"].items()) walk(v, path.empty() ? k : path + "." + k);
            return;
        }
        out[path] = node;
    };
    walk(config_schema(), "");
    return out;
}

json& at(json& values, const std::string& path) {
    json* node = &values;
    size_t start = 0;
    while (true) {
        const size_t dot = path.find('.', start);
        node = &(*node)[path.substr(start, dot - start)];
        if (dot == std::string::npos) return *node;
        start = dot + 1;
    }
}

// A valid value other than the default, from the schema entry alone.
json other_value(const json& f) {
    const json& d = f["default"];
    if (f.contains("enum")) {
        for (const auto& e : f["enum"])
            if (e != d) return e;
        // A one-value enum (one registered component): binding does not validate, so any
        // other string shows where the row writes.
        return d.get<std::string>() + "_changed";
    }
    const std::string type = f["type"];
    if (type == "boolean") return !d.get<bool>();
    if (type == "string") return d.get<std::string>() + "_changed";
    const double max = f.value("maximum", 1e18);
    if (type == "number") {
        const double v = d.get<double>() + 0.5;
        return v <= max ? v : d.get<double>() / 2;
    }
    const int64_t v = d.get<int64_t>();
    if (f.value("power_of_two", false)) return double(2 * v) <= max ? 2 * v : v / 2;
    return double(v + 1) <= max ? v + 1 : v - 1;
}

}  // namespace

TEST(Params, EverySchemaFieldIsBoundExactlyOnce) {
    const auto leaves = schema_leaves();
    std::map<std::string, int> bound;
    for (const auto& b : config_bindings()) ++bound[b.path];
    for (const auto& [path, entry] : leaves)
        EXPECT_EQ(bound[path], 1) << path << ": bound " << bound[path] << " times";
    for (const auto& [path, n] : bound)
        EXPECT_TRUE(leaves.count(path)) << path << " is bound but not in the schema";
}

// Each field set alone to another value: its row reads it back, and every other row still reads
// its default. A row writing a member another row owns, or the wrong member, fails here.
TEST(Params, EachRowWritesItsOwnMemberAndNoOther) {
    const auto leaves = schema_leaves();
    const json defaults = load_config("", {}).values;
    const Params base = bind_params(defaults);
    for (const auto& b : config_bindings()) {
        EXPECT_EQ(b.get(base), leaves.at(b.path)["default"]) << b.path;
        json values = defaults;
        const json changed = other_value(leaves.at(b.path));
        ASSERT_NE(changed, leaves.at(b.path)["default"]) << b.path;
        at(values, b.path) = changed;
        const Params p = bind_params(values);
        EXPECT_EQ(b.get(p), changed) << b.path;
        for (const auto& other : config_bindings()) {
            if (other.path == b.path) continue;
            EXPECT_EQ(other.get(p), other.get(base))
                << "setting " << b.path << " changed " << other.path;
        }
    }
}

// The model structs keep default initializers (unit tests build blocks without a config); they
// must say what the schema says. Where one struct serves two sections (CacheParams: l1 and l2,
// UnitParams: box and triangle units) its defaults are the first section's.
TEST(Params, ModelStructDefaultsEqualTheSchemas) {
    const Params schema = load_config("", {}).typed;
    const Params cpp;  // the model structs as their initializers make them
    int checked = 0;
    for (const auto& b : config_bindings()) {
        if (!b.cpp_default_mirrors_schema) continue;
        EXPECT_EQ(b.get(cpp), b.get(schema)) << b.path << ": C++ default differs from the schema";
        ++checked;
    }
    EXPECT_GT(checked, 40);
}

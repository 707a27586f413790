// Registered components and the config schema agree: every kind is selected by some schema
// field, each such field's enum is exactly the registered names, its default is registered, and
// every parameter a component names is a schema field.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <sstream>

#include "models/registry.h"
#include "models/unit_kind.h"
#include "sim/config.h"
#include "sim/list_cmd.h"

using namespace rtsim;
using nlohmann::json;

namespace {

const json* field_at(const std::string& path) {
    const json* node = &config_schema();
    std::stringstream ss(path);
    std::string part;
    while (std::getline(ss, part, '.')) {
        if (!node->contains("fields") || !(*node)["fields"].contains(part)) return nullptr;
        node = &(*node)["fields"][part];
    }
    return node;
}

}  // namespace

TEST(Registry, EveryKindIsSelectedBySchemaFieldsWhoseEnumIsTheRegisteredNames) {
    const auto selectors = component_selectors();
    ASSERT_FALSE(ComponentIndex::all().empty());
    for (const auto& [kind, components] : ComponentIndex::all()) {
        if (kind == "unit_kind") continue;  // configured by sections (UnitKinds... below)
        ASSERT_TRUE(selectors.count(kind))
            << kind << " is registered but no schema field selects it";
        for (const std::string& path : selectors.at(kind)) {
            const json* f = field_at(path);
            ASSERT_NE(f, nullptr) << path;
            std::vector<std::string> names;
            for (const auto& c : components) names.push_back(c.name);
            EXPECT_EQ((*f)["enum"].get<std::vector<std::string>>(), names) << path;
            EXPECT_NE(std::find(names.begin(), names.end(), (*f)["default"].get<std::string>()),
                      names.end())
                << path << ": default not registered";
        }
    }
    for (const auto& [kind, paths] : selectors)
        EXPECT_TRUE(ComponentIndex::all().count(kind))
            << paths[0] << " names unknown kind " << kind;
}

// Unit kinds: each is a schema section of its name whose fields are its parameters, and the
// step kinds' table and the registry name the same units for the same step kinds.
TEST(Registry, UnitKindsAreSchemaSectionsAndMatchTheStepKinds) {
    const auto& units = ComponentIndex::all().at("unit_kind");
    EXPECT_EQ(units.size(), size_t(kStepKinds));
    for (int k = 0; k < kStepKinds; ++k) {
        const UnitKindEntry* u = UnitKindRegistry::find(step_kind_info(k).unit);
        ASSERT_NE(u, nullptr) << step_kind_info(k).unit;
        EXPECT_EQ(int(u->tests), k);
        const json* section = field_at(u->name);
        ASSERT_TRUE(section && section->contains("fields")) << u->name;
        std::vector<std::string> fields;
        for (auto& [f, v] : (*section)["fields"].items()) fields.push_back(f);
        auto params = u->params;
        std::sort(params.begin(), params.end());
        EXPECT_EQ(params, fields) << u->name << ": parameters and schema fields differ";
    }
}

TEST(Registry, EveryComponentParameterIsASchemaField) {
    const auto selectors = component_selectors();
    for (const auto& [kind, components] : ComponentIndex::all()) {
        if (kind == "unit_kind") continue;
        for (const auto& c : components)
            for (const std::string& p : c.params)
                for (const std::string& sel : selectors.at(kind)) {
                    const std::string section = sel.substr(0, sel.rfind('.'));
                    const std::string path =
                        p.find('.') != std::string::npos
                            ? p
                            : (sel.find('.') == std::string::npos ? p : section + "." + p);
                    const json* f = field_at(path);
                    EXPECT_TRUE(f && !f->contains("fields"))
                        << kind << " " << c.name << ": parameter " << path << " is not a field";
                }
    }
}

TEST(Registry, EveryComponentHasAOneLineDescription) {
    for (const auto& [kind, components] : ComponentIndex::all())
        for (const auto& c : components) {
            EXPECT_FALSE(c.description.empty()) << kind << " " << c.name;
            EXPECT_EQ(c.description.find('\n'), std::string::npos) << kind << " " << c.name;
        }
}

TEST(Registry, KindsThatLaterIssuesExtendAreRegistered) {
    for (const char* kind :
         {"replacement", "treelet_scheduler", "dram_model", "traversal_mode", "unit_kind"})
        EXPECT_TRUE(ComponentIndex::all().count(kind)) << kind;
}

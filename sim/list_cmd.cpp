#include "sim/list_cmd.h"

#include <fmt/format.h>
#include <functional>
#include <nlohmann/json.hpp>

#include "models/registry.h"
#include "sim/config.h"
#include "workloads/error.h"

namespace rtsim {

using nlohmann::json;

std::map<std::string, std::vector<std::string>> component_selectors() {
    std::map<std::string, std::vector<std::string>> out;
    std::function<void(const json&, const std::string&)> walk = [&](const json& node,
                                                                    const std::string& path) {
        if (node.contains("fields")) {
            for (auto& [k, v] : node["fields"].items()) walk(v, path.empty() ? k : path + "." + k);
            return;
        }
        if (node.contains("registry")) out[node["registry"].get<std::string>()].push_back(path);
    };
    walk(config_schema(), "");
    return out;
}

int list_command(const std::string& kind, bool as_json) {
    const auto& all = ComponentIndex::all();
    if (!kind.empty() && !all.count(kind)) {
        std::string known;
        for (const auto& [k, v] : all) known += (known.empty() ? "" : ", ") + k;
        throw InputError(
            fmt::format("list: unknown component kind '{}' (expected one of: {})", kind, known));
    }
    const auto selectors = component_selectors();
    json j = json::object();
    std::string text;
    for (const auto& [k, components] : all) {
        if (!kind.empty() && k != kind) continue;
        const auto sel = selectors.count(k) ? selectors.at(k) : std::vector<std::string>{};
        std::string selected_by;
        for (const auto& s : sel) selected_by += (selected_by.empty() ? "" : ", ") + s;
        // Kinds no field selects (unit kinds) are each configured by the section of their name.
        text += selected_by.empty()
                    ? fmt::format("{} (each configured by the config section of its name)\n", k)
                    : fmt::format("{} (selected by {})\n", k, selected_by);
        size_t width = 0;
        for (const auto& c : components) width = std::max(width, c.name.size());
        json list = json::array();
        for (const auto& c : components) {
            text += fmt::format("  {:<{}}  {}\n", c.name, width, c.description);
            std::string params;
            for (const auto& p : c.params) params += (params.empty() ? "" : ", ") + p;
            if (!params.empty())
                text += fmt::format("  {:<{}}  parameters: {}\n", "", width, params);
            list.push_back(
                {{"name", c.name}, {"description", c.description}, {"params", c.params}});
        }
        j[k] = {{"selected_by", sel}, {"components", list}};
    }
    if (as_json)
        fmt::print("{}\n", j.dump(2));
    else
        fmt::print("{}", text);
    return 0;
}

}  // namespace rtsim

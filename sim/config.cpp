#include "sim/config.h"

#include "models/dram_device.h"
#include "models/memory_block.h"
#include "sim/sampling/registry.h"

#include <fmt/format.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

#include "models/registry.h"
#include "models/replacement.h"
#include "models/traversal_mode.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

extern const char* const kConfigSchemaJson;

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// A field marked "registry": "KIND" takes its enum from the components registered for KIND, so
// adding a component needs no schema edit. Its default must be one of them.
void expand_registries(json& node, const std::string& path) {
    if (node.contains("fields")) {
        for (auto& [k, v] : node["fields"].items())
            expand_registries(v, path.empty() ? k : path + "." + k);
        return;
    }
    if (!node.contains("registry")) return;
    const std::string kind = node["registry"];
    const auto names = ComponentIndex::names(kind);
    if (names.empty())
        throw std::logic_error("schema: " + path + ": no component registered for kind " + kind);
    node["enum"] = names;
    if (std::find(names.begin(), names.end(), node["default"].get<std::string>()) == names.end())
        throw std::logic_error("schema: " + path + ": default is not a registered " + kind);
}

}  // namespace

const json& config_schema() {
    static const json schema = [] {
        json s = json::parse(kConfigSchemaJson);
        expand_registries(s, "");
        return s;
    }();
    return schema;
}

namespace {

// Finds the schema entry for a dotted path, or nullptr.
const json* schema_entry(const std::string& path) {
    const json* node = &config_schema();
    std::stringstream ss(path);
    std::string part;
    while (std::getline(ss, part, '.')) {
        if (!node->contains("fields")) return nullptr;
        const json& fields = (*node)["fields"];
        if (!fields.contains(part)) return nullptr;
        node = &fields[part];
    }
    return node;
}

json defaults_of(const json& node) {
    if (!node.contains("fields")) return node.at("default");
    json out = json::object();
    for (auto& [k, v] : node["fields"].items()) out[k] = defaults_of(v);
    return out;
}

std::string expectation(const json& field) {
    const std::string type = field.at("type");
    std::string s = type == "integer" ? "an integer" : type == "number" ? "a number" : "a " + type;
    if (field.contains("enum")) {
        std::string list;
        for (auto& e : field["enum"]) list += (list.empty() ? "" : ", ") + e.dump();
        s += " (one of " + list + ")";
    }
    const bool lo = field.contains("minimum"), xlo = field.contains("exclusive_minimum"),
               hi = field.contains("maximum");
    if (lo && hi)
        s += fmt::format(" from {} to {}", field["minimum"].dump(), field["maximum"].dump());
    else if (lo)
        s += fmt::format(" >= {}", field["minimum"].dump());
    if (xlo) s += fmt::format(" > {}", field["exclusive_minimum"].dump());
    if (xlo && hi) s += fmt::format(" and <= {}", field["maximum"].dump());
    if (!lo && !xlo && hi) s += fmt::format(" <= {}", field["maximum"].dump());
    if (field.value("power_of_two", false)) s += ", a power of two";
    return s;
}

bool is_power_of_two(int64_t v) {
    return v > 0 && (v & (v - 1)) == 0;
}

// Checks one leaf value; returns an empty string if fine, else what was expected.
std::string check_leaf(const json& field, const json& v) {
    const std::string type = field.at("type");
    bool ok_type = (type == "integer" && v.is_number_integer()) ||
                   (type == "number" && v.is_number()) || (type == "string" && v.is_string()) ||
                   (type == "boolean" && v.is_boolean());
    if (ok_type && type == "number" && !std::isfinite(v.get<double>())) ok_type = false;
    bool ok = ok_type;
    if (ok && v.is_number()) {
        const double d = v.get<double>();
        if (field.contains("minimum") && d < field["minimum"].get<double>()) ok = false;
        if (field.contains("exclusive_minimum") && d <= field["exclusive_minimum"].get<double>())
            ok = false;
        if (field.contains("maximum") && d > field["maximum"].get<double>()) ok = false;
        if (field.value("power_of_two", false) && !is_power_of_two(v.get<int64_t>())) ok = false;
    }
    if (ok && field.contains("enum")) {
        ok = false;
        for (auto& e : field["enum"]) ok = ok || e == v;
    }
    return ok ? std::string() : expectation(field);
}

// Keys that configs once had, with why they went: a config that still sets one is told so.
const char* removed_key(const std::string& path) {
    if (path == "sim.quantum_cycles")
        return "removed: the temporal-decoupling quantum bought 1.06x-1.13x speed for mean cycle "
               "errors up to +159% (bench/results/fidelity_quanta.md); delete the key";
    if (path == "sim.sample_window_drain")
        return "replaced by sim.sample_window_hold: write \"drain\" for true, \"none\" for false";
    return nullptr;
}

// Values that configs once had, read as what they meant. sim.fidelity = sampled was the fast
// engine sampled, before sampling became a layer over either engine (sim.sampled).
bool is_legacy_sampled(const json& fidelity) {
    return fidelity.is_string() && fidelity.get<std::string>() == "sampled";
}
void upgrade_legacy_values(json& j) {
    if (!j.is_object() || !j.contains("sim") || !j["sim"].is_object()) return;
    json& sim = j["sim"];
    if (sim.contains("fidelity") && is_legacy_sampled(sim["fidelity"])) {
        sim["fidelity"] = "fast";
        if (!sim.contains("sampled")) sim["sampled"] = true;
    }
}

// Validates a (partial) config object against the schema node; `where` names the source.
void validate(const json& schema_node, const json& v, const std::string& path,
              const std::string& where) {
    if (schema_node.contains("fields")) {
        if (!v.is_object())
            throw InputError(fmt::format("{}: {}: expected an object, got {}", where,
                                         path.empty() ? "(top level)" : path, v.dump()));
        for (auto& [k, child] : v.items()) {
            if (path.empty() && k == "extends") continue;
            const std::string p = path.empty() ? k : path + "." + k;
            if (const char* why = removed_key(p))
                throw InputError(fmt::format("{}: {}: {}", where, p, why));
            if (!schema_node["fields"].contains(k)) {
                std::string known;
                for (auto& [fk, fv] : schema_node["fields"].items())
                    known += (known.empty() ? "" : ", ") + fk;
                throw InputError(
                    fmt::format("{}: {}: unknown key (expected one of: {})", where, p, known));
            }
            validate(schema_node["fields"][k], child, p, where);
        }
        return;
    }
    const std::string why = check_leaf(schema_node, v);
    if (!why.empty())
        throw InputError(fmt::format("{}: {}: expected {}, got {}", where, path, why, v.dump()));
}

void merge_into(json& base, const json& over) {
    for (auto& [k, v] : over.items()) {
        if (v.is_object() && base.contains(k) && base[k].is_object())
            merge_into(base[k], v);
        else
            base[k] = v;
    }
}

// Reads `path` and its extends chain into `out` (parent values first). `chain` holds the files
// being loaded, child first, to detect cycles; `files` collects them parent first.
void load_chain(const std::string& path, json& out, std::vector<std::string>& files,
                std::vector<std::string>& chain) {
    for (const std::string& f : chain)
        if (fs::weakly_canonical(f) == fs::weakly_canonical(path))
            throw InputError(fmt::format("{}: extends: cycle through this file", path));
    if (chain.size() > 32)
        throw InputError(fmt::format("{}: extends: chain deeper than 32 files", path));
    json j = read_json_file(path, "config file");
    upgrade_legacy_values(j);
    validate(config_schema(), j, "", path);
    if (j.contains("extends")) {
        if (!j["extends"].is_string())
            throw InputError(fmt::format("{}: extends: expected a file name string, got {}", path,
                                         j["extends"].dump()));
        fs::path parent = j["extends"].get<std::string>();
        if (parent.is_relative()) parent = fs::path(path).parent_path() / parent;
        chain.push_back(path);
        load_chain(parent.string(), out, files, chain);
        chain.pop_back();
        j.erase("extends");
    }
    merge_into(out, j);
    files.push_back(path);
}

// Checks that involve several fields, on the effective config.
void validate_cross(const json& c, const std::string& where) {
    for (const char* level : {"l1", "l2"}) {
        const int64_t size = c[level]["size_kib"].get<int64_t>() * 1024;
        const int64_t ways = c[level]["ways"], line = c[level]["line_bytes"];
        if (size % (ways * line) != 0 || !is_power_of_two(size / (ways * line)))
            throw InputError(fmt::format(
                "{}: {}: size_kib / (ways * line_bytes) must be a power-of-two number of sets, got "
                "{} KiB / ({} * {}) = {:.4g} sets",
                where, level, size / 1024, ways, line, double(size) / double(ways * line)));
    }
    for (const char* level : {"l1", "l2"}) {
        const ReplacementEntry& policy = ReplacementRegistry::at(c[level]["replacement"]);
        const std::string why = policy.check ? policy.check(int(c[level]["ways"])) : "";
        if (!why.empty())
            throw InputError(
                fmt::format("{}: {}.replacement: {} {}", where, level, policy.name, why));
    }
    const TraversalModeEntry& mode = TraversalModeRegistry::at(c["traversal"]["mode"]);
    if (mode.needs_treelets && c["bvh"]["treelet_bytes"].get<int64_t>() == 0)
        throw InputError(fmt::format(
            "{}: traversal.mode={} queues rays by treelet, but bvh.treelet_bytes is 0 (no "
            "treelets); set it, e.g. to the L1 size in bytes",
            where, mode.name));
    if (mode.ray_buffer && c["traversal"]["treelet_cache_kib"].get<int64_t>() > 0 &&
        c["l1"]["split"].get<bool>())
        throw InputError(fmt::format(
            "{}: traversal.treelet_cache_kib: a treelet cache sits in front of a unified L1; set "
            "l1.split to false or the treelet cache to 0",
            where));
    if (c["core"]["short_stack_entries"].get<int64_t>() > 0 && (mode.packets || mode.ray_buffer))
        throw InputError(fmt::format(
            "{}: core.short_stack_entries: a short stack is modelled for independent traversal "
            "only (traversal.mode={}: {}); set it to 0",
            where, mode.name,
            mode.packets ? "packet traces record no per-ray stack"
                         : "a ray's stack would move with it through the ray buffer"));
    {
        // The traversal's own data has 16 GiB regions (models/short_stack.h).
        const uint64_t region = uint64_t(1) << 34;
        const uint64_t slots =
            c["core"]["count"].get<uint64_t>() * c["core"]["ray_slots"].get<uint64_t>();
        if (c["core"]["short_stack_entries"].get<int64_t>() > 0 &&
            slots * 128 * c["core"]["stack_entry_bytes"].get<uint64_t>() > region)
            throw InputError(fmt::format(
                "{}: core.stack_entry_bytes: {} slots x 128 entries x {} bytes overrun the 16 GiB "
                "stack region",
                where, slots, c["core"]["stack_entry_bytes"].get<uint64_t>()));
        const uint64_t records = c["ray_buffer"]["capacity_rays"].get<uint64_t>() *
                                 c["ray_buffer"]["ray_bytes"].get<uint64_t>();
        if (c["ray_buffer"]["storage"] == "memory" && records > region)
            throw InputError(fmt::format(
                "{}: ray_buffer.capacity_rays: {} rays x {} bytes overrun the 16 GiB ray-record "
                "region",
                where, c["ray_buffer"]["capacity_rays"].get<uint64_t>(),
                c["ray_buffer"]["ray_bytes"].get<uint64_t>()));
    }
    if (c["dram"]["model"] == "tlm" && c["dram"]["tlm_target"].get<std::string>().empty())
        throw InputError(fmt::format(
            "{}: dram.tlm_target: dram.model=tlm needs the path of a shared library that makes a "
            "TLM-2.0 target (docs/extending.md)",
            where));
    if (c["dram"]["model"] == "command") {
        DramParams p;
        p.device = c["dram"]["device"];
        p.page_policy = c["dram"]["page_policy"];
        p.address_mapping = c["dram"]["address_mapping"];
        p.refresh = c["dram"]["refresh"];
        try {
            command_dram_spec(p);
        } catch (const std::invalid_argument& e) {
            throw InputError(fmt::format("{}: {}", where, e.what()));
        }
    }
    if (c["sim"]["sample_first_unit"].get<int64_t>() >= 0 &&
        c["sim"]["sample_design"] != "systematic")
        throw InputError(fmt::format(
            "{}: sim.sample_first_unit: only a systematic sample has a first unit; add "
            "sim.sample_design=systematic (a stratified sample draws one unit per period; "
            "sim.sample_seed picks another draw)",
            where));
    if (SampleDesignRegistry::at(c["sim"]["sample_design"]).needs_profile &&
        !FastForwardRegistry::at(c["sim"]["sample_fast_forward"]).needs_profile)
        throw InputError(fmt::format(
            "{}: sim.sample_design={}: needs sim.sample_fast_forward=skip (the units' work comes "
            "from the frame's profile)",
            where, c["sim"]["sample_design"].get<std::string>()));
    if (c["sim"]["sample_first_unit"].get<int64_t>() >=
        c["sim"]["sample_period_units"].get<int64_t>())
        throw InputError(fmt::format(
            "{}: sim.sample_first_unit: expected -1 or below sim.sample_period_units ({}), got {}",
            where, c["sim"]["sample_period_units"].get<int64_t>(),
            c["sim"]["sample_first_unit"].get<int64_t>()));
    for (const char* position : {"below_l1", "below_l2"}) {
        const std::string kind = c["memory_path"][position];
        const MemoryBlockEntry& block = MemoryBlockRegistry::at(kind);
        const std::string why = block.check ? block.check(c["memory_path"][kind]) : "";
        if (!why.empty()) throw InputError(fmt::format("{}: memory_path.{}.{}", where, kind, why));
    }
    if (c["l2"]["line_bytes"].get<int64_t>() < c["l1"]["line_bytes"].get<int64_t>())
        throw InputError(fmt::format(
            "{}: l2.line_bytes: expected at least l1.line_bytes ({}), got {}", where,
            c["l1"]["line_bytes"].get<int64_t>(), c["l2"]["line_bytes"].get<int64_t>()));
}

}  // namespace

std::string Config::hash() const {
    uint64_t h = 1469598103934665603ull;
    for (unsigned char c : values.dump()) {
        h ^= c;
        h *= 1099511628211ull;
    }
    return fmt::format("{:016x}", h);
}

Config load_config(const std::string& path, const std::vector<std::string>& sets) {
    Config cfg;
    cfg.values = defaults_of(config_schema());
    if (!path.empty()) {
        std::vector<std::string> chain;
        load_chain(path, cfg.values, cfg.files, chain);
    }
    for (const std::string& s : sets) {
        const std::string where = "--set " + s;
        const auto eq = s.find('=');
        if (eq == std::string::npos || eq == 0)
            throw InputError(fmt::format("{}: expected KEY=VALUE, e.g. l1.size_kib=64", where));
        const std::string key = s.substr(0, eq), text = s.substr(eq + 1);
        const json* field = schema_entry(key);
        if (const char* why = removed_key(key))
            throw InputError(fmt::format("{}: {}: {}", where, key, why));
        if (!field) throw InputError(fmt::format("{}: {}: unknown key", where, key));
        if (field->contains("fields"))
            throw InputError(
                fmt::format("{}: {}: is a section; set one of its fields", where, key));
        json value = json::parse(text, nullptr, /*allow_exceptions=*/false);
        if (value.is_discarded()) value = text;  // bare words are strings: --set bvh.builder=sah
        if (key == "sim.fidelity" && is_legacy_sampled(value)) {
            value = "fast";
            cfg.values["sim"]["sampled"] = true;
        }
        const std::string why = check_leaf(*field, value);
        if (!why.empty())
            throw InputError(
                fmt::format("{}: {}: expected {}, got {}", where, key, why, value.dump()));
        json* node = &cfg.values;
        std::stringstream ss(key);
        std::string part;
        while (std::getline(ss, part, '.')) node = &(*node)[part];
        *node = value;
        cfg.overrides.push_back(s);
    }
    validate_cross(cfg.values, path.empty() ? (sets.empty() ? "defaults" : "--set") : path);
    cfg.typed = bind_params(cfg.values);
    return cfg;
}

std::string config_reference_markdown() {
    std::string out =
        "# RTSim config reference\n\nGenerated from configs/schema.json by `rtsim config "
        "--doc`.\n\n";
    out += config_schema().value("description", "") +
           "\n\n| key | type | default | limits | description |\n|---|---|---|---|---|\n";
    std::function<void(const json&, const std::string&)> walk = [&](const json& node,
                                                                    const std::string& path) {
        if (node.contains("fields")) {
            for (auto& [k, v] : node["fields"].items()) walk(v, path.empty() ? k : path + "." + k);
            return;
        }
        std::string limits = expectation(node);
        out +=
            fmt::format("| `{}` | {} | `{}` | {} | {} |\n", path, node["type"].get<std::string>(),
                        node["default"].dump(), limits, node.value("description", ""));
    };
    walk(config_schema(), "");
    return out;
}

json read_json_file(const std::string& path, const std::string& what) {
    const std::optional<std::string> text = read_file_text(path);
    if (!text) throw InputError(fmt::format("{}: cannot open {}", path, what));
    try {
        return json::parse(*text);
    } catch (const json::parse_error& e) {
        std::string msg = e.what();
        const auto pos = msg.find("] ");
        if (pos != std::string::npos) msg = msg.substr(pos + 2);
        throw InputError(fmt::format("{}: invalid JSON at byte {}: {}", path, e.byte, msg));
    } catch (const json::exception& e) {
        // A number beyond double's range is out_of_range, not a parse error (found by fuzzing).
        std::string msg = e.what();
        const auto pos = msg.find("] ");
        if (pos != std::string::npos) msg = msg.substr(pos + 2);
        throw InputError(fmt::format("{}: invalid JSON: {}", path, msg));
    }
}

}  // namespace rtsim

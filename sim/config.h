// Architecture configs: JSON files validated against configs/schema.json (embedded), with
// "extends" inheritance and --set KEY=VALUE overrides. Unknown keys, wrong types and impossible
// values are errors naming the file, the JSON path and what was expected.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/params.h"

namespace rtsim {

class Config {
  public:
    nlohmann::json values;           // effective config: defaults < extends chain < file < --set
    std::vector<std::string> files;  // files read, parent first
    std::vector<std::string> overrides;  // --set arguments applied, in order

    // The same values as typed block parameters, bound from `values` through config_bindings()
    // (the only way the simulator reads a config).
    Params typed;
    // FNV-1a 64 over the canonical (sorted-key) dump of `values`, as 16 hex digits.
    std::string hash() const;
};

// Loads `path` (empty: defaults only) and applies `sets` ("a.b=value"; value parsed as JSON,
// else taken as a string). Throws InputError.
Config load_config(const std::string& path, const std::vector<std::string>& sets);

// Reads a JSON file; InputError naming it (`what`: "config file", ...) if it cannot be opened
// or parsed, with the byte offset of the error.
nlohmann::json read_json_file(const std::string& path, const std::string& what);

// The schema (configs/schema.json) as compiled in.
const nlohmann::json& config_schema();
// Markdown reference of every field, generated from the schema (rtsim config --doc).
std::string config_reference_markdown();

}  // namespace rtsim

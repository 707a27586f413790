// DRAM devices as data: presets in configs/dram/*.json, embedded at build time and
// registered by name (`rtsim list dram_device`), read into a DramDeviceSpec field by field.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "models/dram.h"
#include "models/dram_command.h"
#include "models/registry.h"

namespace rtsim {

struct DramDeviceEntry {
    static constexpr const char* kKind = "dram_device";
    std::string name, description;
    std::vector<std::string> params;
    const char* json = nullptr;  // the preset file's text
};
using DramDeviceRegistry = Registry<DramDeviceEntry>;

// A device spec from a preset's JSON: every key must be a DramDeviceSpec field (or name,
// description, source), with a value of its type; the result must pass DramDeviceSpec::check.
// Throws std::invalid_argument naming the field and what is wrong.
DramDeviceSpec dram_device_from_json(const nlohmann::json& j);
// The spec as JSON (the same keys), for stats.json and round trips.
nlohmann::json dram_device_to_json(const DramDeviceSpec& s);
// Sets one field from text ("t_rcd", "20"), as --set does; throws std::invalid_argument on a bad
// value. The caller checks the whole spec (DramDeviceSpec::check) once every field is set.
void set_dram_device_field(DramDeviceSpec& s, const std::string& key, const std::string& value);

// A controller's energy by kind, in pJ: activate, read, write, refresh, background and total
// (stats.json of rtsim dram and of dram.model = command).
nlohmann::json dram_energy_json(const DramCounters& k);

// The device dram.model = command simulates: the preset dram.device with the config's controller
// policy (page policy, address mapping, refresh). Throws std::invalid_argument naming the field.
DramDeviceSpec command_dram_spec(const DramParams& p);

}  // namespace rtsim

// DRAM devices from presets, files and DRAMsim3 .ini device configs, and `rtsim dram`: a memory
// trace in DRAMsim3's format ("0x<address> READ|WRITE <cycle>" per line, cycles of the device's
// clock) run through the command-level DRAM model alone (models/dram_command.h).
#pragma once

#include <string>
#include <vector>

#include "models/dram_command.h"

namespace rtsim {

// A registered preset's name (rtsim list dram_device), a .json device file (the presets' keys)
// or a DRAMsim3 .ini device config; then `sets` ("t_rcd=20") applied in order. Throws InputError
// naming the file or setting and what is wrong.
DramDeviceSpec load_dram_device(const std::string& name_or_path,
                                const std::vector<std::string>& sets = {});

// A DRAMsim3 device config (.ini): organisation, timings, currents and controller settings it
// shares with this model; the rest (power-down, self-refresh, thermal) is ignored. Ranks follow
// from channel_size as DRAMsim3 derives them; the burst's bus cycles from its protocol rule.
DramDeviceSpec import_dramsim3_ini(const std::string& path);

struct DramTraceOptions {
    std::string trace_path;
    std::string device = "DDR4_8Gb_x8_3200";
    std::vector<std::string> sets;
    std::string out_dir;  // writes stats.json here when set
    // Writes every issued command here when set, a CSV line each:
    // cycle,command,channel,rank,bankgroup,bank,row (REF: bank group and bank -1).
    std::string commands_path;
    bool quiet = false;
};

int dram_command(const DramTraceOptions& opt);

}  // namespace rtsim

// Fidelity levels, registered by name (sim.fidelity; `rtsim list`): what runs the cores and in
// what order the shared blocks see their requests. Each level is one file in models/fidelity/.
//   fast      the cores run their ray slots in tight loops against the blocks' calendars; a
//             request's whole path through the memory levels is computed when it is issued
//             (models/core.h: CoreScheduler).
//   accurate  the time-ordered reference: every stage of every request runs at its own cycle
//             (the kernel's time) from one event queue, the cores reaching the memory blocks
//             through TLM-2.0 sockets, so every shared resource serves in simulated-time order
//             by construction (models/fidelity/accurate.cpp, models/transaction.h).
// Both drive the same blocks (same configs, counters and stats.json); only the order and the
// time at which the blocks are called differ.
#pragma once

#include <memory>
#include <string>
#include <systemc>
#include <vector>

#include "models/calendar.h"
#include "models/registry.h"
#include "models/timing.h"

namespace rtsim {

class Core;
class StageQueue;
class WakeSource;

// The one SystemC process that runs a chip's cores.
class ChipDriver : public sc_core::sc_module {
  public:
    explicit ChipDriver(sc_core::sc_module_name name) : sc_core::sc_module(name) {}
    // Host seconds the process ran (for the host section of stats.json, not simulated figures).
    virtual double host_busy_seconds() const = 0;
    // The earliest cycle a request may still reach the blocks the cores share, and core `i`'s
    // private blocks (its L1s and own units): the floors those blocks follow.
    virtual const TimeFloor* shared_floor() const = 0;
    virtual const TimeFloor* private_floor(size_t core) const = 0;
};

struct DriverSetup {
    std::vector<Core*> cores;
    WakeSource* wake = nullptr;  // where work for parked cores comes from (the ray buffer, or a
                                 // source that holds rays)
    // The queue the blocks run their stages on under the time-ordered engine (the chip's).
    StageQueue* stages = nullptr;
};

struct FidelityEntry {
    static constexpr const char* kKind = "fidelity";
    std::string name, description;
    std::vector<std::string> params;
    std::unique_ptr<ChipDriver> (*make)(const char* module_name, const DriverSetup&) = nullptr;
};
using FidelityRegistry = Registry<FidelityEntry>;

}  // namespace rtsim

// A block the config places in the memory path (memory_path.below_l1, memory_path.below_l2),
// registered by name, one file each in models/memory_path/ (docs/extending.md). Chip assembly
// builds it from the registry and binds it between two levels; both engines reach it through its
// sockets only (models/transaction.h), so a block written once runs under either.
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <systemc>
#include <vector>

#include "models/calendar.h"
#include "models/registry.h"
#include "models/stats.h"
#include "models/timing.h"
#include "models/transaction.h"

namespace rtsim {

// Where a block sits: between each core's L1s and the crossbar (one block per core, reached
// by that core's L1 misses), or between the L2 and DRAM (one block, reached by the L2's misses
// and write-backs).
enum class MemoryPathPosition : int { kBelowL1 = 0, kBelowL2 = 1 };
constexpr int kMemoryPathPositions = 2;
inline const char* memory_path_position_name(MemoryPathPosition p) {
    return p == MemoryPathPosition::kBelowL1 ? "below_l1" : "below_l2";
}

// What a block learns of its place besides its own parameters.
struct MemoryBlockSetting {
    MemoryPathPosition position = MemoryPathPosition::kBelowL2;
    // The level its own cycles are charged to in stall attribution (the level it stands in front
    // of: the L2 for below_l1, DRAM for below_l2).
    int level = kLevelDram;
    // Addresses the caches hold end here: a block that reads ahead never reads at or past it.
    uint64_t address_limit_bytes = ~uint64_t(0);
};

// Both engines reach a block through its target socket only: nb_transport (accurate) and
// b_transport (fast), as models/transaction.h lays down.
class MemoryBlock : public sc_core::sc_module, public TimedTarget {
  public:
    explicit MemoryBlock(sc_core::sc_module_name name) : sc_core::sc_module(name) {}
    // Binds the block's initiator socket to the next level's target socket.
    virtual void bind_below(TargetSocketBase& below) = 0;
    virtual void register_stats(StatsRegistry& reg) = 0;  // under this module's name
    // Its stats.json section (memory_path.<instance>), with its registered name as "block".
    virtual nlohmann::json report(const ReportContext& ctx) const = 0;
    // The floor behind which its calendars may forget (a private floor for a block per core).
    virtual void follow(const TimeFloor* /*floor*/) {}
    // Requests it served after one later in simulated time (stats.json out_of_order): the fast
    // engine's order, which an order-dependent block's state follows.
    virtual uint64_t out_of_order_requests() const { return 0; }
    // Requests it served (reads and writes), what the count above is a share of.
    virtual uint64_t requests() const = 0;
};

struct MemoryBlockEntry {
    static constexpr const char* kKind = "memory_block";
    std::string name, description;
    std::vector<std::string> params;  // its fields: memory_path.<name>.<field>
    // nullptr: no block ("none"). `config`: its memory_path.<name> section, validated against
    // the schema.
    std::unique_ptr<MemoryBlock> (*make)(const char* module_name, const nlohmann::json& config,
                                         const MemoryBlockSetting& setting) = nullptr;
    // What the schema's ranges cannot say of its section (fields that constrain each other):
    // empty if the section is fine, else "FIELD: what is wrong" (FIELD within the section).
    std::string (*check)(const nlohmann::json& config) = nullptr;
};
using MemoryBlockRegistry = Registry<MemoryBlockEntry>;

}  // namespace rtsim

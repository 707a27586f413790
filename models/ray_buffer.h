// Treelet ray buffer: an on-chip SRAM holding every ray in flight, queued by the treelet it
// needs next (Aila & Karras 2010; Kopta et al. 2015, STRaTA), and the scheduler that hands
// cores batches of rays from one treelet, so the treelet's data is fetched once for many rays.
//
// A ray enters the buffer when there is room for it (admission is the back-pressure: a full
// buffer holds new rays back, and a ray crossing into another treelet writes its state back
// to its own entry, so no ray is ever dropped), leaves it when it finishes, and in between
// moves from queue to queue. Reads and writes of ray records share `ports` per cycle and take
// `latency_cycles`. A passive block: cores call it in global time order.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <systemc>
#include <utility>
#include <vector>

#include "models/core.h"
#include "models/stats.h"
#include "models/timing.h"
#include "models/transaction.h"
#include "models/treelet_scheduler.h"
#include "workloads/step.h"

namespace rtsim {

// Defaults: the schema's (tests/sim/test_params.cpp checks they agree).
struct RayBufferParams {
    uint32_t capacity_rays = 8192;
    uint32_t ray_bytes = 64;  // one ray record: origin, direction, extent, hit, traversal state
    int ports = 2;            // ray records read or written per cycle
    Cycle latency_cycles = 2;
    uint32_t batch_rays = 256;            // rays a core takes from one treelet's queue at once
    std::string scheduler = "most_rays";  // a registered treelet scheduler (rtsim list)
    uint32_t max_wait_batches = 8;        // its bound on starvation (age_ordered)
    uint32_t banks = 1;                   // SRAM banks (an access's energy is one bank's)
    // The records live in memory (through the L2) instead of the SRAM (ray_buffer.storage).
    bool in_memory = false;
};

// Where a treelet's data lives: one run of node records and one of triangles.
struct TreeletSpan {
    uint64_t node_addr = 0, node_bytes = 0;
    uint64_t tri_addr = 0, tri_bytes = 0;
    uint64_t instance_addr = 0, instance_bytes = 0;  // a two-level TLAS treelet's instance records
    uint64_t bytes() const { return node_bytes + tri_bytes + instance_bytes; }
};

class RayBuffer : public sc_core::sc_module, public WakeSource {
  public:
    RayBuffer(sc_core::sc_module_name name, const RayBufferParams& params,
              std::vector<TreeletSpan> treelets, RayWorkSource* source);
    void register_stats(StatsRegistry& reg);  // under this module's name
    // stats.json "ray_buffer": its size, traffic, batches and crossings, and the treelets the
    // cores loaded for its batches.
    nlohmann::json report(const ReportContext& ctx, uint64_t treelet_loads,
                          uint64_t treelet_load_bytes) const;
    const RayBufferParams& params() const { return params_; }
    uint64_t port_out_of_order() const { return ports_.out_of_order; }
    const TreeletSpan& span(uint32_t treelet) const { return treelets_[treelet]; }

    // A batch: up to batch_rays ray handles of one treelet, which leave its queue. First admits
    // up to batch_rays new rays while there is room. False when no treelet has queued rays
    // (`finished()` tells whether more can come).
    bool next_batch(Cycle now, uint32_t& treelet, std::deque<uint32_t>& rays);
    // True once the source is empty and no ray is left in the buffer.
    bool finished() const { return source_done_ && occupancy_ == 0; }
    // Reads ray `handle` into a core's slot (the slot owns the work until it gives it back);
    // returns the cycle the record is there.
    Cycle read(uint32_t handle, Cycle now, RayWork& work, size_t& pos);
    // The cycle ray `handle`'s record is written: it cannot be read before.
    Cycle record_written(uint32_t handle) const { return entries_[handle].written; }
    // A ray crossing into `treelet`: its state is written back and queued there.
    Cycle requeue(uint32_t handle, RayWork& work, size_t pos, uint32_t treelet, Cycle now);
    // A finished ray leaves the buffer.
    void release(uint32_t handle);

    // The cores' socket: each finds the buffer through it (DirectAccess, models/transaction.h)
    // and calls it directly, as it schedules, reads and writes rays on every step; it answers
    // nothing else.
    TargetSocket<RayBuffer> up;

    // Records in memory (params().in_memory): their reads and writes go through `down` (bound
    // to the level below the L1s). A driver that runs memory requests itself (the time-ordered
    // engine) defers them: reads then return when the record may be read (it reads it itself),
    // and writes queue their addresses (deferred_writes) for it to post.
    InitiatorSocket<RayBuffer> down;
    void set_defer(bool defer) { defer_ = defer; }
    bool has_memory() const { return below_.bound(); }
    uint64_t record_address(uint32_t handle) const {
        return kRayRecordBase + uint64_t(handle) * params_.ray_bytes;
    }
    std::vector<uint64_t>& deferred_writes() { return deferred_writes_; }
    // Slots parked waiting for work (the cores say when they park and wake them).
    void note_parked(int delta) { parked_slots_ = uint32_t(int64_t(parked_slots_) + delta); }
    // Work arrived while slots are parked: the core running stops so that they wake first.
    bool wake_needed() const { return wake_ && parked_slots_ > 0; }
    // Work arrived for idle cores since the last call: the cycle it arrived (cores wake then).
    bool take_wake(Cycle& at) override {
        if (!wake_) return false;
        wake_ = false;
        at = wake_cycle_;
        return true;
    }

    uint64_t reads = 0, writes = 0;  // ray records
    uint64_t port_wait_cycles = 0;   // cycles accesses waited for a port
    uint64_t peak_rays = 0;          // most rays held at once
    uint64_t admitted = 0;           // rays that entered the buffer
    uint64_t admission_blocked = 0;  // batch requests that found it full with rays waiting outside
    uint64_t batches = 0, batch_rays = 0;
    uint64_t crossings = 0;  // rays queued again for another treelet

  private:
    void b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time&) {
        if (!answer_direct(this, gp)) gp.set_response_status(tlm::TLM_COMMAND_ERROR_RESPONSE);
    }
    Cycle port(Cycle now);
    // A record written at `now`: through the SRAM's ports, or to memory; the cycle it is there.
    Cycle write_record(uint32_t handle, Cycle now);
    void admit(Cycle now);
    void enqueue(uint32_t handle, uint32_t treelet, Cycle now);
    // Tells the scheduler that a queue's length changed from `before`.
    void recount(uint32_t treelet, size_t before);

    RayBufferParams params_;
    std::vector<TreeletSpan> treelets_;
    RayWorkSource* source_;
    bool source_done_ = false;
    struct Entry {
        RayWork work;
        size_t pos = 0;
        Cycle written = 0;  // cycle the record was last written: it cannot be read before
        uint64_t seq = 0;   // queueing order (the scheduler's age)
    };
    std::vector<Entry> entries_;
    std::vector<uint32_t> free_;
    uint32_t occupancy_ = 0;
    std::vector<std::deque<uint32_t>> queues_;
    std::unique_ptr<TreeletScheduler> scheduler_;
    uint64_t next_seq_ = 0;
    PortCalendar ports_;
    bool wake_ = false;
    Cycle wake_cycle_ = 0;
    uint32_t parked_slots_ = 0;
    LtPort below_{down};
    bool defer_ = false;
    std::vector<uint64_t> deferred_writes_;
};

}  // namespace rtsim

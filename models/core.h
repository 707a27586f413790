// A MIMD traversal core: `ray_slots` thread contexts, each running one ray's step stream
// (node fetch + box test, triangle fetch + triangle test) against the core's L1 and units.
//
// Speed: a ray slot's steps cost no SystemC event. A core is a passive block: the CoreScheduler
// (one SystemC process for all cores) advances it, and the core runs its earliest-ready slot in
// a tight loop against the resource calendars of its units and L1. Private work (an L1 hit on a
// private unit) runs ahead freely; work that touches shared state (taking a ray, an L1 miss, a
// shared unit) waits until it is the earliest such work on the chip, so shared blocks see
// requests nearly in time order (a miss's later stages still land out of order by their
// latencies: stats.json out_of_order counts it, and sim.fidelity = accurate, the time-ordered
// reference in models/fidelity/accurate.cpp, measures the error). (A temporal-decoupling quantum
// that let a core run shared work ahead of the others bought at most 1.13x for large errors and
// was removed: bench/results/fidelity_quanta.md.)
#pragma once

#include <deque>
#include <string>
#include <systemc>
#include <vector>

#include "models/cache.h"
#include "models/calendar.h"
#include "models/fidelity.h"
#include "models/short_stack.h"
#include "models/stats.h"
#include "models/timing.h"
#include "models/transaction.h"
#include "models/unit.h"
#include "workloads/step.h"

namespace rtsim {

// Tells the core scheduler that work arrived for parked cores, and from which cycle.
class WakeSource {
  public:
    virtual ~WakeSource() = default;
    virtual bool take_wake(Cycle& at) = 0;
};

// Hands out rays to cores; the chip's shared work queue. Calls arrive in simulated time order
// from every core.
class RayWorkSource {
  public:
    virtual ~RayWorkSource() = default;
    // Fills `work` with the next ray's steps; false when no ray is left, or none yet (holding).
    // `now`: the cycle the ray is taken at (a sampled run times its units by it).
    virtual bool next(RayWork& work, Cycle now) = 0;
    // After next() returned false: whether a ray is held back rather than none left. The slot
    // then parks until the source's wakes() says when to look again.
    virtual bool holding() const { return false; }
    // A work item of `rays` rays that a core took from this source finished at `done`.
    virtual void finished(uint32_t rays, Cycle done) {
        (void)rays;
        (void)done;
    }
    // Where the wakes of slots parked on a held ray come from; nullptr: this source never holds.
    virtual WakeSource* wakes() { return nullptr; }
    // While set, a wake is waiting to be taken: a core running stops so that parked slots wake
    // first. nullptr: this source never holds.
    virtual const bool* wake_pending() const { return nullptr; }
};

struct CoreParams {
    int ray_slots = 8;
    int issue_width = 1;             // instructions the core issues per cycle, over all slots
    Cycle issue_latency_cycles = 1;  // pipeline depth from the last issued instruction to the fetch
    // Per StepKind, control instructions issued before the step's fetch (a node step's traversal
    // control, a triangle step's intersection control).
    int step_instructions[kStepKinds] = {1, 1, 1, 8};
    int ray_setup_instructions = 1;  // instructions to start a ray
    bool units_shared = false;       // units serve several cores: every step synchronises
    // Packet mode: a work item is a packet and its box and triangle operations occupy this
    // many SIMD lanes whether or not every lane's ray takes part (lockstep). 0: single rays.
    int packet_lanes = 0;
    bool treelet_prefetch = true;  // treelet mode: load a batch's treelet before its rays run
    // Memory traffic of the traversal itself, through the level below the L1 (the L1s hold
    // BVH data only). A short stack of this many entries per slot, the rest spilled to memory
    // (models/short_stack.h); 0: the whole stack on chip.
    uint32_t short_stack_entries = 0;
    uint32_t stack_entry_bytes = 8;  // a node address and its entry distance
    uint32_t hit_record_bytes = 0;   // written per ray when it finishes; 0: results stay on chip
    // Those writes are posted: each holds one of these entries from its issue until the level
    // below has accepted it (looked it up); a write finding all busy waits (stall cause
    // write_buffer). 0: unbounded.
    uint32_t write_buffer_entries = 8;
};

// The cycle a core reports when it has nothing left to do.
constexpr Cycle kNeverCycle = ~Cycle(0);
// ...and when it has nothing to do now but more may come (treelet mode): it waits to be woken.
constexpr Cycle kParkedCycle = kNeverCycle - 1;

// A cycle and an index packed into one key, cycle above the index bits, so that the least key
// is the earliest cycle and, among equals, the lowest index. Picking the earliest of several
// (ray slots, cores) is then a plain minimum, which compiles to conditional moves: which one is
// earliest changes unpredictably from step to step, and a branch on it mispredicts half the time.
// kParkedCycle and kNeverCycle map to the two largest cycle fields.
class CycleKeys {
  public:
    // Keys for indices below `count`.
    explicit CycleKeys(size_t count) {
        while ((size_t(1) << bits_) < count) ++bits_;
        top_ = ~uint64_t(0) >> bits_;
    }
    uint64_t key(Cycle c, size_t index) const {
        const uint64_t field = c >= kParkedCycle ? top_ - (kNeverCycle - c) : c;
        return field << bits_ | index;
    }
    Cycle cycle(uint64_t key) const {
        const uint64_t field = key >> bits_;
        return field >= top_ - 1 ? kNeverCycle - (top_ - field) : field;
    }
    size_t index(uint64_t key) const { return size_t(key & ((uint64_t(1) << bits_) - 1)); }

  private:
    uint32_t bits_ = 0;
    uint64_t top_ = 0;  // the largest cycle field: kNeverCycle's
};

class RayBuffer;

class Core : public sc_core::sc_module {
  public:
    // Per StepKind, the memory its fetches go to (the same L1 for all, or a split L1's node and
    // triangle caches) and the unit that tests it (a PipelinedUnit's socket).
    // `memory` and `units` (where given) are bound to memory_socket and unit_socket here.
    Core(sc_core::sc_module_name name, const CoreParams& params,
         const std::array<TargetSocketBase*, kStepKinds>& memory,
         const std::array<TargetSocketBase*, kStepKinds>& units, RayWorkSource* source);
    // Per StepKind, the cache at the other end of memory_socket (null: not a cache, such as
    // ideal memory). The fast engine reads its tags to serve a private hit ahead of the other
    // cores, and to hold back a miss until one of its MSHRs frees (models/core.cpp); everything
    // that reaches memory goes through the socket.
    void set_first_caches(const std::array<Cache*, kStepKinds>& caches) {
        for (int k = 0; k < kStepKinds; ++k) cache_by_kind_[k] = caches[size_t(k)];
    }
    void register_stats(StatsRegistry& reg);  // under this module's name (core[0].rays)
    const CoreParams& params() const { return params_; }
    uint64_t issue_port_out_of_order() const { return issue_port_.out_of_order; }
    // No-work cycles of the retired slots, from their retirement to `end`.
    uint64_t retired_idle_cycles(Cycle end) const;
    // stats.json "stalls" entry: ray-slot cycles per cause, the cycles slots had no ray
    // (no_work, counted as they sat idle), their shares, and what neither accounts for of
    // slots x cycles (unaccounted_cycles, 0 when every cycle is charged once).
    nlohmann::json stall_report(const ReportContext& ctx) const;
    // The same over several cores (the "total" entry).
    static nlohmann::json stall_report_total(const std::vector<const Core*>& cores,
                                             const ReportContext& ctx);
    // stats.json "packets" (packet mode): active lanes of the lane slots operations occupied.
    static nlohmann::json packet_report(const std::vector<const Core*>& cores);
    void set_series(TimeSeries* rays_done) { rays_series_ = rays_done; }
    // Treelet mode: rays come in per-treelet batches from the ray buffer (which admits them
    // from the source) instead of one by one from the source. `buffer` (its `up` socket) is
    // bound to ray_buffer_socket here; the core finds the buffer through it at the end of
    // elaboration.
    void set_ray_buffer(TargetSocketBase* buffer) {
        if (!buffer) return;
        ray_buffer_socket.bind(*buffer);
        treelet_mode_ = true;
    }
    // Where stack spills, refills and hit records go (the L1s' next level; bound to
    // local_socket here), and the chip-wide index of this core's first slot (each slot spills to
    // its own stack region).
    void set_local_memory(TargetSocketBase* local, uint64_t first_slot) {
        if (local) local_socket.bind(*local);
        first_slot_ = first_slot;
    }
    bool has_local_memory() const { return lt_local_.bound(); }
    // Functional warming (sampled runs) of a stack or hit-record access, through local_socket.
    void warm_local(uint64_t addr, uint32_t size_bytes, bool write) const {
        lt_local_.warm(addr, size_bytes, write);
    }
    // The time-ordered engine's requests (models/transaction.h): per StepKind to the memory its
    // fetches go to, and below the L1s (stack refills and spills, ray records, hit records).
    InitiatorSocket<Core> memory_socket[kStepKinds];
    InitiatorSocket<Core> local_socket;
    // Per StepKind, the unit that tests it. A step's operation books the unit the socket leads
    // to, called directly once found through the socket at the end of elaboration
    // (models/unit.h).
    InitiatorSocket<Core> unit_socket[kStepKinds];
    InitiatorSocket<Core> ray_buffer_socket;  // treelet mode: the ray buffer
    // What the answers to those requests go to (the time-ordered engine).
    class Requester {
      public:
        virtual void answered(tlm::tlm_generic_payload& gp) = 0;

      protected:
        ~Requester() = default;
    };
    void set_requester(Requester* requester) { requester_ = requester; }
    // Without a ray buffer, a ray finishes where its last step's unit operation ends; with hit
    // records it ends at its own turn instead, as writing them is shared work.
    bool finish_at_step_end() const { return !ray_buffer_ && params_.hit_record_bytes == 0; }
    // The address of memory stack entry `index` of slot `slot`.
    uint64_t stack_address(size_t slot, uint32_t index) const {
        return kStackRegionBase +
               (first_slot_ + slot) * uint64_t(kStackDepthMax + 1) * params_.stack_entry_bytes +
               uint64_t(index) * params_.stack_entry_bytes;
    }
    // (A frame of more than 16 GiB of hit records wraps around its region.)
    uint64_t hit_record_address(uint32_t ray_id) const {
        return kHitRecordBase + uint64_t(ray_id) * params_.hit_record_bytes % kLocalRegionBytes;
    }
    // A finished work item's hit-record bytes (0: none written).
    uint32_t hit_record_size(const RayWork& work) const {
        return params_.hit_record_bytes * work.rays;
    }
    void count_hit_records(uint32_t bytes) {
        hit_record_writes += 1;
        hit_record_bytes += bytes;
    }
    // Stack spills of `traffic`: counted, and their bytes.
    uint32_t count_stack_spill(const StackTraffic& traffic) {
        const uint32_t bytes = traffic.spill_entries * params_.stack_entry_bytes;
        ++stack_spills;
        stack_spill_bytes += bytes;
        return bytes;
    }
    void count_stack_refill(const StackTraffic& traffic) {
        ++stack_refills;
        stack_refill_bytes += uint64_t(traffic.refill_entries) * params_.stack_entry_bytes;
    }

    // Runs the slots in ready order: private work freely, shared work only at cycles up to
    // `horizon`. Returns the cycle of the next shared work; kParkedCycle when every slot waits
    // for work that may still come; kNeverCycle once every slot has retired (the work queue is
    // empty and all rays are done).
    // `others_floor`: the earliest cycle the other cores may still send a request at; with this
    // core's own, it keeps the shared blocks' floor (set_shared_floor) current as the core runs.
    // `at_horizon`: whether shared work exactly at `horizon` may run (this core comes first
    // among cores at that cycle).
    Cycle advance(Cycle horizon, Cycle others_floor = kNeverCycle, bool at_horizon = true);
    void set_shared_floor(TimeFloor* shared) { shared_floor_ = shared; }
    // Parked slots look for work again from cycle `at`; false if none was parked.
    bool wake(Cycle at);
    // The earliest cycle this core may still send a request at (its earliest slot's): the floor
    // its private blocks (L1s, own units) follow.
    const TimeFloor* floor() const { return &floor_; }

    // The ray slots' state machine (models/core_slots.h), written once: slot `slot`'s next
    // action at t, through `engine`, which says how requests reach the memory and when the slot
    // runs again. Returns kRunOn, or the cycle of shared work the engine holds back (`beyond`).
    static constexpr Cycle kRunOn = kNeverCycle;
    template <class Engine>
    Cycle run_slot(size_t slot, Cycle t, Engine& engine);
    // How an engine's fetch of a step went: done (its data there at `cycle`, `bd` the cycles by
    // level), held back until `cycle` (shared work past the engine's horizon), or pending (the
    // engine calls step_fetched when the data is there).
    struct Fetch {
        enum Kind : uint8_t { kDone, kHold, kPending } kind = kPending;
        Cycle cycle = 0;
        AccessBreakdown bd;
    };
    // The treelet loader's next line at t (models/core_slots.h): requested through `engine`,
    // held by it while every MSHR is busy.
    template <class Engine>
    void run_loader(Cycle t, Engine& engine);
    // Slot `slot`'s pending fetch arrived at t, having spent `cycles_by_level` (kMemLevels)
    // cycles at each level: charged, then its unit operations.
    template <class Engine>
    void step_fetched(size_t slot, Cycle t, const Cycle* cycles_by_level, Engine& engine);
    // When slot `slot` took its ray, and since when it has had no work (parked or retired).
    Cycle slot_start(size_t slot) const { return slots_[slot].start; }
    Cycle slot_idle_since(size_t slot) const { return slots_[slot].idle_since; }
    // Treelet mode: slot `slot`'s ray's ray-buffer entry.
    uint32_t slot_handle(size_t slot) const { return slots_[slot].handle; }

    // Issues `instructions` (at least 1) ready at t; returns when the step's fetch can start.
    Cycle issue(Cycle t, int instructions);
    // A work item of `rays` rays that took a slot at `start` finished at `done`.
    void count_finished(uint32_t rays, Cycle start, Cycle done);
    // Slot `slot` has had no work since `since`: retired for good, or parked (then the caller
    // counts its no-work cycles when it wakes).
    void set_slot_idle(size_t slot, Cycle since, bool retired) {
        slots_[slot].idle_since = since;
        set_ready(slot, retired ? kNeverCycle : kParkedCycle);
    }
    RayWorkSource* source() const { return source_; }
    RayBuffer* ray_buffer() const { return ray_buffer_; }

    // Stall attribution: every cycle a ray slot holds a ray is charged to exactly one cause;
    // cycles without a ray are counted as no work (no_work_cycles, retired_idle_cycles).
    // The units' causes follow kUnitStall in StepKind order (box_unit, triangle_unit).
    enum Stall {
        kIssue,
        kL1,
        kL2,
        kDram,
        kCrossbar,
        kUnitStall,
        kRayBuffer = kUnitStall + kStepKinds,
        kStack,        // waiting for spilled stack entries to come back from memory
        kWriteBuffer,  // a write waiting for a free write-buffer entry
        kStallKinds
    };
    static const char* stall_name(int s);
    uint64_t stall_cycles[kStallKinds] = {};

    uint64_t rays = 0;
    uint64_t steps = 0;
    uint64_t ray_latency_cycles = 0;  // summed over rays, cycles each held a slot
    uint64_t issue_stall_cycles = 0;  // cycles steps waited for an issue slot
    // Slot cycles without a ray, counted as they pass (parked slots when woken; retired slots
    // from retirement to the end are added at report time).
    uint64_t no_work_cycles = 0;
    uint64_t last_cycle = 0;  // cycle the core's last ray finished
    // Treelet mode
    uint64_t treelet_loads = 0, treelet_load_bytes = 0;
    // Packet mode: lanes whose ray took part, and lanes occupied, summed over steps.
    uint64_t active_lanes = 0, lane_slots = 0;
    // The traversal's own memory traffic: stack spills (writes) and refills (reads), hit records.
    uint64_t stack_spills = 0, stack_spill_bytes = 0, stack_refills = 0, stack_refill_bytes = 0;
    uint64_t hit_record_writes = 0, hit_record_bytes = 0;

  private:
    // Treelet mode: what a slot without a running ray does next (take a ray from the batch, read
    // its record once written, issue its setup once read).
    enum Phase : uint8_t { kTakeRay, kReadRecord, kSetUp };
    struct Slot {
        Phase phase = kTakeRay;
        RayWork work;
        size_t pos = 0;
        Cycle start = 0;
        bool busy = false;
        bool fetch_is_shared = false;  // the next step's fetch was found to leave the L1
        // A fetch of several lines sent line by line (Core::advance): the lines sent so far, and
        // the slowest one's data cycle and breakdown.
        uint8_t fetch_lines_sent = 0;
        Cycle fetch_ready = 0;
        AccessBreakdown fetch_bd;
        // The step's data is there (at the slot's ready cycle): its unit operations wait for
        // their turn (see advance).
        bool unit_pending = false;
        uint8_t unit_kind = 0;
        uint16_t unit_items = 0;
        uint32_t handle = 0;            // treelet mode: the ray's ray-buffer entry
        uint32_t treelet = 0;           // treelet mode: the treelet this slot's ray runs in
        Cycle idle_since = 0;           // parked or retired: the cycle it found no work
        ShortStack stack;               // the running ray's short stack (core.short_stack_entries)
        size_t stack_pos = ~size_t(0);  // the step whose stack traffic has been made
    };
    // The slot has no work from `t` on: parked (more may come) or retired.
    void go_idle(size_t slot, Cycle t, Cycle key_cycle);

    // Treelet mode with prefetch: a batch's treelet is loaded into the L1 (or treelet cache)
    // line by line, one line per cycle in address order (node records, then triangles), by a
    // loader (the fast engine runs it as one more entry of the slots' ready keys). A line that
    // would miss while every MSHR is busy holds the load until one frees: the loader never
    // queues behind its MSHRs, and its requests reach the shared levels in time order. A new
    // batch's load replaces one still running.
    void load_treelet(uint32_t treelet);  // the lines to load, counted
    struct TreeletLoad {
        uint64_t next[kStepKinds] = {}, end[kStepKinds] = {};  // per StepKind: lines left
    } load_;
    size_t loader_ = ~size_t(0);  // the loader's index among the ready keys (none: ~0)
    // A step's unit operations ran from `fetched` (data there) to `done`; `now`: the cycle of
    // the action that booked them.
    template <class Engine>
    void step_done(size_t slot, int kind, Cycle fetched, Cycle done, Cycle now, Engine& engine);
    // The fast engine's side of run_slot (loosely timed: requests complete at once).
    struct LooselyTimed;
    // The lanes a step's unit operations occupy (a packet's, or 1 for a single ray).
    int unit_lanes() const { return params_.packet_lanes > 0 ? params_.packet_lanes : 1; }
    void finish_ray(Slot& s, Cycle done) {
        count_finished(s.work.rays, s.start, done);
        s.busy = false;
    }

    tlm::tlm_sync_enum nb_transport_bw(tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time&) {
        requester_->answered(gp);
        phase = tlm::END_RESP;
        return tlm::TLM_COMPLETED;
    }
    Requester* requester_ = nullptr;
    CoreParams params_;
    RayWorkSource* source_;
    // The source's pending-wake flag when it may hold a ray (RayWorkSource::wake_pending):
    // finished rays are then reported to it. nullptr otherwise, and in treelet mode.
    const bool* source_wake_ = nullptr;
    std::vector<Slot> slots_;
    // Per slot: the cycle it is ready for its next step (kNeverCycle once retired) as a key of
    // keys_, padded to a multiple of eight with retired keys. Apart from the slots so that finding
    // the earliest is a short branch-free scan.
    std::vector<uint64_t> ready_;
    CycleKeys keys_;
    void set_ready(size_t slot, Cycle c) { ready_[slot] = keys_.key(c, slot); }
    // Per StepKind, the L1 its fetches go to when it is a Cache (set_first_caches): its hit path
    // is called directly, on every step.
    Cache* cache_by_kind_[kStepKinds] = {};
    // Per StepKind: the unit its test runs on, found through unit_socket.
    PipelinedUnit* unit_by_kind_[kStepKinds] = {};
    void end_of_elaboration() override;
    void attach_ray_buffer(RayBuffer* buffer);
    int instructions_by_kind_[kStepKinds];  // per StepKind: control instructions per step
    RayBuffer* ray_buffer_ = nullptr;
    bool treelet_mode_ = false;  // a ray buffer is bound (found at the end of elaboration)
    // Per write-buffer entry, the cycle it frees (empty: unbounded).
    std::vector<Cycle> write_buffer_;
    // The cycle a write ready at t finds an entry free.
    Cycle write_buffer_free_at(Cycle t) const {
        if (write_buffer_.empty()) return t;
        return std::max(t, *std::min_element(write_buffer_.begin(), write_buffer_.end()));
    }
    // Whether slot `slot`'s write at t finds every entry busy: then the slot is charged the wait
    // and tries again when the first entry frees.
    bool wait_for_write_entry(size_t slot, Cycle t) {
        const Cycle free = write_buffer_free_at(t);
        if (free <= t) return false;
        stall_cycles[kWriteBuffer] += free - t;
        set_ready(slot, free);
        return true;
    }
    // Posts a write at t, which has found an entry free (write_buffer_free_at(t) == t).
    void post_write(uint64_t addr, uint32_t bytes, Cycle t) {
        const Cycle accepted = lt_local_.write(addr, bytes, t);
        if (!write_buffer_.empty())
            *std::min_element(write_buffer_.begin(), write_buffer_.end()) = accepted;
    }
    uint64_t first_slot_ = 0;
    std::deque<uint32_t> batch_;  // treelet mode: rays of the current batch not yet in a slot
    uint32_t batch_treelet_ = 0;
    uint32_t loaded_treelet_ = ~0u;
    TimeSeries* rays_series_ = nullptr;
    PortCalendar issue_port_;
    TimeFloor floor_;
    TimeFloor* shared_floor_ = nullptr;
    uint32_t parked_slots_ = 0;  // slots waiting for work that may still come
    // The fast engine's calls through memory_socket, per StepKind (nodes: the L1; triangles: the
    // triangle L1 of a split L1, else the same L1), and through local_socket (below the L1s:
    // stack and hit-record traffic). Last: their payloads would spread the fields above over
    // more of the host's cache lines.
    LtPort lt_memory_[kStepKinds];
    mutable LtPort lt_local_;
};

// Runs a set of cores in global time order: the cores' one SystemC process. It picks the core
// whose next shared work is earliest and advances it up to the next one's cycle, so shared
// blocks see requests nearly in time order at the cost of a scan of the cores'
// next cycles rather than a kernel event. It also keeps the shared blocks' time floor (the
// earliest cycle any running core may still send a request at). SystemC time follows the
// earliest core, synchronised every `kKernelSyncCycles` (nothing else in the chip is an active
// process; the kernel's time serves progress reports and sc_stop).
class CoreScheduler : public ChipDriver {
  public:
    SC_HAS_PROCESS(CoreScheduler);
    static constexpr Cycle kKernelSyncCycles = 4096;
    // `wake`: where work for parked cores comes from (the ray buffer in treelet mode).
    CoreScheduler(sc_core::sc_module_name name, std::vector<Core*> cores,
                  WakeSource* wake = nullptr);
    // Host seconds the process ran (not simulated statistics: for the host section).
    double host_busy_seconds() const override { return host_busy_seconds_; }
    // The earliest cycle any core may still send a request at: the floor shared blocks follow.
    const TimeFloor* shared_floor() const override { return &floor_; }
    // A core's own earliest slot: its private blocks run ahead of the other cores.
    const TimeFloor* private_floor(size_t core) const override { return cores_[core]->floor(); }

  private:
    void run();
    std::vector<Core*> cores_;
    WakeSource* wake_;
    double host_busy_seconds_ = 0;
    TimeFloor floor_;
    // Per core, padded to eights with retired cores: the cycle of its next shared work as a key
    // of keys_, and its floor while it runs (kNeverCycle otherwise).
    std::vector<uint64_t> next_;
    std::vector<Cycle> floors_;
    CycleKeys keys_;
};

// The stall causes of stats.json's "stalls" shares, in report order: the cores' causes
// (Core::stall_name), then "no_work" (slot cycles without a ray).
std::vector<std::string> stall_causes();

}  // namespace rtsim

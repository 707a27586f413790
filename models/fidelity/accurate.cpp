// sim.fidelity = accurate: the time-ordered reference timing model.
//
// One event queue (models/transaction.h: StageQueue) holds every stage of every request, ordered
// by cycle: a ray slot's next action, and each stage the memory blocks run themselves (a request
// arriving at a cache, each line's tag check at its lookup cycle, a miss taking an MSHR or
// queueing for one, each DRAM stage, a line crossing the crossbar, a fill completing). The
// SystemC kernel advances from one cycle with stages to the next (run_cycle). The cores reach the
// blocks through TLM-2.0 sockets with the base protocol's non-blocking calls, so every bank, MSHR
// pool, bus, link, unit and port sees its requests in simulated-time order by construction: the
// out-of-order counts of stats.json are 0 here (tests check it).
//
// The blocks' behaviour is theirs (models/cache.cpp, crossbar.cpp, dram.cpp): this engine runs the
// cores' ray-slot state machine (Core::run_slot, models/core_slots.h: its TimeOrdered engine makes
// each slot action an event) and keeps what belongs to the cores' side of the sockets: requests in
// flight, write-buffer entries, parked slots. Each answer carries its request's timeline (which
// level held it over which cycles), from which the slot's stalls are charged exactly.
#include <chrono>
#include <deque>
#include <vector>

#include "models/cache.h"
#include "models/core.h"
#include "models/core_slots.h"
#include "models/fidelity.h"
#include "models/ray_buffer.h"
#include "models/transaction.h"
#include "models/unit.h"

namespace rtsim {
namespace {

class ReferenceScheduler final : public ChipDriver, private StageHandler, private Core::Requester {
  public:
    SC_HAS_PROCESS(ReferenceScheduler);
    ReferenceScheduler(sc_core::sc_module_name name, const DriverSetup& setup)
        : ChipDriver(name), cores_(setup.cores), wake_(setup.wake), stages_(*setup.stages) {
        uint64_t slots = 0;
        for (Core* core : cores_) {
            slot_rank_.push_back(slots);
            slots += uint64_t(core->params().ray_slots);
            CoreState cs;
            cs.write_wait_from.resize(size_t(core->params().ray_slots));
            states_.push_back(std::move(cs));
            core->set_requester(this);
        }
        SC_METHOD(run_cycle);
    }
    void start_of_simulation() override {
        // Ray records in memory: read and written here, each stage at its cycle. (The cores know
        // their ray buffer once elaborated.)
        for (Core* core : cores_)
            if (RayBuffer* rb = core->ray_buffer(); rb && rb->params().in_memory)
                rb->set_defer(true);
    }
    double host_busy_seconds() const override { return host_busy_seconds_; }
    const TimeFloor* shared_floor() const override { return stages_.floor(); }
    const TimeFloor* private_floor(size_t) const override { return stages_.floor(); }

  private:
    enum Stage : uint32_t { kSlot, kLoad };
    // What a request's answer goes to. kForStep: a fetched step (core, slot); kForStack: a stack
    // refill the slot waits for; kForRecord: a ray record the slot reads from memory; kForWrite: a
    // core's posted write (owner_k 1: it holds a write-buffer entry); kForNothing: a treelet
    // load's line, a ray record written.
    enum Purpose : uint32_t { kForStep, kForStack, kForRecord, kForWrite, kForNothing };
    // What the engine keeps per core beside the core's own slots.
    struct CoreState {
        std::vector<Cycle> write_wait_from;  // per slot: when it began waiting for a write entry
        // The treelet load in progress (Core::run_loader): its kLoad stages' generation.
        uint32_t load_generation = 0;
        // Write-buffer entries held by posted writes not yet accepted, and slots waiting for one.
        uint32_t writes_in_flight = 0;
        std::deque<uint32_t> write_waiters;
    };

    // The core's side of the time-ordered engine: each slot action is an event at its cycle,
    // each request goes through the core's sockets and its answer resumes the slot.
    struct TimeOrdered {
        static constexpr bool kTimeOrdered = true;
        ReferenceScheduler& r;
        uint32_t c;

        bool beyond(Cycle) const { return false; }
        void ready(size_t slot, Cycle at) { r.schedule_slot(at, c, uint32_t(slot)); }
        void idle(size_t slot, Cycle t, bool retired) {
            r.cores_[c]->set_slot_idle(slot, t, retired);
            if (!retired) r.parked_.emplace_back(c, uint32_t(slot));
            r.take_wakes(t);
        }
        void work_changed(Cycle t) { r.take_wakes(t); }
        void records_written(Cycle t) { r.post_record_writes(c, t); }
        // Each load is a generation of kLoad stages; a newer load drops an older one's.
        void start_loader(Cycle t) { r.schedule_load(t, c, ++r.states_[c].load_generation); }
        void loader_ready(Cycle at) {
            if (at != kNeverCycle) r.schedule_load(at, c, r.states_[c].load_generation);
        }
        // A line that would miss while every MSHR it takes is busy waits for one to free.
        bool load_line(size_t kind, Cache* cache, uint64_t addr, uint32_t bytes, Cycle t) {
            if (!cache->may_load(addr, &r, kLoad, c, r.states_[c].load_generation)) return false;
            r.send(r.cores_[c]->memory_socket[kind],
                   r.request(tlm::TLM_READ_COMMAND, addr, bytes, t, kForNothing, c), t);
            return true;
        }
        // Records in memory: read through the level below, each stage at its cycle.
        bool read_record(size_t slot, Cycle from) {
            RayBuffer* rb = r.cores_[c]->ray_buffer();
            if (!rb->params().in_memory || !rb->has_memory()) return false;
            r.read_local(c, uint32_t(slot), rb->record_address(r.cores_[c]->slot_handle(slot)),
                         rb->params().ray_bytes, from, kForRecord);
            return true;
        }
        bool write_entry_busy(size_t slot, Cycle t) {
            if (!r.write_buffer_full(c)) return false;
            r.wait_for_write_buffer(c, uint32_t(slot), t);
            return true;
        }
        void post_write(uint64_t addr, uint32_t bytes, Cycle t) {
            r.post_core_write(c, addr, bytes, t);
        }
        void read_stack(size_t slot, uint64_t addr, uint32_t bytes, Cycle t) {
            r.read_local(c, uint32_t(slot), addr, bytes, t, kForStack);
        }
        // The fetch reaches the step's memory at the cycle it is issued, after what that memory
        // already has at that cycle (queued); answered(), resumes the slot.
        void fetch(size_t slot, const Step& st, Cycle issued, Core::Fetch& fetch) {
            tlm::tlm_generic_payload& gp = r.request(tlm::TLM_READ_COMMAND, st.addr, st.size_bytes,
                                                     issued, kForStep, c, uint32_t(slot));
            memory_request(gp).queued = true;
            r.send(r.cores_[c]->memory_socket[size_t(st.kind)], gp, issued);
            fetch.kind = Core::Fetch::kPending;
        }
    };

    void run_cycle();
    void run_stage(uint32_t kind, uint32_t id, uint32_t k, Cycle t) override {
        if (kind == kSlot) {
            TimeOrdered engine{*this, id};
            cores_[id]->run_slot(k, t, engine);
        } else {
            load_line(id, k, t);
        }
    }
    // Within a cycle, slots run by core and slot (the fast model's arbitration).
    void schedule_slot(Cycle t, uint32_t c, uint32_t i) {
        stages_.schedule(t, StageQueue::kSlotOrder + slot_rank_[c] + i, this, kSlot, c, i);
    }
    void schedule_load(Cycle t, uint32_t c, uint32_t generation) {
        stages_.schedule(t, StageQueue::kMemoryOrder, this, kLoad, c, generation);
    }
    tlm::tlm_generic_payload& request(tlm::tlm_command command, uint64_t addr, uint32_t size,
                                      Cycle t, Purpose purpose, uint32_t c, uint32_t k = 0) {
        tlm::tlm_generic_payload& gp = payloads_.acquire(command, addr, size, t);
        MemoryRequest& r = memory_request(gp);
        r.owner_kind = purpose;
        r.owner_id = c;
        r.owner_k = k;
        return gp;
    }
    // BEGIN_REQ through `socket`, reaching its block at t.
    tlm::tlm_sync_enum send(InitiatorSocket<Core>& socket, tlm::tlm_generic_payload& gp, Cycle t) {
        if (t < stages_.now())
            throw std::logic_error("accurate fidelity: a request sent before the current cycle");
        tlm::tlm_phase phase = tlm::BEGIN_REQ;
        sc_core::sc_time delay = cycles_delay(t - stages_.now());
        return socket->nb_transport_fw(gp, phase, delay);
    }
    void answered(tlm::tlm_generic_payload& gp) override;
    void load_line(uint32_t c, uint32_t generation, Cycle t);
    void take_wakes(Cycle t);
    // Core c's write buffer (core.write_buffer_entries; 0: unbounded).
    bool write_buffer_full(uint32_t c) const {
        const uint32_t n = cores_[c]->params().write_buffer_entries;
        return n > 0 && states_[c].writes_in_flight >= n;
    }
    void wait_for_write_buffer(uint32_t c, uint32_t i, Cycle t) {
        states_[c].write_wait_from[i] = t;
        states_[c].write_waiters.push_back(i);
    }
    void post_core_write(uint32_t c, uint64_t addr, uint32_t size, Cycle t);
    void write_accepted(uint32_t c, Cycle t);
    // A read below core c's L1s (a stack refill or a ray record) that slot i waits for.
    void read_local(uint32_t c, uint32_t i, uint64_t addr, uint32_t size, Cycle t,
                    Purpose purpose) {
        send(cores_[c]->local_socket, request(tlm::TLM_READ_COMMAND, addr, size, t, purpose, c, i),
             t);
    }
    void post_record_writes(uint32_t c, Cycle t);

    std::vector<Core*> cores_;
    WakeSource* wake_;
    StageQueue& stages_;
    PayloadPool payloads_;
    std::vector<CoreState> states_;
    std::vector<uint64_t> slot_rank_;  // per core: the rank of its first slot among all slots
    std::vector<std::pair<uint32_t, uint32_t>> parked_;  // core, slot
    double host_busy_seconds_ = 0;
    bool started_ = false;
};

// The SystemC kernel runs the engine cycle by cycle: at each cycle with stages, the kernel's time
// is that cycle's, its stages run in their order, and the method is triggered again at the next
// cycle with stages. Other SystemC processes (an outside target's, progress reports) therefore
// see the chip at its own time.
void ReferenceScheduler::run_cycle() {
    const auto resumed = std::chrono::steady_clock::now();
    if (!started_) {
        started_ = true;
        for (uint32_t c = 0; c < cores_.size(); ++c)
            for (uint32_t i = 0; i < uint32_t(cores_[c]->params().ray_slots); ++i)
                schedule_slot(0, c, i);
    }
    if (stages_.empty()) return;
    const Cycle cycle = stages_.next_cycle();
    if (sc_core::sc_time_stamp().value() != cycle * kTimeUnitsPerCycle)
        throw std::logic_error("accurate fidelity: stages ran apart from the kernel's time");
    while (!stages_.empty() && stages_.next_cycle() == cycle) stages_.run_next();
    if (!stages_.empty()) next_trigger(cycles_delay(stages_.next_cycle() - cycle));
    host_busy_seconds_ +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - resumed).count();
}

// An answer through a core's socket, at the current cycle.
void ReferenceScheduler::answered(tlm::tlm_generic_payload& gp) {
    const Cycle t = stages_.now();
    const MemoryRequest& r = memory_request(gp);
    const uint32_t c = r.owner_id, i = r.owner_k;
    switch (Purpose(r.owner_kind)) {
        case kForStep: {
            Cycle by_level[kMemLevels] = {0, 0, 0, 0};
            r.timeline.charge(by_level);
            payloads_.release(gp);
            TimeOrdered engine{*this, c};
            cores_[c]->step_fetched(i, t, by_level, engine);
            return;
        }
        case kForStack:
            cores_[c]->stall_cycles[Core::kStack] += t - r.start;
            schedule_slot(t, c, i);
            break;
        case kForRecord:  // the ray's wait from taking the slot to its record's arrival
            cores_[c]->stall_cycles[Core::kRayBuffer] += t - cores_[c]->slot_start(i);
            schedule_slot(t, c, i);
            break;
        case kForWrite:
            if (i) write_accepted(c, t);
            break;
        case kForNothing:
            break;
    }
    payloads_.release(gp);
}

// Work arrived in the ray buffer for parked slots: they look again from then.
void ReferenceScheduler::take_wakes(Cycle t) {
    Cycle at;
    if (!wake_ || !wake_->take_wake(at)) return;
    at = std::max(at, t);
    for (const auto& [c, i] : parked_) {
        cores_[c]->no_work_cycles += at - std::min(at, cores_[c]->slot_idle_since(i));
        schedule_slot(at, c, i);
    }
    parked_.clear();
}

void ReferenceScheduler::load_line(uint32_t c, uint32_t generation, Cycle t) {
    if (generation != states_[c].load_generation) return;  // replaced by a newer load
    TimeOrdered engine{*this, c};
    cores_[c]->run_loader(t, engine);
}

// A core's posted write takes a write-buffer entry until the level below has accepted it (a
// level that takes it within the call, as ideal memory does, holds none).
void ReferenceScheduler::post_core_write(uint32_t c, uint64_t addr, uint32_t size, Cycle t) {
    const bool entry = cores_[c]->params().write_buffer_entries > 0;
    tlm::tlm_generic_payload& gp =
        request(tlm::TLM_WRITE_COMMAND, addr, size, t, kForWrite, c, entry);
    memory_request(gp).queued = true;
    if (entry) ++states_[c].writes_in_flight;
    if (send(cores_[c]->local_socket, gp, t) == tlm::TLM_COMPLETED) {
        payloads_.release(gp);
        if (entry) --states_[c].writes_in_flight;
    }
}

// Core c's write was accepted at t: its entry goes to the first slot waiting for one.
void ReferenceScheduler::write_accepted(uint32_t c, Cycle t) {
    CoreState& cs = states_[c];
    --cs.writes_in_flight;
    if (cs.write_waiters.empty()) return;
    const uint32_t i = cs.write_waiters.front();
    cs.write_waiters.pop_front();
    cores_[c]->stall_cycles[Core::kWriteBuffer] += t - cs.write_wait_from[i];
    schedule_slot(t, c, i);
}

// Ray records the buffer wrote (admissions, crossings) go to memory as posted writes, below the
// L1s of the core that caused them (RayBuffer::memory is that level).
void ReferenceScheduler::post_record_writes(uint32_t c, Cycle t) {
    RayBuffer* rb = cores_[c]->ray_buffer();
    if (!rb || rb->deferred_writes().empty()) return;
    for (const uint64_t addr : rb->deferred_writes()) {
        tlm::tlm_generic_payload& gp =
            request(tlm::TLM_WRITE_COMMAND, addr, rb->params().ray_bytes, t, kForNothing, c);
        memory_request(gp).queued = true;
        if (send(cores_[c]->local_socket, gp, t) == tlm::TLM_COMPLETED) payloads_.release(gp);
    }
    rb->deferred_writes().clear();
}

std::unique_ptr<ChipDriver> make_accurate(const char* module_name, const DriverSetup& setup) {
    return std::make_unique<ReferenceScheduler>(module_name, setup);
}

}  // namespace

RTSIM_REGISTER(FidelityEntry,
               {"accurate",
                "the time-ordered reference: every stage of every request runs at its own cycle "
                "from one event queue, so every shared resource serves in time order",
                {},
                &make_accurate})

}  // namespace rtsim

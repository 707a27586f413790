// sim.fidelity = accurate: the time-ordered reference timing model.
//
// One event queue holds every stage of every request, ordered by cycle: a ray slot's next
// action, a request arriving at a cache (its banks), each line's tag check at its lookup cycle,
// a miss taking an MSHR (or queueing for one, first come first served), each DRAM stage, a line
// crossing the crossbar when the L2 returns it, a fill completing (which frees its MSHR and
// wakes every request merged on it), a fetched step's unit operation. Each stage calls its block
// at the cycle it happens, so every bank, MSHR pool, bus, link, unit and port sees its requests
// in simulated-time order by construction: the out-of-order counts of stats.json are 0 here
// (tests check it). Within one cycle, fills complete before new requests are served (a line
// arriving at cycle t is there for a lookup at t, as the fast model has it), then events run
// in the order they were scheduled.
//
// It drives the same blocks as the fast model (their counters, calendars used in order, tag
// stores and replacement policies, report sections) and the same ray-slot state machine
// (Core::run_slot, models/core_slots.h: its TimeOrdered engine makes each slot action an event);
// it keeps what only a time-ordered model needs itself: fills in flight with their waiting
// requests, MSHR queues, and each request's timeline (which level held it over which cycles), from
// which stalls are charged exactly. Waiting on another request's fill is charged to where that fill
// was at each cycle.
#include <chrono>
#include <deque>
#include <queue>
#include <stdexcept>
#include <unordered_map>
#include <vector>

#include "models/cache.h"
#include "models/core.h"
#include "models/core_slots.h"
#include "models/crossbar.h"
#include "models/dram.h"
#include "models/fidelity.h"
#include "models/ray_buffer.h"
#include "models/unit.h"

namespace rtsim {
namespace {

// A request's life from `start`, as consecutive parts each charged to one memory level.
struct Timeline {
    static constexpr int kMaxParts = 12;
    struct Part {
        Cycle end;
        int level;
    };
    Cycle start = 0;
    int parts = 0;
    Part part[kMaxParts];

    Timeline() = default;
    explicit Timeline(Cycle from) : start(from) {}
    Cycle end() const { return parts ? part[parts - 1].end : start; }
    // Extends the timeline to `until`, the new cycles charged to `level`.
    void add(Cycle until, int level) {
        if (until <= end()) return;
        if (parts > 0 && part[parts - 1].level == level) {
            part[parts - 1].end = until;
            return;
        }
        // A request passes each level at most a few times (a wait on a fill adds that fill's
        // levels): running out means the model went around in a circle.
        if (parts == kMaxParts)
            throw std::logic_error("accurate fidelity: a request's timeline overflowed");
        part[parts++] = {until, level};
    }
    // Appends `other`'s parts from `from` to `until` (the cycles this request waited on it).
    void add_overlap(const Timeline& other, Cycle from, Cycle until) {
        Cycle lo = other.start;
        for (int p = 0; p < other.parts; ++p) {
            const Cycle hi = other.part[p].end;
            if (hi > from && lo < until) add(std::min(hi, until), other.part[p].level);
            lo = hi;
        }
        // Past the fill's recorded end (never, as fills end when their waiters do).
        add(until, other.parts ? other.part[other.parts - 1].level : kLevelL1);
    }
    void charge(uint64_t* cycles_by_level) const {
        Cycle lo = start;
        for (int p = 0; p < parts; ++p) {
            cycles_by_level[part[p].level] += part[p].end - lo;
            lo = part[p].end;
        }
    }
};

// The cache whose MSHRs a miss of `cache` takes: its own, or, for a cache with unlimited MSHRs in
// front of another of its level (a treelet cache before its L1), that one's; nullptr: unlimited.
Cache* limiting_cache(Cache* cache) {
    while (cache && cache->params().mshrs == 0) {
        auto* next = dynamic_cast<Cache*>(cache->next_level());
        cache = next && next->level() == cache->level() ? next : nullptr;
    }
    return cache;
}

class ReferenceScheduler final : public ChipDriver {
  public:
    SC_HAS_PROCESS(ReferenceScheduler);
    ReferenceScheduler(sc_core::sc_module_name name, const DriverSetup& setup)
        : ChipDriver(name), cores_(setup.cores), wake_(setup.wake) {
        uint64_t slots = 0;
        for (Core* core : cores_) {
            slot_rank_.push_back(slots);
            slots += uint64_t(core->params().ray_slots);
            CoreState cs;
            cs.write_wait_from.resize(size_t(core->params().ray_slots));
            states_.push_back(std::move(cs));
            loaders_ = loaders_ || (core->ray_buffer() && core->params().treelet_prefetch);
            // Ray records in memory: read and written here, each stage at its cycle.
            if (RayBuffer* rb = core->ray_buffer(); rb && rb->params().in_memory)
                rb->set_memory(rb->memory(), true);
        }
        SC_THREAD(run);
    }
    double host_busy_seconds() const override { return host_busy_seconds_; }
    const TimeFloor* shared_floor() const override { return &now_; }
    const TimeFloor* private_floor(size_t) const override { return &now_; }

  private:
    enum EventType : uint8_t {
        kSlot,
        kArrive,
        kTag,
        kFillDone,
        kDram,
        kIdealDone,
        kLoad,
        kWriteArrive,  // a posted write reaches its cache
        kWriteTag,     // one of its lines is looked up
        kDramWrite     // a write's next stage in DRAM
    };
    // Within a cycle: fills complete first, then other memory stages, then ray slots by core and
    // slot (the fast model's arbitration: at equal cycles the lower core, then the lower slot,
    // takes the next ray), each group first scheduled first.
    struct Event {
        Cycle t;
        uint64_t order;  // 0: a fill completing; 1: another memory stage; 2 + slot rank: a slot
        uint64_t seq;
        EventType type;
        uint32_t id, k;
        bool operator>(const Event& o) const {
            if (t != o.t) return t > o.t;
            if (order != o.order) return order > o.order;
            return seq > o.seq;
        }
    };
    void schedule(Cycle t, EventType type, uint32_t id, uint32_t k = 0) {
        uint64_t order = type == kFillDone ? 0 : 1;
        if (type == kSlot) order = 2 + slot_rank_[id] + k;
        events_.push(Event{t, order, seq_++, type, id, k});
    }

    // What a memory request's completion goes to.
    // kForStack: a stack refill a slot waits for; kForWrite: a posted write nobody waits for.
    // kForRecord: a ray record a slot reads from memory (queues in memory).
    enum WaiterKind : uint8_t { kForStep, kForFill, kForNothing, kForStack, kForWrite, kForRecord };
    struct Access {
        MemoryPort* node = nullptr;
        uint64_t addr = 0;
        uint32_t size_bytes = 0;
        WaiterKind for_kind = kForNothing;
        uint32_t a = 0, b = 0;          // kForStep: core, slot; kForFill: the fill
        Crossbar* via = nullptr;        // a fill's request through the crossbar
        uint32_t write_entry_core = 0;  // a core's posted write: 1 + the core whose entry it holds
        Cycle start = 0;
        uint64_t first_line = 0;
        uint32_t lines_left = 0;
        uint64_t pending_lines = 0;  // lines counted in their cache's pending_misses (bit k)
        // The slowest line so far (the first of equals), and its timeline.
        bool any = false;
        Cycle done = 0;
        uint64_t slowest_k = 0;
        Timeline timeline;
    };
    struct Waiter {
        uint32_t access;
        uint32_t k;  // its line
        Cycle from;  // when its tag check found the line still filling
    };
    struct Fill {
        Cache* cache = nullptr;
        uint32_t cache_state = 0;
        uint64_t line = 0;
        Cycle requested = 0;  // the miss's tag check: it asks for an MSHR then
        Timeline timeline;    // from `requested` to the data's arrival
        std::vector<Waiter> waiters;
        DramRequest dram;
    };
    struct CacheState {
        std::unordered_map<uint64_t, uint32_t> in_flight;  // line -> its newest fill
        uint32_t mshrs = 0;                                // 0: unlimited
        uint32_t busy = 0;
        // Lines of requests that have arrived and not yet been looked up, absent when they
        // arrived: misses to come, each of which will take an MSHR. A treelet loader counts
        // them as taken (the fast engine books a miss's MSHR when it is issued), so that it
        // never queues behind its own lines still in the lookup pipeline.
        uint32_t pending_misses = 0;
        std::deque<uint32_t> waiting;  // fills waiting for an MSHR, first come first served
        // Treelet loaders (core, load generation) waiting for a free MSHR.
        std::vector<std::pair<uint32_t, uint32_t>> loaders;
    };
    struct DramWrite {
        DramModel* dram = nullptr;
        DramRequest request;
    };
    // What the engine keeps per core beside the core's own slots.
    struct CoreState {
        std::vector<Cycle> write_wait_from;  // per slot: when it began waiting for a write entry
        // The treelet load in progress (Core::run_loader): its kLoad events' generation.
        uint32_t load_generation = 0;
        // Write-buffer entries held by posted writes not yet accepted, and slots waiting for one.
        uint32_t writes_in_flight = 0;
        std::deque<uint32_t> write_waiters;
    };

    // The core's side of the time-ordered engine: each slot action is an event at its cycle,
    // each request a chain of stage events whose completion resumes the slot.
    struct TimeOrdered {
        static constexpr bool kTimeOrdered = true;
        ReferenceScheduler& r;
        uint32_t c;

        bool beyond(Cycle) const { return false; }
        void ready(size_t slot, Cycle at) { r.schedule(at, kSlot, c, uint32_t(slot)); }
        void idle(size_t slot, Cycle t, bool retired) {
            r.cores_[c]->set_slot_idle(slot, t, retired);
            if (!retired) r.parked_.emplace_back(c, uint32_t(slot));
            r.take_wakes(t);
        }
        void work_changed(Cycle t) { r.take_wakes(t); }
        void records_written(Cycle t) { r.post_record_writes(r.cores_[c]->ray_buffer(), t); }
        // Each load is a generation of kLoad events; a newer load drops an older one's.
        void start_loader(Cycle t) { r.schedule(t, kLoad, c, ++r.states_[c].load_generation); }
        void loader_ready(Cycle at) {
            if (at != kNeverCycle) r.schedule(at, kLoad, c, r.states_[c].load_generation);
        }
        // A line that would miss while every MSHR it takes is busy waits for one to free.
        bool load_line(Cache* cache, uint64_t addr, uint32_t bytes, Cycle t) {
            if (!cache->contains(addr)) {
                if (Cache* limit = limiting_cache(cache)) {
                    CacheState& st = r.caches_[r.cache_state(limit)];
                    if (st.busy + st.pending_misses >= st.mshrs) {
                        st.loaders.emplace_back(c, r.states_[c].load_generation);
                        return false;
                    }
                }
            }
            r.arrive(r.new_access(cache, addr, bytes, t), t);
            return true;
        }
        // Records in memory: read through the level below, each stage at its cycle.
        bool read_record(size_t slot, Cycle from) {
            RayBuffer* rb = r.cores_[c]->ray_buffer();
            if (!rb->params().in_memory || !rb->memory()) return false;
            r.read_local(c, uint32_t(slot), rb->memory(),
                         rb->record_address(r.cores_[c]->slot_handle(slot)), rb->params().ray_bytes,
                         from, kForRecord);
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
            r.read_local(c, uint32_t(slot), r.cores_[c]->local_memory(), addr, bytes, t, kForStack);
        }
        void fetch(size_t slot, const Step& st, Cycle issued, Core::Fetch& fetch) {
            const uint32_t a =
                r.new_access(r.cores_[c]->memory(int(st.kind)), st.addr, st.size_bytes, issued);
            Access& A = r.accesses_[a];
            A.for_kind = kForStep;
            A.a = c;
            A.b = uint32_t(slot);
            r.schedule(issued, kArrive, a);
            fetch.kind = Core::Fetch::kPending;  // access_done resumes the slot
        }
    };

    void run();
    void slot_ready(uint32_t c, uint32_t i, Cycle t) {
        TimeOrdered engine{*this, c};
        cores_[c]->run_slot(i, t, engine);
    }
    void load_line(uint32_t c, uint32_t generation, Cycle t);
    void take_wakes(Cycle t);
    uint32_t new_access(MemoryPort* node, uint64_t addr, uint32_t size, Cycle start);
    void arrive(uint32_t a, Cycle t);
    void tag(uint32_t a, uint32_t k, Cycle t);
    uint32_t new_fill(Cache* cache, uint32_t cs, uint64_t line, Cycle t);
    void issue_fill(uint32_t f, Cycle t);
    void count_pending_misses(Cache* cache, Access& A);
    void wake_loaders(CacheState& st, Cycle t) {
        for (const auto& [core, generation] : st.loaders) schedule(t, kLoad, core, generation);
        st.loaders.clear();
    }
    void prefetch(Cache* cache, uint32_t cs, uint64_t line, Cycle t);
    void dram_stage(uint32_t f, Cycle t);
    void fill_done(uint32_t f, Cycle t);
    void line_done(uint32_t a, uint64_t k, Cycle t, const Timeline& timeline);
    void access_done(uint32_t a, Cycle t);
    uint32_t cache_state(Cache* cache);
    // The traversal's own traffic through a core's local memory (below its L1s).
    // A write with no entry to free (ray records, write-backs), or holding core c's (entry_core
    // 1 + c).
    void post_write(MemoryPort* port, uint64_t addr, uint32_t size, Cycle t,
                    uint32_t entry_core = 0);
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
    void write_arrive(uint32_t a, Cycle t);
    void write_tag(uint32_t a, uint32_t k, Cycle t);
    void start_dram_write(MemoryPort* dram, uint64_t addr, uint32_t size, Cycle t);
    void dram_write_stage(uint32_t w, Cycle t);
    void send_writebacks(Cache* cache, Cycle t);
    // A read through `port` (a core's local memory) that slot i of core c waits for.
    void read_local(uint32_t c, uint32_t i, MemoryPort* port, uint64_t addr, uint32_t size, Cycle t,
                    WaiterKind why);
    void post_record_writes(RayBuffer* rb, Cycle t);
    // A fresh record from a pool of them (reusing a freed one when there is one).
    template <typename T>
    static uint32_t take(std::vector<T>& pool, std::vector<uint32_t>& free) {
        if (free.empty()) {
            pool.emplace_back();
            return uint32_t(pool.size() - 1);
        }
        const uint32_t i = free.back();
        free.pop_back();
        pool[i] = T{};
        return i;
    }

    std::vector<Core*> cores_;
    WakeSource* wake_;
    std::vector<CoreState> states_;
    std::vector<uint64_t> slot_rank_;  // per core: the rank of its first slot among all slots
    std::vector<std::pair<uint32_t, uint32_t>> parked_;  // core, slot
    std::priority_queue<Event, std::vector<Event>, std::greater<Event>> events_;
    uint64_t seq_ = 0;
    TimeFloor now_;  // every block's floor: nothing is ever requested before the current event
    std::vector<Access> accesses_;
    std::vector<uint32_t> free_accesses_;
    std::vector<Fill> fills_;
    std::vector<uint32_t> free_fills_;
    std::vector<CacheState> caches_;
    std::vector<DramWrite> dram_writes_;
    std::vector<uint32_t> free_dram_writes_;
    std::unordered_map<const Cache*, uint32_t> cache_index_;
    std::vector<Cycle> lookup_scratch_;
    std::vector<uint64_t> prefetch_lines_;
    double host_busy_seconds_ = 0;
    bool loaders_ = false;  // a core may load treelets (pending misses are counted)
};

uint32_t ReferenceScheduler::cache_state(Cache* cache) {
    auto it = cache_index_.find(cache);
    if (it != cache_index_.end()) return it->second;
    CacheState st;
    st.mshrs = uint32_t(std::max(0, cache->params().mshrs));
    caches_.push_back(std::move(st));
    return cache_index_[cache] = uint32_t(caches_.size() - 1);
}

uint32_t ReferenceScheduler::new_access(MemoryPort* node, uint64_t addr, uint32_t size,
                                        Cycle start) {
    const uint32_t a = take(accesses_, free_accesses_);
    Access& A = accesses_[a];
    A.node = node;
    A.addr = addr;
    A.size_bytes = size;
    A.start = start;
    A.timeline = Timeline(start);
    return a;
}

void ReferenceScheduler::run() {
    for (uint32_t c = 0; c < cores_.size(); ++c)
        for (uint32_t i = 0; i < uint32_t(cores_[c]->params().ray_slots); ++i)
            schedule(0, kSlot, c, i);
    auto resumed = std::chrono::steady_clock::now();
    Cycle kernel_cycle = 0;
    while (!events_.empty()) {
        const Event e = events_.top();
        events_.pop();
        now_.cycle = e.t;
        if (e.t >= kernel_cycle + CoreScheduler::kKernelSyncCycles) {
            host_busy_seconds_ +=
                std::chrono::duration<double>(std::chrono::steady_clock::now() - resumed).count();
            wait(cycles_to_time(e.t - kernel_cycle));
            resumed = std::chrono::steady_clock::now();
            kernel_cycle = e.t;
        }
        switch (e.type) {
            case kSlot:
                slot_ready(e.id, e.k, e.t);
                break;
            case kArrive:
                arrive(e.id, e.t);
                break;
            case kTag:
                tag(e.id, e.k, e.t);
                break;
            case kFillDone:
                fill_done(e.id, e.t);
                break;
            case kDram:
                dram_stage(e.id, e.t);
                break;
            case kLoad:
                load_line(e.id, e.k, e.t);
                break;
            case kWriteArrive:
                write_arrive(e.id, e.t);
                break;
            case kWriteTag:
                write_tag(e.id, e.k, e.t);
                break;
            case kDramWrite:
                dram_write_stage(e.id, e.t);
                break;
            case kIdealDone: {
                Timeline tl(accesses_[e.id].start);
                tl.add(e.t, kLevelL1);
                line_done(e.id, 0, e.t, tl);
                break;
            }
        }
    }
    host_busy_seconds_ +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - resumed).count();
}

// Work arrived in the ray buffer for parked slots: they look again from then.
void ReferenceScheduler::take_wakes(Cycle t) {
    Cycle at;
    if (!wake_ || !wake_->take_wake(at)) return;
    at = std::max(at, t);
    for (const auto& [c, i] : parked_) {
        cores_[c]->no_work_cycles += at - std::min(at, cores_[c]->slot_idle_since(i));
        schedule(at, kSlot, c, i);
    }
    parked_.clear();
}

void ReferenceScheduler::load_line(uint32_t c, uint32_t generation, Cycle t) {
    if (generation != states_[c].load_generation) return;  // replaced by a newer load
    TimeOrdered engine{*this, c};
    cores_[c]->run_loader(t, engine);
}

// A core's posted write takes a write-buffer entry until the cache below has looked it up.
void ReferenceScheduler::post_core_write(uint32_t c, uint64_t addr, uint32_t size, Cycle t) {
    MemoryPort* port = cores_[c]->local_memory();
    const bool to_cache = dynamic_cast<Crossbar*>(port) || dynamic_cast<Cache*>(port);
    if (to_cache && cores_[c]->params().write_buffer_entries > 0) {
        ++states_[c].writes_in_flight;
        post_write(port, addr, size, t, c + 1);
        return;
    }
    post_write(port, addr, size, t);
}

// Core c's write was accepted at t: its entry goes to the first slot waiting for one.
void ReferenceScheduler::write_accepted(uint32_t c, Cycle t) {
    CoreState& cs = states_[c];
    --cs.writes_in_flight;
    if (cs.write_waiters.empty()) return;
    const uint32_t i = cs.write_waiters.front();
    cs.write_waiters.pop_front();
    cores_[c]->stall_cycles[Core::kWriteBuffer] += t - cs.write_wait_from[i];
    schedule(t, kSlot, c, i);
}

// A posted write from t: across the crossbar's write link, then into the cache below (or DRAM).
void ReferenceScheduler::post_write(MemoryPort* port, uint64_t addr, uint32_t size, Cycle t,
                                    uint32_t entry_core) {
    if (auto* xbar = dynamic_cast<Crossbar*>(port)) {
        t = xbar->carry_up(t, size);
        port = xbar->next_level();
    }
    if (auto* cache = dynamic_cast<Cache*>(port)) {
        const uint32_t a = new_access(cache, addr, size, t);
        accesses_[a].for_kind = kForWrite;
        accesses_[a].write_entry_core = entry_core;
        schedule(t, kWriteArrive, a);
        return;
    }
    if (dynamic_cast<DramModel*>(port)) start_dram_write(port, addr, size, t);
    // Ideal memory: nothing below to write to.
}

void ReferenceScheduler::write_arrive(uint32_t a, Cycle t) {
    Access& A = accesses_[a];
    auto* cache = static_cast<Cache*>(A.node);
    A.first_line = cache->arrive_write(A.addr, A.size_bytes, t, lookup_scratch_);
    A.lines_left = uint32_t(lookup_scratch_.size());
    for (uint32_t k = 0; k < lookup_scratch_.size(); ++k)
        schedule(lookup_scratch_[k], kWriteTag, a, k);
}

void ReferenceScheduler::write_tag(uint32_t a, uint32_t k, Cycle t) {
    Access& A = accesses_[a];
    auto* cache = static_cast<Cache*>(A.node);
    cache->write_tag(A.first_line + k, t);
    send_writebacks(cache, t);
    if (--A.lines_left > 0) return;
    // Write-through: on to the next level once every line is looked up (as the fast model).
    if (!cache->params().write_back && cache->next_level())
        start_dram_write(cache->next_level(), A.addr, A.size_bytes, t);
    const uint32_t entry_core = A.write_entry_core;
    free_accesses_.push_back(a);
    if (entry_core) write_accepted(entry_core - 1, t);
}

// Dirty lines the cache evicted (on a write's allocation or a miss's fill) go to DRAM.
void ReferenceScheduler::send_writebacks(Cache* cache, Cycle t) {
    std::vector<uint64_t>& lines = cache->queued_writebacks();
    for (const uint64_t line : lines)
        start_dram_write(cache->next_level(), cache->line_address(line), cache->params().line_bytes,
                         t);
    lines.clear();
}

void ReferenceScheduler::start_dram_write(MemoryPort* port, uint64_t addr, uint32_t size, Cycle t) {
    auto* dram = dynamic_cast<DramModel*>(port);
    if (!dram) throw std::logic_error("accurate fidelity: a write below the L2 that is not DRAM");
    const uint32_t w = take(dram_writes_, free_dram_writes_);
    dram_writes_[w].dram = dram;
    DramRequest& r = dram_writes_[w].request;
    r.addr = addr;
    r.size_bytes = size;
    r.write = true;
    dram_write_stage(w, t);
}

void ReferenceScheduler::dram_write_stage(uint32_t w, Cycle t) {
    bool done = false;
    const Cycle next = dram_writes_[w].dram->advance(dram_writes_[w].request, t, done);
    if (done)
        free_dram_writes_.push_back(w);
    else
        schedule(next, kDramWrite, w);
}

// Ray records the buffer wrote (admissions, crossings) go to memory as posted writes.
void ReferenceScheduler::post_record_writes(RayBuffer* rb, Cycle t) {
    if (!rb || rb->deferred_writes().empty()) return;
    for (const uint64_t addr : rb->deferred_writes())
        post_write(rb->memory(), addr, rb->params().ray_bytes, t);
    rb->deferred_writes().clear();
}

// A stack refill or a ray record: the slot goes on once it is back.
void ReferenceScheduler::read_local(uint32_t c, uint32_t i, MemoryPort* port, uint64_t addr,
                                    uint32_t size, Cycle t, WaiterKind why) {
    Crossbar* via = dynamic_cast<Crossbar*>(port);
    const uint32_t a = new_access(via ? via->next_level() : port, addr, size, t);
    Access& A = accesses_[a];
    A.for_kind = why;
    A.a = c;
    A.b = i;
    A.via = via;
    arrive(a, t);
}

// A request reaches its block at t.
void ReferenceScheduler::arrive(uint32_t a, Cycle t) {
    Access& A = accesses_[a];
    if (A.size_bytes == 0) {  // reads nothing (an any-hit shader without alpha data): done now
        A.lines_left = 1;
        schedule(t, kIdealDone, a);
        return;
    }
    if (auto* cache = dynamic_cast<Cache*>(A.node)) {
        A.first_line = cache->arrive(A.addr, A.size_bytes, t, lookup_scratch_);
        A.lines_left = uint32_t(lookup_scratch_.size());
        if (loaders_) count_pending_misses(cache, A);
        for (uint32_t k = 0; k < lookup_scratch_.size(); ++k)
            schedule(lookup_scratch_[k], kTag, a, k);
        return;
    }
    // Ideal memory (the cores' only memory): the L1 hit latency, nothing shared.
    A.lines_left = 1;
    schedule(A.node->access(A.addr, A.size_bytes, t), kIdealDone, a);
}

// The lines of request A, just arrived at `cache`, that will take an MSHR when looked up
// (CacheState::pending_misses, of the cache whose MSHRs they take): absent here, and, for a
// cache without MSHRs of its own (a treelet cache), absent from the cache behind it as well.
void ReferenceScheduler::count_pending_misses(Cache* cache, Access& A) {
    Cache* limit = limiting_cache(cache);
    if (!limit) return;  // unlimited MSHRs
    CacheState& st = caches_[cache_state(limit)];
    const uint32_t lines = std::min<uint32_t>(A.lines_left, 64);
    for (uint32_t k = 0; k < lines; ++k) {
        const uint64_t addr = cache->line_address(A.first_line + k);
        if (!cache->contains(addr) && (limit == cache || !limit->contains(addr))) {
            A.pending_lines |= uint64_t(1) << k;
            ++st.pending_misses;
        }
    }
}

// Line k of a request is looked up at t.
void ReferenceScheduler::tag(uint32_t a, uint32_t k, Cycle t) {
    Cache* cache = static_cast<Cache*>(accesses_[a].node);
    const uint64_t line = accesses_[a].first_line + k;
    const uint32_t cs = cache_state(cache);
    const bool was_pending = k < 64 && (accesses_[a].pending_lines >> k & 1);
    CacheState* pending_at = nullptr;  // the state it was counted in
    if (was_pending) {
        accesses_[a].pending_lines &= ~(uint64_t(1) << k);
        pending_at = &caches_[cache_state(limiting_cache(cache))];
        --pending_at->pending_misses;
    }
    const bool hit = cache->check_tag(line, t);
    if (!cache->queued_writebacks().empty()) send_writebacks(cache, t);
    if (hit) {
        // A miss that did not come: a loader waiting on it may go on.
        if (pending_at && !pending_at->loaders.empty()) wake_loaders(*pending_at, t);
        auto it = caches_[cs].in_flight.find(line);
        if (it != caches_[cs].in_flight.end()) {  // still filling: wait for it (merged miss)
            ++cache->merged_misses;
            fills_[it->second].waiters.push_back({a, k, t});
            return;
        }
        Timeline tl(accesses_[a].start);
        tl.add(t, cache->level());
        line_done(a, k, t, tl);
        return;
    }
    const uint32_t f = new_fill(cache, cs, line, t);
    fills_[f].waiters.push_back({a, k, t});
    CacheState& st = caches_[cs];
    if (st.mshrs) cache->request_mshr(t);
    if (st.mshrs == 0 || st.busy < st.mshrs) {
        if (st.mshrs) ++st.busy;
        issue_fill(f, t);
    } else {
        st.waiting.push_back(f);
    }
    if (cache->prefetching()) prefetch(cache, cs, line, t);
}

// After a demand miss of `line` at t, the cache's prefetcher's lines (models/prefetcher.h): each
// one not held takes an MSHR free now or is dropped, and is fetched as a fill nobody waits for
// yet.
void ReferenceScheduler::prefetch(Cache* cache, uint32_t cs, uint64_t line, Cycle t) {
    cache->prefetch_candidates(line, prefetch_lines_);
    for (const uint64_t l : prefetch_lines_) {
        CacheState& st = caches_[cs];
        if (cache->contains(cache->line_address(l))) continue;  // held or filling
        if (st.mshrs && st.busy >= st.mshrs) {
            ++cache->prefetches_dropped;
            continue;
        }
        cache->install_prefetch(l, t);
        if (!cache->queued_writebacks().empty()) send_writebacks(cache, t);
        if (st.mshrs) {
            cache->request_mshr(t);
            ++st.busy;
        }
        issue_fill(new_fill(cache, cs, l, t), t);
    }
}

// A fill of `line` into `cache` (its state cs) from its tag check at t, the line's newest in
// flight (an older fill of the line, evicted while filling, ends unseen).
uint32_t ReferenceScheduler::new_fill(Cache* cache, uint32_t cs, uint64_t line, Cycle t) {
    const uint32_t f = take(fills_, free_fills_);
    Fill& F = fills_[f];
    F.cache = cache;
    F.cache_state = cs;
    F.line = line;
    F.requested = t;
    F.timeline = Timeline(t);
    caches_[cs].in_flight[line] = f;
    return f;
}

// A miss holding an MSHR from t asks the next level for its line.
void ReferenceScheduler::issue_fill(uint32_t f, Cycle t) {
    Fill& F = fills_[f];
    Cache* cache = F.cache;
    cache->mshr_wait_cycles += t - F.requested;
    F.timeline.add(t, cache->level());
    const uint32_t line_bytes = cache->params().line_bytes;
    uint64_t addr = F.line;
    for (uint32_t b = line_bytes; b > 1; b >>= 1) addr <<= 1;  // line sizes are powers of two
    MemoryPort* next = cache->next_level();
    if (dynamic_cast<DramModel*>(next)) {
        F.dram = DramRequest{};
        F.dram.addr = addr;
        F.dram.size_bytes = line_bytes;
        dram_stage(f, t);
        return;
    }
    Crossbar* via = dynamic_cast<Crossbar*>(next);
    if (via) next = via->next_level();  // the request crosses at once; its line comes back later
    const uint32_t a = new_access(next, addr, line_bytes, t);
    Access& A = accesses_[a];
    A.for_kind = kForFill;
    A.a = f;
    A.via = via;
    arrive(a, t);
}

void ReferenceScheduler::dram_stage(uint32_t f, Cycle t) {
    Fill& F = fills_[f];
    auto* dram = static_cast<DramModel*>(F.cache->next_level());
    bool done = false;
    const Cycle next = dram->advance(F.dram, t, done);
    if (!done) {
        schedule(next, kDram, f);
        return;
    }
    F.timeline.add(next, kLevelDram);
    schedule(next, kFillDone, f);
}

// A fill's line is there at t: its MSHR goes to the next miss waiting, and every request that
// waited on the line goes on, charged for the wait where the fill was at each cycle.
void ReferenceScheduler::fill_done(uint32_t f, Cycle t) {
    Fill& F = fills_[f];
    CacheState& st = caches_[F.cache_state];
    auto it = st.in_flight.find(F.line);
    if (it != st.in_flight.end() && it->second == f) st.in_flight.erase(it);
    if (st.mshrs) {
        if (!st.waiting.empty()) {
            const uint32_t next = st.waiting.front();
            st.waiting.pop_front();
            issue_fill(next, t);
        } else {
            --st.busy;
            wake_loaders(st, t);
        }
    }
    const int level = F.cache->level();
    std::vector<Waiter> waiters;
    waiters.swap(F.waiters);
    const Timeline fill_timeline = F.timeline;
    free_fills_.push_back(f);
    for (const Waiter& w : waiters) {
        Timeline tl(accesses_[w.access].start);
        tl.add(w.from, level);
        tl.add_overlap(fill_timeline, w.from, t);
        line_done(w.access, w.k, t, tl);
    }
}

void ReferenceScheduler::line_done(uint32_t a, uint64_t k, Cycle t, const Timeline& timeline) {
    Access& A = accesses_[a];
    if (!A.any || t > A.done || (t == A.done && k < A.slowest_k)) {
        A.any = true;
        A.done = t;
        A.slowest_k = k;
        A.timeline = timeline;
    }
    if (--A.lines_left == 0) access_done(a, t);
}

void ReferenceScheduler::access_done(uint32_t a, Cycle t) {
    const Access A = accesses_[a];
    free_accesses_.push_back(a);
    switch (A.for_kind) {
        case kForStep: {
            Cycle by_level[kMemLevels] = {0, 0, 0, 0};
            A.timeline.charge(by_level);
            TimeOrdered engine{*this, A.a};
            cores_[A.a]->step_fetched(A.b, t, by_level, engine);
            break;
        }
        case kForFill: {
            Fill& F = fills_[A.a];
            for (int p = 0; p < A.timeline.parts; ++p)
                F.timeline.add(A.timeline.part[p].end, A.timeline.part[p].level);
            if (A.via) {
                const Cycle end = A.via->carry(t, A.size_bytes);
                F.timeline.add(end, kLevelCrossbar);
                schedule(end, kFillDone, A.a);
            } else {
                fill_done(A.a, t);
            }
            break;
        }
        case kForStack:
        case kForRecord: {
            const Cycle end = A.via ? A.via->carry(t, A.size_bytes) : t;
            if (A.for_kind == kForStack) {
                cores_[A.a]->stall_cycles[Core::kStack] += end - A.start;
            } else {  // the ray's wait from taking the slot to its record's arrival
                cores_[A.a]->stall_cycles[Core::kRayBuffer] += end - cores_[A.a]->slot_start(A.b);
            }
            schedule(end, kSlot, A.a, A.b);
            break;
        }
        case kForNothing:
        case kForWrite:
            break;
    }
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

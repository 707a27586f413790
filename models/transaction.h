// The contract between the cores and the memory blocks (caches, crossbar, DRAM, ideal memory):
// TLM-2.0 generic payloads carrying a MemoryRequest extension, through TLM-2.0 sockets.
//
// The time-ordered engine (sim.fidelity = accurate) drives the blocks with the base protocol's
// non-blocking calls. A requester sends BEGIN_REQ through nb_transport_fw, the delay annotating
// the cycle the request reaches the block (from the StageQueue's current cycle); the block
// answers BEGIN_RESP through nb_transport_bw at the cycle its data is there, with a zero delay:
// the call happens at that cycle. A posted write is answered at the cycle the block accepted it,
// or, when nothing waits for its acceptance below the block, the call returns TLM_COMPLETED.
// Each block runs its own later stages (a tag check at its lookup cycle, a DRAM bank, a line
// crossing the crossbar) as events on the chip's StageQueue, which calls them in cycle order, so
// every bank, MSHR pool, bus and link serves its requests in simulated-time order.
//
// The loosely timed engine (sim.fidelity = fast) drives the same blocks through the same sockets
// with b_transport (LtPort below). The annotated delay places the request at its cycle, counted
// from the kernel's time (the cores' scheduler runs ahead of the kernel, never behind it); the
// block works out the request's whole path below it within the call and returns with the delay
// advanced to the cycle its data is there (a read) or it took the write. The MemoryRequest
// extension carries the same cycles (lt_kernel, lt_at, lt_done), so that no level converts the
// delay. The block's side of this is its MemoryPort (models/timing.h), which
// serve_loosely_timed calls.
#pragma once

#include <tlm_utils/simple_initiator_socket.h>
#include <algorithm>
#include <cstdint>
#include <deque>
#include <memory>
#include <queue>
#include <stdexcept>
#include <tlm>
#include <type_traits>
#include <vector>

#include "models/calendar.h"
#include "models/timing.h"

namespace rtsim {

// A request's life from `start`, as consecutive parts each charged to one memory level (stall
// attribution: a wait on another request's fill is charged where that fill was at each cycle).
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
    // Appends every part of `other` (what a request below took for this one).
    void append(const Timeline& other) {
        for (int p = 0; p < other.parts; ++p) add(other.part[p].end, other.part[p].level);
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

// What a memory request carries besides the generic payload's address, length and command.
struct MemoryRequest : tlm::tlm_extension<MemoryRequest> {
    Cycle start = 0;  // issued: its timeline starts here
    // Arrives as a stage of its target at its cycle (a core's fetch at its issue cycle, a core's
    // posted write), after what the target already has at that cycle, rather than within the
    // call (a miss's fill, a dirty line written back). Every target honours it.
    bool queued = false;
    uint32_t owner_kind = 0, owner_id = 0, owner_k = 0;  // the requester's: what it is for
    // Which level held it over which cycles; in the answer, its slowest line's.
    Timeline timeline;
    // Kept by the cache serving it: its first line, lines not yet done, lines counted as misses
    // to come (bit k), and its slowest line so far (the first of equals).
    uint64_t first_line = 0;
    uint32_t lines_left = 0;
    uint64_t pending_lines = 0;
    bool any = false;
    Cycle done = 0;
    uint64_t slowest_k = 0;
    // The upstream socket each block with several requesters took it from, innermost last.
    static constexpr int kMaxHops = 4;
    int hops = 0;
    int route[kMaxHops] = {};
    // Loosely timed calls only: what kind of call, and where each level adds its cycles.
    enum class Lt : uint8_t {
        kTimed,      // MemoryPort::access or write
        kLocalOnly,  // MemoryPort::access_local: TLM_INCOMPLETE_RESPONSE if it cannot
        kWarm,       // MemoryPort::warm or warm_write: no time, nothing counted
    };
    Lt lt = Lt::kTimed;
    AccessBreakdown* breakdown = nullptr;
    // A loosely timed call's cycles, beside the annotated delay that says the same: the kernel's
    // cycle the delay counts from, the request's cycle (kernel + delay), and, on return, the
    // cycle the target was done. Every level reads and writes them instead of converting the
    // delay (a division and a floating-point product per level and direction).
    Cycle lt_kernel = 0, lt_at = 0, lt_done = 0;

    // A fresh request issued at `start` (route and timeline parts left as they were: unused).
    void reset(Cycle issued) {
        start = issued;
        queued = false;
        owner_kind = owner_id = owner_k = 0;
        timeline.start = issued;
        timeline.parts = 0;
        first_line = pending_lines = slowest_k = 0;
        lines_left = 0;
        any = false;
        done = 0;
        hops = 0;
    }
    void push_route(int id) {
        if (hops == kMaxHops) throw std::logic_error("memory request: too many routing hops");
        route[hops++] = id;
    }
    int pop_route() { return route[--hops]; }

    tlm::tlm_extension_base* clone() const override { return new MemoryRequest(*this); }
    void copy_from(const tlm::tlm_extension_base& other) override {
        *this = static_cast<const MemoryRequest&>(other);
    }
};

// Every payload in the chip's memory path comes from a PayloadPool: a generic payload that also
// keeps its MemoryRequest at hand (get_extension is a call into the SystemC library, and the
// accurate engine asks for it several times per stage).
struct MemoryPayload : tlm::tlm_generic_payload {
    MemoryRequest request;  // its MemoryRequest extension, set on it for as long as it lives
    MemoryPayload() { set_extension(&request); }
    ~MemoryPayload() override { clear_extension(&request); }
    MemoryPayload(const MemoryPayload&) = delete;
    MemoryPayload& operator=(const MemoryPayload&) = delete;
};
inline MemoryRequest& memory_request(tlm::tlm_generic_payload& gp) {
    return static_cast<MemoryPayload&>(gp).request;
}

// Annotated delays in cycles: the chip clock's cycle is 1 ns of SystemC time, and SystemC's
// default resolution is 1 ps (Chip checks it).
constexpr uint64_t kTimeUnitsPerCycle = 1000;
inline sc_core::sc_time cycles_delay(Cycle cycles) {
    // sc_time's constructors are calls into the SystemC library (every loosely timed request
    // makes two per level); its arithmetic is inline, and exact below 2^53 ps (104 days).
    static const sc_core::sc_time one_cycle = sc_core::sc_time::from_value(kTimeUnitsPerCycle);
    return one_cycle * static_cast<double>(cycles);
}
inline Cycle delay_cycles(const sc_core::sc_time& delay) {
    return delay.value() / kTimeUnitsPerCycle;
}
// The kernel's time in whole cycles: what a loosely timed delay is counted from.
inline Cycle kernel_cycle() {
    // (sc_time_stamp() as the kernel keeps it, read inline: it is read twice per request and
    // level.)
    const sc_core::sc_simcontext* kernel = sc_core::sc_curr_simcontext;
    return kernel ? kernel->time_stamp().value() / kTimeUnitsPerCycle : 0;
}

// A target socket's direct entry for loosely timed calls (TargetSocket below): the block's
// registered b_transport as a plain function of the block and the requester's index. An LtPort
// bound to such a socket calls it instead of the binder's virtual b_transport (one indirect call
// instead of a virtual thunk and two); the call is the same b_transport, with the same payload
// and delay.
using LtEntry = void (*)(void* block, int requester, tlm::tlm_generic_payload&, sc_core::sc_time&);
struct LtDirectTarget {
    struct Entry {
        LtEntry call = nullptr;  // nullptr: the block registered no b_transport
        void* block = nullptr;
        int requester = 0;
    };
    virtual Entry lt_entry() const = 0;

  protected:
    ~LtDirectTarget() = default;
};

// A requester's loosely timed calls through its initiator socket. A call's payload is the next
// free one of a stack that every port shares (a call returns before its requester makes another,
// and the calls it leads to below are nested in it): the few a chain of calls uses stay in the
// host's cache, where a payload per port (one per cache of a 64-core chip) did not.
class LtPort {
  public:
    using Port = sc_core::sc_port_b<tlm::tlm_fw_transport_if<>>;
    LtPort() = default;
    explicit LtPort(Port& port) : port_(&port) {}
    void attach(Port& port) { port_ = &port; }
    // Whether anything is bound (known once the kernel has elaborated the sockets).
    bool bound() const {
        if (!fw_ && port_->size() > 0) {
            fw_ = port_->operator->();
            // (Once per port, on its first call: whether the target offers a direct entry.)
            if (const auto* direct = dynamic_cast<const LtDirectTarget*>(fw_))
                direct_ = direct->lt_entry();
        }
        if (!fw_ && sc_core::sc_get_status() == sc_core::SC_ELABORATION)
            throw std::logic_error(std::string(port_->name()) +
                                   ": a block's socket is used before elaboration (sc_start)");
        return fw_ != nullptr;
    }
    // MemoryPort::access through the socket: the cycle the data is there.
    Cycle read(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd = nullptr) {
        Cycle done;
        transport(tlm::TLM_READ_COMMAND, addr, size_bytes, now, MemoryRequest::Lt::kTimed, bd,
                  done);
        return done;
    }
    // MemoryPort::write: the cycle the target took it.
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) {
        Cycle done;
        transport(tlm::TLM_WRITE_COMMAND, addr, size_bytes, now, MemoryRequest::Lt::kTimed, nullptr,
                  done);
        return done;
    }
    // MemoryPort::access_local: false (and nothing changed) unless the target serves it alone.
    bool read_local(uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
                    AccessBreakdown* bd = nullptr) {
        return transport(tlm::TLM_READ_COMMAND, addr, size_bytes, now,
                         MemoryRequest::Lt::kLocalOnly, bd, ready);
    }
    // MemoryPort::warm and warm_write.
    void warm(uint64_t addr, uint32_t size_bytes, bool write = false) {
        if (!bound()) return;
        Call call(write ? tlm::TLM_WRITE_COMMAND : tlm::TLM_READ_COMMAND, addr, size_bytes,
                  MemoryRequest::Lt::kWarm, nullptr);
        sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
        forward(call.gp, delay);
    }
    // Passes a loosely timed call on as it came (a block that adds nothing to the request's way
    // down, as the crossbar): the payload's lt_* cycles and the delay are the caller's.
    [[gnu::always_inline]] void forward(tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
        if (!fw_ && !bound())
            throw std::logic_error(std::string(port_->name()) + ": nothing is bound to it");
        if (direct_.call)
            direct_.call(direct_.block, direct_.requester, gp, delay);
        else
            fw_->b_transport(gp, delay);
    }

  private:
    // The payload of a call in progress, taken from the stack and given back when it returns.
    struct Call {
        MemoryPayload& gp;
        Call(tlm::tlm_command command, uint64_t addr, uint32_t size_bytes, MemoryRequest::Lt lt,
             AccessBreakdown* bd)
            : gp(take()) {
            gp.set_command(command);
            gp.set_address(addr);
            gp.set_data_length(size_bytes);
            gp.set_response_status(tlm::TLM_INCOMPLETE_RESPONSE);
            gp.request.lt = lt;
            gp.request.breakdown = bd;
        }
        ~Call() { --depth_; }
        Call(const Call&) = delete;
        Call& operator=(const Call&) = delete;
    };
    static MemoryPayload& take() {
        if (depth_ == stack_.size()) grow();
        return *stack_[depth_++];
    }
    [[gnu::noinline]] static void grow() { stack_.push_back(std::make_unique<MemoryPayload>()); }
    [[gnu::always_inline]] Cycle kernel_at(Cycle now) const {
        const Cycle kernel = kernel_cycle();
        if (now < kernel)
            throw std::logic_error(std::string(port_->name()) + ": a loosely timed request at " +
                                   std::to_string(now) + " came before the kernel's time " +
                                   std::to_string(kernel));
        return kernel;
    }
    // A timed or local-only call at `now`: whether the target served it, and then the cycle it
    // was done. (Out of line: a miss's path, kept out of the requesters' hit loops.)
    [[gnu::noinline]] bool transport(tlm::tlm_command command, uint64_t addr, uint32_t size_bytes,
                                     Cycle now, MemoryRequest::Lt lt, AccessBreakdown* bd,
                                     Cycle& done) {
        const Cycle kernel = kernel_at(now);
        Call call(command, addr, size_bytes, lt, bd);
        call.gp.request.lt_kernel = kernel;
        call.gp.request.lt_at = now;
        sc_core::sc_time delay = cycles_delay(now - kernel);
        forward(call.gp, delay);
        if (!call.gp.is_response_ok()) return false;
        done = call.gp.request.lt_done;
        return true;
    }
    Port* port_ = nullptr;
    mutable tlm::tlm_fw_transport_if<>* fw_ = nullptr;  // what is bound, once elaborated
    mutable LtDirectTarget::Entry direct_;              // its direct entry, if it has one
    static inline std::vector<std::unique_ptr<MemoryPayload>> stack_;
    static inline size_t depth_ = 0;
};

// A block's b_transport: the loosely timed call as its MemoryPort serves it (Block: the block's
// own class, so that a final one's calls are direct).
template <class Block>
void serve_loosely_timed(Block& block, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
    static_assert(std::is_base_of_v<MemoryPort, Block>, "a block serves as its MemoryPort");
    MemoryRequest& r = memory_request(gp);
    const uint64_t addr = gp.get_address();
    const uint32_t size_bytes = gp.get_data_length();
    gp.set_response_status(tlm::TLM_OK_RESPONSE);
    if (r.lt == MemoryRequest::Lt::kWarm) {
        if (gp.is_write())
            block.warm_write(addr, size_bytes);
        else
            block.warm(addr, size_bytes);
        return;
    }
    const Cycle now = r.lt_at;  // the kernel's cycle + the delay
    Cycle done;
    if (r.lt == MemoryRequest::Lt::kLocalOnly) {
        if (!block.access_local(addr, size_bytes, now, done, r.breakdown)) {
            gp.set_response_status(tlm::TLM_INCOMPLETE_RESPONSE);
            return;
        }
    } else if (gp.is_write()) {
        done = block.write(addr, size_bytes, now);
    } else {
        done = block.access(addr, size_bytes, now, r.breakdown);
    }
    r.lt_done = done;
    delay = cycles_delay(done - r.lt_kernel);
}

// Payloads a requester owns, each with its MemoryRequest, reused once answered.
class PayloadPool {
  public:
    tlm::tlm_generic_payload& acquire(tlm::tlm_command command, uint64_t addr, uint32_t size_bytes,
                                      Cycle start) {
        MemoryPayload* gp;
        if (free_.empty()) {
            gp = &all_.emplace_back();
        } else {
            gp = free_.back();
            free_.pop_back();
        }
        gp->set_command(command);
        gp->set_address(addr);
        gp->set_data_length(size_bytes);
        gp->set_response_status(tlm::TLM_INCOMPLETE_RESPONSE);
        gp->request.reset(start);
        return *gp;
    }
    void release(tlm::tlm_generic_payload& gp) {
        free_.push_back(static_cast<MemoryPayload*>(&gp));
    }

  private:
    std::deque<MemoryPayload> all_;  // in blocks, each payload where it was made
    std::vector<MemoryPayload*> free_;
};

// Records a block keeps while their stages are pending, each known by the id its stages carry,
// reused once removed.
template <typename T>
class IdPool {
  public:
    // A record's id: a removed one's (its value as it was left) or a new default one's.
    uint32_t take() {
        if (free_.empty()) {
            items_.emplace_back();
            return uint32_t(items_.size() - 1);
        }
        const uint32_t id = free_.back();
        free_.pop_back();
        return id;
    }
    uint32_t add(const T& value) {
        const uint32_t id = take();
        items_[id] = value;
        return id;
    }
    T& operator[](uint32_t id) { return items_[id]; }
    void remove(uint32_t id) { free_.push_back(id); }
    // Ids handed out so far, removed ones included: every id below it names a record.
    size_t size() const { return items_.size(); }

  private:
    std::vector<T> items_;
    std::vector<uint32_t> free_;
};

// A block that runs stages of its own on the StageQueue.
class StageHandler {
  public:
    virtual void run_stage(uint32_t kind, uint32_t id, uint32_t k, Cycle t) = 0;

  protected:
    ~StageHandler() = default;
};

// The time-ordered engine's event queue: every stage of every request at its cycle. Within a
// cycle, fills complete first (a line arriving at t is there for a lookup at t, as the fast model
// has it), then other memory stages, then ray slots by rank (the fast model's arbitration: the
// lower core, then the lower slot, takes the next ray), each class in the order it was scheduled.
//
// Stages fall within a few hundred cycles of the current one: they wait in a ring of per-cycle
// buckets, and only the current cycle's stages are ordered (a small heap); a stage further ahead
// than the ring waits in a heap of its own until the ring reaches it. (One heap of every stage
// took a quarter of the engine's time.)
class StageQueue {
  public:
    static constexpr uint64_t kFillOrder = 0, kMemoryOrder = 1, kSlotOrder = 2;
    StageQueue() : ring_(kRingCycles) {}
    void schedule(Cycle t, uint64_t order, StageHandler* block, uint32_t kind, uint32_t id,
                  uint32_t k = 0) {
        const Event e{t, order << kSeqBits | seq_++, block, id, k, kind};
        ++pending_;
        if (t == now_.cycle && current_loaded_) {
            current_.push_back(e);
            std::push_heap(current_.begin(), current_.end(), Later{});
        } else if (t < now_.cycle) {
            throw std::logic_error("accurate fidelity: a stage scheduled before the current cycle");
        } else if (t < now_.cycle + kRingCycles) {
            ring_[t & (kRingCycles - 1)].push_back(e);
            ++in_ring_;
        } else {
            far_.push(e);
        }
    }
    bool empty() const { return pending_ == 0; }
    // The cycle of the earliest stage (the queue must not be empty).
    Cycle next_cycle() {
        if (current_.empty()) load_next();
        return now_.cycle;
    }
    // Runs the earliest stage.
    void run_next() {
        if (current_.empty()) load_next();
        std::pop_heap(current_.begin(), current_.end(), Later{});
        const Event e = current_.back();
        current_.pop_back();
        --pending_;
        e.block->run_stage(e.kind, e.id, e.k, e.t);
    }
    Cycle now() const { return now_.cycle; }
    // Every block's floor: nothing is ever requested before the current stage.
    const TimeFloor* floor() const { return &now_; }

  private:
    static constexpr int kSeqBits = 40;
    static constexpr Cycle kRingCycles = 1024;  // a power of two
    struct Event {
        Cycle t;
        uint64_t key;  // order, then the order scheduled
        StageHandler* block;
        uint32_t id, k, kind;
    };
    struct Later {
        bool operator()(const Event& a, const Event& b) const {
            return a.t != b.t ? a.t > b.t : a.key > b.key;
        }
    };
    // Makes the next cycle with stages the current one, its stages the current heap.
    void load_next() {
        Cycle c = now_.cycle + (current_loaded_ ? 1 : 0);
        if (in_ring_ == 0) c = std::max(c, far_.top().t);  // nothing near: jump to the far ones
        for (;;) {
            // The ring covers [c, c + kRingCycles): far stages it now reaches move into it.
            while (!far_.empty() && far_.top().t < c + kRingCycles) {
                ring_[far_.top().t & (kRingCycles - 1)].push_back(far_.top());
                ++in_ring_;
                far_.pop();
            }
            std::vector<Event>& bucket = ring_[c & (kRingCycles - 1)];
            if (!bucket.empty()) {
                current_.swap(bucket);
                in_ring_ -= current_.size();
                std::make_heap(current_.begin(), current_.end(), Later{});
                break;
            }
            ++c;
        }
        now_.cycle = c;
        current_loaded_ = true;
    }
    std::vector<std::vector<Event>> ring_;  // per cycle modulo kRingCycles
    std::priority_queue<Event, std::vector<Event>, Later> far_;
    std::vector<Event> current_;  // the current cycle's stages, a heap
    bool current_loaded_ = false;
    uint64_t in_ring_ = 0, pending_ = 0;
    uint64_t seq_ = 0;
    TimeFloor now_;
};

// Socket types every memory block uses: a target socket any number of requesters bind to (the
// block answers each on its own), and the initiator socket towards the next level.
using TargetSocketBase =
    tlm::tlm_target_socket<32, tlm::tlm_base_protocol_types, 0, sc_core::SC_ZERO_OR_MORE_BOUND>;

// The target socket: any number of requesters bind to it, and each call reaches the block's
// registered member function with the requester's index (the order they bound in); the block
// answers requester i through (*this)[i], as with tlm_utils' multi-passthrough socket. The
// functions are registered as template arguments,
//     up.register_b_transport<&Cache::b_transport>(this);
// so that a call costs one virtual call into the socket's per-requester binder and one direct
// call into the block. (tlm_utils' socket makes two more indirect calls per call, which was
// several percent of the fast engine's time at one loosely timed call per step.) A call the
// block registered nothing for is refused with TLM_COMMAND_ERROR_RESPONSE.
template <class Module>
class TargetSocket final : public TargetSocketBase {
  public:
    using Payload = tlm::tlm_generic_payload;
    using BTransport = void (Module::*)(int, Payload&, sc_core::sc_time&);
    using NbTransport = tlm::tlm_sync_enum (Module::*)(int, Payload&, tlm::tlm_phase&,
                                                       sc_core::sc_time&);
    explicit TargetSocket(const char* name) : TargetSocketBase(name) {
        // The export must be bound at elaboration even when nothing binds to the socket: to the
        // first requester's binder, made now.
        binders_.push_back(std::make_unique<Binder>(this, 0));
        TargetSocketBase::export_type::bind(*binders_[0]);
    }
    template <BTransport F>
    void register_b_transport(Module* module) {
        module_ = module;
        b_ = &call_b<F>;
    }
    template <NbTransport F>
    void register_nb_transport_fw(Module* module) {
        module_ = module;
        nb_ = &call_nb<F>;
    }
    // A requester binding: the next binder, in bind order.
    tlm::tlm_fw_transport_if<>& get_base_interface() override {
        while (binders_.size() <= handed_out_)
            binders_.push_back(std::make_unique<Binder>(this, int(binders_.size())));
        return *binders_[handed_out_++];
    }
    const tlm::tlm_fw_transport_if<>& get_base_interface() const override { return *binders_[0]; }

  private:
    template <BTransport F>
    static void call_b(void* m, int id, Payload& gp, sc_core::sc_time& delay) {
        (static_cast<Module*>(m)->*F)(id, gp, delay);
    }
    template <NbTransport F>
    static tlm::tlm_sync_enum call_nb(Module* m, int id, Payload& gp, tlm::tlm_phase& phase,
                                      sc_core::sc_time& delay) {
        return (m->*F)(id, gp, phase, delay);
    }
    struct Binder final : tlm::tlm_fw_transport_if<>, LtDirectTarget {
        TargetSocket* socket;
        int id;
        Binder(TargetSocket* s, int i) : socket(s), id(i) {}
        Entry lt_entry() const override { return {socket->b_, socket->module_, id}; }
        void b_transport(Payload& gp, sc_core::sc_time& delay) override {
            if (!socket->b_) return refuse(gp);
            socket->b_(socket->module_, id, gp, delay);
        }
        tlm::tlm_sync_enum nb_transport_fw(Payload& gp, tlm::tlm_phase& phase,
                                           sc_core::sc_time& delay) override {
            if (!socket->nb_) {
                refuse(gp);
                return tlm::TLM_COMPLETED;
            }
            return socket->nb_(socket->module_, id, gp, phase, delay);
        }
        bool get_direct_mem_ptr(Payload&, tlm::tlm_dmi&) override { return false; }
        unsigned int transport_dbg(Payload&) override { return 0; }
        static void refuse(Payload& gp) { gp.set_response_status(tlm::TLM_COMMAND_ERROR_RESPONSE); }
    };
    Module* module_ = nullptr;
    LtEntry b_ = nullptr;
    tlm::tlm_sync_enum (*nb_)(Module*, int, Payload&, tlm::tlm_phase&, sc_core::sc_time&) = nullptr;
    std::vector<std::unique_ptr<Binder>> binders_;
    size_t handed_out_ = 0;
};
template <class Module>
using InitiatorSocket = tlm_utils::simple_initiator_socket_optional<Module>;

// Direct access to a block found through a socket, as TLM-2.0's DMI hands out memory: a requester
// that calls a block on every step (a core its units and its ray buffer) asks once, through the
// socket its binding gave it, for the block itself, and calls it directly from then on. The
// binding still decides which block it is (shared units, one ray buffer for all cores).
template <class Block>
struct DirectAccess : tlm::tlm_extension<DirectAccess<Block>> {
    Block* block = nullptr;
    tlm::tlm_extension_base* clone() const override { return new DirectAccess(*this); }
    void copy_from(const tlm::tlm_extension_base& other) override {
        block = static_cast<const DirectAccess&>(other).block;
    }
};
// A payload that is not a memory access (TLM_IGNORE_COMMAND) and carries `ext`, for one call;
// the extension is taken off again when the call ends.
template <class Extension>
struct ExtensionCall {
    tlm::tlm_generic_payload gp;
    explicit ExtensionCall(Extension& ext) : ext_(ext) {
        gp.set_command(tlm::TLM_IGNORE_COMMAND);
        gp.set_response_status(tlm::TLM_INCOMPLETE_RESPONSE);
        gp.set_extension(&ext_);
    }
    ~ExtensionCall() { gp.clear_extension(&ext_); }
    ExtensionCall(const ExtensionCall&) = delete;
    ExtensionCall& operator=(const ExtensionCall&) = delete;

  private:
    Extension& ext_;
};
// The requester's side: the Block at the other end of `target`, or nullptr if it is not one.
template <class Block>
Block* find_direct(tlm::tlm_fw_transport_if<>& target) {
    DirectAccess<Block> ask;
    ExtensionCall<DirectAccess<Block>> call(ask);
    sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
    target.b_transport(call.gp, delay);
    return call.gp.is_response_ok() ? ask.block : nullptr;
}
// The block's side, first thing in its b_transport: answers a request for direct access (true)
// or leaves the payload to the block (false).
template <class Block>
bool answer_direct(Block* block, tlm::tlm_generic_payload& gp) {
    auto* ask = gp.get_extension<DirectAccess<Block>>();
    if (!ask) return false;
    ask->block = block;
    gp.set_response_status(tlm::TLM_OK_RESPONSE);
    return true;
}

// A block the cores reach through its target socket.
class TimedTarget {
  public:
    virtual TargetSocketBase& target_socket() = 0;
    // The time-ordered engine's queue, on which the block runs its stages.
    virtual void set_stage_queue(StageQueue* queue) = 0;

  protected:
    ~TimedTarget() = default;
};

}  // namespace rtsim

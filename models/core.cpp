#include "models/core.h"

#include "models/core_slots.h"
#include "models/ray_buffer.h"

#include <algorithm>
#include <chrono>
#include <utility>

namespace rtsim {

namespace {
// The least two of a set of keys, merged pairwise (minimums and maximums only, no branches).
struct LeastTwo {
    uint64_t least = ~uint64_t(0), second = ~uint64_t(0);
    static LeastTwo of(uint64_t a, uint64_t b) {
        // A mask, not min and max: gcc turns a min and a max of one compare into a branch.
        const uint64_t swap = (a ^ b) & -uint64_t(b < a);
        return {a ^ swap, b ^ swap};
    }
    LeastTwo merge(const LeastTwo& o) const {
        const LeastTwo lows = of(least, o.least);
        return {lows.least, std::min(lows.second, std::min(second, o.second))};
    }
};
[[gnu::always_inline]] inline LeastTwo least_two_of_8(const uint64_t* k) {
    const LeastTwo a = LeastTwo::of(k[0], k[1]).merge(LeastTwo::of(k[2], k[3]));
    const LeastTwo b = LeastTwo::of(k[4], k[5]).merge(LeastTwo::of(k[6], k[7]));
    return a.merge(b);
}
// The least two of `n` keys, n a multiple of eight (as least_of).
[[gnu::always_inline]] inline LeastTwo least_two(const uint64_t* k, size_t n) {
    LeastTwo two = least_two_of_8(k);
    for (size_t j = 8; j < n; j += 8) two = two.merge(least_two_of_8(k + j));
    return two;
}
}  // namespace

Core::Core(sc_core::sc_module_name name, const CoreParams& params,
           const std::array<TargetSocketBase*, kStepKinds>& memory,
           const std::array<TargetSocketBase*, kStepKinds>& units, RayWorkSource* source)
    : sc_core::sc_module(name),
      local_socket("local_socket"),
      params_(params),
      source_(source),
      source_wake_(source ? source->wake_pending() : nullptr),
      slots_(static_cast<size_t>(params.ray_slots)),
      ready_(padded_to_8(slots_.size())),
      keys_(ready_.size()) {
    local_socket.register_nb_transport_bw(this, &Core::nb_transport_bw);
    ray_buffer_socket.register_nb_transport_bw(this, &Core::nb_transport_bw);
    lt_local_.attach(local_socket);
    for (int k = 0; k < kStepKinds; ++k) {
        memory_socket[k].register_nb_transport_bw(this, &Core::nb_transport_bw);
        if (memory[size_t(k)]) memory_socket[k].bind(*memory[size_t(k)]);
        lt_memory_[k].attach(memory_socket[k]);
        unit_socket[k].register_nb_transport_bw(this, &Core::nb_transport_bw);
        if (units[size_t(k)]) unit_socket[k].bind(*units[size_t(k)]);
        instructions_by_kind_[k] = params.step_instructions[k];
    }
    // Slots beyond ray_slots pad the keys to the eights the pick unrolls; they never run.
    for (size_t i = 0; i < ready_.size(); ++i) set_ready(i, i < slots_.size() ? 0 : kNeverCycle);
    issue_port_.per_cycle = params.issue_width;
    for (Slot& s : slots_) s.stack = ShortStack(params.short_stack_entries);
    write_buffer_.assign(params.write_buffer_entries, 0);
}

void Core::end_of_elaboration() {
    for (int k = 0; k < kStepKinds; ++k) {
        if (unit_socket[k].size() == 0) continue;  // a step kind this chip has no unit for
        unit_by_kind_[k] = find_direct<PipelinedUnit>(*unit_socket[k].operator->());
        if (!unit_by_kind_[k])
            throw std::logic_error(std::string(unit_socket[k].name()) +
                                   ": the target bound to it is not a unit");
    }
    if (ray_buffer_socket.size() > 0) {
        RayBuffer* buffer = find_direct<RayBuffer>(*ray_buffer_socket.operator->());
        if (!buffer)
            throw std::logic_error(std::string(ray_buffer_socket.name()) +
                                   ": the target bound to it is not a ray buffer");
        attach_ray_buffer(buffer);
    }
}

// Issues `instructions` (at least 1) instructions ready at t through the core's shared issue
// port (issue_width per cycle); returns when the step's fetch can start.
Cycle Core::issue(Cycle t, int instructions) {
    Cycle last = issue_port_.take(t);
    issue_stall_cycles += last - t;  // waiting for the first issue slot
    for (int i = 1; i < instructions; ++i) last = issue_port_.take(t);
    return last + params_.issue_latency_cycles;
}

void Core::count_finished(uint32_t work_rays, Cycle start, Cycle done) {
    rays += work_rays;
    ray_latency_cycles += done - start;
    if (rays_series_) rays_series_->add(done, work_rays);
    last_cycle = std::max(last_cycle, done);
    if (source_wake_) source_->finished(work_rays, done);
}

void Core::attach_ray_buffer(RayBuffer* buffer) {
    ray_buffer_ = buffer;
    // Rays then come from the buffer, which parks and wakes slots itself.
    if (buffer) source_wake_ = nullptr;
    if (!buffer || !params_.treelet_prefetch) return;
    // One more ready key, for the treelet loader (idle until a batch needs a treelet).
    loader_ = slots_.size();
    ready_.assign(padded_to_8(slots_.size() + 1), 0);
    keys_ = CycleKeys(ready_.size());
    for (size_t i = 0; i < ready_.size(); ++i) set_ready(i, i < slots_.size() ? 0 : kNeverCycle);
}

void Core::go_idle(size_t slot, Cycle t, Cycle key_cycle) {
    slots_[slot].idle_since = t;
    set_ready(slot, key_cycle);
    if (key_cycle == kParkedCycle) {
        ++parked_slots_;
        if (ray_buffer_) ray_buffer_->note_parked(1);
    }
}

bool Core::wake(Cycle at) {
    if (parked_slots_ == 0) return false;
    at = std::max(at, floor_.cycle);  // never behind the core's own floor
    for (size_t i = 0; i < slots_.size(); ++i)
        if (keys_.cycle(ready_[i]) == kParkedCycle) {
            // Every ray done: the slot retires where it parked (its idle tail is counted up to
            // the run's end, which may come before this core's floor).
            if (ray_buffer_ && ray_buffer_->finished()) {
                set_ready(i, kNeverCycle);
                continue;
            }
            // Never before it parked (this core may have run ahead of `at` on private work).
            const Cycle from = std::max(at, slots_[i].idle_since);
            no_work_cycles += from - slots_[i].idle_since;
            set_ready(i, from);
        }
    if (ray_buffer_) ray_buffer_->note_parked(-int(parked_slots_));
    parked_slots_ = 0;
    return true;
}

uint64_t Core::retired_idle_cycles(Cycle end) const {
    uint64_t idle = 0;
    for (size_t i = 0; i < slots_.size(); ++i)
        if (keys_.cycle(ready_[i]) == kNeverCycle && slots_[i].idle_since < end)
            idle += end - slots_[i].idle_since;
    return idle;
}

// Starts loading a batch's treelet: the loader (run_loader) requests its lines from now on; rays
// that need a line still filling wait for it (miss merging).
void Core::load_treelet(uint32_t treelet) {
    const TreeletSpan& span = ray_buffer_->span(treelet);
    const size_t node = size_t(StepKind::Node), tri = size_t(StepKind::Triangle);
    load_.next[node] = span.node_addr;
    load_.end[node] = span.node_addr + span.node_bytes;
    load_.next[tri] = span.tri_addr;
    load_.end[tri] = span.tri_addr + span.tri_bytes;
    const size_t inst = size_t(StepKind::Transform);
    load_.next[inst] = span.instance_addr;
    load_.end[inst] = span.instance_addr + span.instance_bytes;
    ++treelet_loads;
    treelet_load_bytes += span.bytes();
    loaded_treelet_ = treelet;
}

namespace {
// Whether a fetch of several lines from `cache` at `issued` must go line by line: more of its
// lines miss than MSHRs are free then, so some misses would wait for others' fills.
bool needs_line_by_line(const Cache& cache, const Step& st, Cycle issued) {
    const auto [first, last] = cache.line_range(st.addr, st.size_bytes);
    if (last == first || last - first >= 255 || cache.params().mshrs <= 0) return false;
    uint32_t missing = 0;
    for (uint64_t line = first; line <= last; ++line)
        missing += !cache.contains(cache.line_address(line));
    return missing > 1 && missing > cache.free_mshrs_at(issued);
}
}  // namespace

// The fast engine's side of the slot state machine: requests complete at once with their
// annotated delays (loosely timed), and shared work past the horizon waits for its turn.
struct Core::LooselyTimed {
    static constexpr bool kTimeOrdered = false;
    Core& core;
    Cycle horizon;
    bool at_horizon;  // whether shared work exactly at `horizon` may run (this core comes first)

    bool beyond(Cycle c) const { return c > horizon || (c == horizon && !at_horizon); }
    void ready(size_t slot, Cycle c) { core.set_ready(slot, c); }
    void idle(size_t slot, Cycle t, bool retired) {
        core.go_idle(slot, t, retired ? kNeverCycle : kParkedCycle);
    }
    // The core scheduler looks for wakes between advances.
    void work_changed(Cycle) {}
    // The ray buffer writes its records to memory itself.
    void records_written(Cycle) {}
    // The loader is one more entry of the ready keys.
    void start_loader(Cycle t) { core.set_ready(core.loader_, t); }
    void loader_ready(Cycle c) { core.set_ready(core.loader_, c); }
    bool load_line(size_t kind, Cache* cache, uint64_t addr, uint32_t bytes, Cycle t) {
        // The breakdown is not charged (no ray waits for the load itself), but asking for one
        // lets the L1 remember its fills' timelines for the rays that then wait on them.
        AccessBreakdown unused;
        Cycle ready;
        if (cache->access_local(addr, bytes, t, ready, &unused)) return true;
        const Cycle leaves = cache->miss_leaves_at(t);
        if (leaves > t) {  // every MSHR busy: wait for one
            loader_ready(leaves);
            return false;
        }
        core.lt_memory_[kind].read(addr, bytes, t, &unused);
        return true;
    }
    // RayBuffer::read has read the record from memory already.
    bool read_record(size_t, Cycle) { return false; }
    bool write_entry_busy(size_t slot, Cycle t) { return core.wait_for_write_entry(slot, t); }
    void post_write(uint64_t addr, uint32_t bytes, Cycle t) { core.post_write(addr, bytes, t); }
    void read_stack(size_t slot, uint64_t addr, uint32_t bytes, Cycle t) {
        const Cycle back = core.lt_local_.read(addr, bytes, t);
        core.stall_cycles[kStack] += back - t;
        ready(slot, back);
    }
    // Tries the fetch as a private hit first (inline: most steps end here); a fetch that needs
    // a shared level runs only at its turn in the global order, else it is held back.
    [[gnu::always_inline]] void fetch(size_t slot, const Step& st, Cycle issued, Fetch& f) {
        f.kind = Fetch::kDone;
        // A step that reads nothing (an any-hit shader without alpha data) has its data at once.
        if (st.size_bytes == 0) {
            f.cycle = issued;
            return;
        }
        Slot& s = core.slots_[slot];
        const auto kind = size_t(st.kind);
        Cache* cache = core.cache_by_kind_[kind];
        if (!s.fetch_is_shared &&
            (cache ? cache->access_local(st.addr, st.size_bytes, issued, f.cycle, &f.bd)
                   : core.lt_memory_[kind].read_local(st.addr, st.size_bytes, issued, f.cycle,
                                                      &f.bd)))
            return;
        fetch_shared(s, st, issued, f);
    }
    void fetch_shared(Slot& s, const Step& st, Cycle issued, Fetch& f);
};

// Inlined as the step loop always had it (called, the loop ran 9% slower).
[[gnu::always_inline]] inline void Core::LooselyTimed::fetch_shared(Slot& s, const Step& st,
                                                                    Cycle issued, Fetch& f) {
    const auto kind = size_t(st.kind);
    LtPort& mem = core.lt_memory_[kind];
    Cache* cache = core.cache_by_kind_[kind];
    // The request leaves the core at `issued`: that is its place in the global order. (Resumed,
    // the slot is still this core's earliest and the port the same, so it issues at the same
    // cycle.)
    // A miss waiting for an MSHR reaches the next level only once one frees: that is its place
    // in the global order (sent now, it would reach the L2 and DRAM ahead of other cores'
    // earlier requests, which then queue behind it: +15% cycles with 2 MSHRs per L1 against the
    // time-ordered reference).
    // A fetch of several lines whose misses outnumber the free MSHRs would send its later lines'
    // misses as earlier ones' fills free their MSHRs, hundreds of cycles ahead of other cores'
    // requests, which would queue behind them (BVH8 nodes, one L1 MSHR, 64 cores: +88% cycles
    // against the time-ordered reference). It goes line by line instead, each miss held back
    // until it can leave.
    const auto hold_until = [&f](Cycle at) {
        f.kind = Fetch::kHold;
        f.cycle = at;
    };
    if (cache && (s.fetch_lines_sent > 0 || needs_line_by_line(*cache, st, issued))) {
        const uint64_t end = st.addr + st.size_bytes;
        const auto [first_line, last_line] = cache->line_range(st.addr, st.size_bytes);
        for (uint64_t k = s.fetch_lines_sent; first_line + k <= last_line; ++k) {
            const uint64_t from = std::max(st.addr, cache->line_address(first_line + k));
            const uint64_t to = std::min(end, cache->line_address(first_line + k + 1));
            const Cycle line_leaves =
                cache->contains(from) ? issued : cache->miss_leaves_at(issued);
            if (beyond(line_leaves)) {
                s.fetch_lines_sent = uint8_t(k);
                hold_until(line_leaves);
                return;
            }
            AccessBreakdown line_bd;
            const Cycle ready = mem.read(from, uint32_t(to - from), issued, &line_bd);
            if (k == 0 || ready > s.fetch_ready) {
                s.fetch_ready = ready;
                s.fetch_bd = line_bd;
            }
        }
        f.cycle = s.fetch_ready;
        f.bd = s.fetch_bd;
        s.fetch_lines_sent = 0;
        s.fetch_is_shared = false;
        return;
    }
    const Cycle leaves = cache ? cache->miss_leaves_at(issued) : issued;
    if (beyond(leaves)) {
        hold_until(leaves);
        return;
    }
    f.cycle = mem.read(st.addr, st.size_bytes, issued, &f.bd);
    s.fetch_is_shared = false;
}

Cycle Core::advance(Cycle horizon, Cycle others_floor, bool at_horizon) {
    // Shared work runs up to the horizon; at it only if this core comes first among equals.
    LooselyTimed engine{*this, horizon, at_horizon};
    for (;;) {
        const LeastTwo two = least_two(ready_.data(), ready_.size());
        const uint64_t least = two.least;
        const size_t i = keys_.index(least);
        const Cycle t = keys_.cycle(least);
        if (t >= kParkedCycle) return t;  // every slot parked or retired
        // Work arrived for parked slots (here or in other cores): they wake before anything
        // later runs.
        if (ray_buffer_ && ray_buffer_->wake_needed()) return t;
        if (source_wake_ && *source_wake_) return t;
        {
            // The next earliest slot usually runs next: start loading its step, which it last
            // touched dozens of steps ago and the host's L1 has likely dropped since.
            const Slot& after = slots_[std::min(keys_.index(two.second), slots_.size() - 1)];
            __builtin_prefetch(after.work.steps.data() + after.pos);
        }
        // Every later request of this core comes at t or after.
        floor_.cycle = t;
        if (shared_floor_) shared_floor_->cycle = std::min(t, others_floor);
        if (i == loader_) {
            if (engine.beyond(t)) return t;  // its misses reach the shared levels
            run_loader(t, engine);
            continue;
        }
        // Private work may run ahead of the other cores: this core's own calendars still see
        // its requests in time order, because it always runs its earliest slot.
        const Cycle held = run_slot(i, t, engine);
        if (held != kRunOn) return held;
    }
}

const char* Core::stall_name(int s) {
    static const char* const names[kUnitStall] = {"issue", "l1", "l2", "dram", "crossbar"};
    if (s < kUnitStall) return names[s];
    if (s < kRayBuffer) return step_kind_info(s - kUnitStall).unit;
    static const char* const later[] = {"ray_buffer", "stack", "write_buffer"};
    return later[s - kRayBuffer];
}

void Core::register_stats(StatsRegistry& reg) {
    const std::string block = name();
    for (int k = 0; k < kStallKinds; ++k)
        reg.add(block, std::string("stall_") + stall_name(k) + "_cycles", &stall_cycles[k],
                "ray-slot cycles charged to this cause");
    reg.add(block, "rays", &rays, "rays completed");
    reg.add(block, "steps", &steps, "traversal steps executed");
    reg.add(block, "ray_latency_cycles", &ray_latency_cycles,
            "summed ray latency, dispatch to result");
    reg.add(block, "issue_stall_cycles", &issue_stall_cycles,
            "cycles steps waited for an issue slot");
    reg.add(block, "last_cycle", &last_cycle, "cycle the core's last ray finished");
    reg.add(block, "no_work_cycles", &no_work_cycles,
            "slot cycles parked without a ray (retired slots' tails are added in the report)");
    reg.add(block, "issue_port_out_of_order", &issue_port_.out_of_order,
            "issues ready before an earlier issue's ready cycle (served out of time order)");
    if (treelet_mode_) {  // (stats are registered before the buffer is found)
        reg.add(block, "treelet_loads", &treelet_loads, "treelets loaded for a batch");
        reg.add(block, "treelet_load_bytes", &treelet_load_bytes, "bytes of treelets loaded");
    }
    if (params_.short_stack_entries > 0) {
        reg.add(block, "stack_spills", &stack_spills, "stack spills (writes) to memory");
        reg.add(block, "stack_spill_bytes", &stack_spill_bytes, "bytes of stack entries spilled");
        reg.add(block, "stack_refills", &stack_refills, "stack refills (reads) from memory");
        reg.add(block, "stack_refill_bytes", &stack_refill_bytes,
                "bytes of stack entries read back");
    }
    if (params_.hit_record_bytes > 0) {
        reg.add(block, "hit_record_writes", &hit_record_writes,
                "hit-record writes (per work item)");
        reg.add(block, "hit_record_bytes", &hit_record_bytes, "bytes of hit records written");
    }
    if (params_.packet_lanes > 0) {
        reg.add(block, "active_lanes", &active_lanes, "packet lanes whose ray took part, summed");
        reg.add(block, "lane_slots", &lane_slots, "packet lanes occupied, summed over steps");
    }
}

CoreScheduler::CoreScheduler(sc_core::sc_module_name name, std::vector<Core*> cores,
                             WakeSource* wake)
    : ChipDriver(name), cores_(std::move(cores)), wake_(wake), keys_(padded_to_8(cores_.size())) {
    for (Core* core : cores_) core->set_shared_floor(&floor_);
    SC_THREAD(run);
}

void CoreScheduler::run() {
    // Per core: the cycle of its next shared work; kParkedCycle while it waits for work,
    // kNeverCycle once retired. A few cores: a branch-free scan for the earliest and the next
    // earliest beats a heap.
    const size_t n = cores_.size();
    // Members, not locals: sc_stop() mid-run (a damaged trace) never unwinds this stack. Both
    // are padded to eights with retired cores for the unrolled scans.
    const size_t padded = padded_to_8(n);
    next_.resize(padded);
    floors_.assign(padded, kNeverCycle);
    for (size_t i = 0; i < padded; ++i) next_[i] = keys_.key(i < n ? 0 : kNeverCycle, i);
    for (size_t i = 0; i < n; ++i) floors_[i] = cores_[i]->floor()->cycle;
    uint64_t* next = next_.data();
    auto resumed = std::chrono::steady_clock::now();
    Cycle kernel_cycle = 0;
    for (;;) {
        // The least two keys (ties: the lower index, so runs are deterministic).
        const LeastTwo two = least_two(next, padded);
        const size_t c = keys_.index(two.least);
        const Cycle first = keys_.cycle(two.least);
        const Cycle second = keys_.cycle(two.second);
        if (first >= kParkedCycle) break;  // all retired (parked cores are woken by work)
        // Parked cores wake no earlier than `first`, retired ones send nothing: the shared
        // floor is the earliest among the running cores', which the advancing core updates.
        floors_[c] = kNeverCycle;
        const Cycle others_floor = least_of(floors_.data(), padded);
        // The kernel's time follows the earliest cycle any core may still send a request at (a
        // miss held back for an MSHR is sent at its slot's cycle, before its core's key): the
        // blocks count a loosely timed request's delay from it (models/transaction.h).
        const Cycle sync_to = std::min({first, others_floor, cores_[c]->floor()->cycle});
        if (sync_to >= kernel_cycle + kKernelSyncCycles) {
            host_busy_seconds_ +=
                std::chrono::duration<double>(std::chrono::steady_clock::now() - resumed).count();
            wait(cycles_to_time(sync_to - kernel_cycle));
            resumed = std::chrono::steady_clock::now();
            kernel_cycle = sync_to;
        }
        const Cycle horizon = second >= kParkedCycle ? kNeverCycle : second;
        // At equal cycles the lower core goes first (the time-ordered reference's arbitration
        // too): a core runs work at the next core's cycle only if its index is lower. (Letting
        // the running core go on at equal cycles handed it runs of consecutive rays that the
        // reference hands to other cores.)
        const bool at_horizon = c < keys_.index(two.second);
        const Cycle next_c = cores_[c]->advance(horizon, others_floor, at_horizon);
        next[c] = keys_.key(next_c, c);
        floors_[c] = next_c < kParkedCycle ? cores_[c]->floor()->cycle : kNeverCycle;
        Cycle at;
        if (wake_ && wake_->take_wake(at)) {
            at = std::max(at, first);  // never behind the order already served
            // Every parked slot wakes, in running cores too.
            for (size_t i = 0; i < n; ++i)
                if (cores_[i]->wake(at)) {
                    const bool was_parked = keys_.cycle(next[i]) == kParkedCycle;
                    next[i] = std::min(next[i], keys_.key(at, i));
                    if (was_parked) floors_[i] = cores_[i]->floor()->cycle;
                }
        }
    }
    host_busy_seconds_ +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - resumed).count();
}

namespace {
// Stall causes charged over `cores`, the cycles they had no ray, and what neither accounts for
// of their slot cycles (0 when every slot cycle is charged exactly once; a test checks it).
nlohmann::json stall_entry(const std::vector<const Core*>& cores, uint64_t slot_cycles, Cycle end) {
    nlohmann::json e = nlohmann::json::object(), share = nlohmann::json::object();
    uint64_t charged = 0, no_work = 0;
    for (int k = 0; k < Core::kStallKinds; ++k) {
        uint64_t v = 0;
        for (const Core* c : cores) v += c->stall_cycles[k];
        e[Core::stall_name(k)] = v;
        share[Core::stall_name(k)] = ReportContext::ratio(double(v), double(slot_cycles));
        charged += v;
    }
    for (const Core* c : cores) no_work += c->no_work_cycles + c->retired_idle_cycles(end);
    e["no_work"] = no_work;
    e["slot_cycles"] = slot_cycles;
    e["unaccounted_cycles"] = int64_t(slot_cycles) - int64_t(charged + no_work);
    share["no_work"] = ReportContext::ratio(double(no_work), double(slot_cycles));
    e["share"] = share;
    return e;
}
}  // namespace

nlohmann::json Core::stall_report(const ReportContext& ctx) const {
    return stall_report_total({this}, ctx);
}

nlohmann::json Core::stall_report_total(const std::vector<const Core*>& cores,
                                        const ReportContext& ctx) {
    uint64_t slots = 0;
    for (const Core* c : cores) slots += uint64_t(c->params_.ray_slots);
    return stall_entry(cores, slots * ctx.total_cycles, ctx.total_cycles);
}

nlohmann::json Core::packet_report(const std::vector<const Core*>& cores) {
    const uint64_t active = sum_of(cores, &Core::active_lanes);
    const uint64_t slots = sum_of(cores, &Core::lane_slots);
    return {{"active_lanes", active},
            {"lane_slots", slots},
            {"lane_utilization", ReportContext::ratio(double(active), double(slots))}};
}

std::vector<std::string> stall_causes() {
    std::vector<std::string> causes;
    for (int k = 0; k < Core::kStallKinds; ++k) causes.push_back(Core::stall_name(k));
    causes.push_back("no_work");
    return causes;
}

}  // namespace rtsim

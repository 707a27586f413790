// The ray slots' state machine, written once and run by both engines: what a slot does next
// (take a ray, read its record, set it up, make its stack traffic, fetch a step, test it, write
// its hit records, move it to another treelet's queue, retire) and what each action costs the
// core. The engine decides only how a request reaches the memory and when the slot runs again:
//
// - the fast engine (Core::LooselyTimed, models/core.cpp) completes a request at once with its
//   annotated delay and runs a slot on while its next action is at the same cycle; it holds
//   shared work back past its horizon (`beyond`), so that shared blocks see requests nearly in
//   time order;
// - the time-ordered reference (models/fidelity/accurate.cpp) runs every action as an event at
//   its own cycle: a request it starts completes later, through Core::step_fetched or its own
//   wake of the slot.
//
// An Engine provides:
//   static constexpr bool kTimeOrdered  every later action is an event (ready, then return)
//   bool beyond(Cycle c)                shared work at c must wait: run_slot returns c
//   void ready(size_t slot, Cycle c)    the slot's next action is at c
//   void idle(size_t slot, Cycle t, bool retired)   no work now: parked, or retired for good
//   void work_changed(Cycle t)          rays were taken, queued or finished (parked slots may wake)
//   void records_written(Cycle t)       the ray buffer wrote records the engine posts itself
//   void start_loader(Cycle t)          a new treelet load (replacing one running) starts at t
//   void loader_ready(Cycle c)          the loader's next line is at c (kNeverCycle: loaded)
//   bool load_line(size_t kind, Cache* cache, uint64_t addr, uint32_t bytes, Cycle t)
//                                       false: every MSHR busy, the engine resumes the loader
//   bool read_record(size_t slot, Cycle from)   true: the record comes from memory later
//   bool write_entry_busy(size_t slot, Cycle t) true: the write waits (the engine resumes it)
//   void post_write(uint64_t addr, uint32_t bytes, Cycle t)
//   void read_stack(size_t slot, uint64_t addr, uint32_t bytes, Cycle t)  the slot waits for it
//   void fetch(size_t slot, const Step& step, Cycle issued, Core::Fetch& fetch)
#pragma once

#include "models/core.h"
#include "models/ray_buffer.h"

namespace rtsim {

template <class Engine>
[[gnu::always_inline]] inline void Core::step_done(size_t slot, int kind, Cycle fetched, Cycle done,
                                                   Cycle now, Engine& engine) {
    Slot& s = slots_[slot];
    engine.ready(slot, done);
    stall_cycles[kUnitStall + kind] += done - fetched;
    if (s.pos == s.work.steps.size() && finish_at_step_end()) {
        finish_ray(s, done);
        engine.work_changed(now);
    }
}

template <class Engine>
void Core::run_loader(Cycle t, Engine& engine) {
    size_t kind = 0;
    while (kind < size_t(kStepKinds) && load_.next[kind] >= load_.end[kind]) ++kind;
    Cache* cache = kind < size_t(kStepKinds) ? cache_by_kind_[kind] : nullptr;
    if (!cache) {  // loaded (ideal memory has nothing to load into)
        engine.loader_ready(kNeverCycle);
        return;
    }
    const uint32_t line_bytes = cache->params().line_bytes;
    const uint64_t addr = load_.next[kind] & ~uint64_t(line_bytes - 1);
    if (!engine.load_line(kind, cache, addr, line_bytes, t)) return;
    load_.next[kind] = addr + line_bytes;
    engine.loader_ready(t + 1);
}

template <class Engine>
void Core::step_fetched(size_t slot, Cycle t, const Cycle* cycles_by_level, Engine& engine) {
    Slot& s = slots_[slot];
    for (int l = 0; l < kMemLevels; ++l) stall_cycles[kL1 + l] += cycles_by_level[l];
    const int lanes = unit_lanes();
    step_done(slot, s.unit_kind, t, unit_by_kind_[s.unit_kind]->issue(t, s.unit_items, lanes), t,
              engine);
}

// Inlined into each engine's loop: the fast engine runs it once per step.
template <class Engine>
[[gnu::always_inline]] inline Cycle Core::run_slot(size_t i, Cycle t, Engine& engine) {
    Slot& s = slots_[i];
    if (!s.busy) {
        if (engine.beyond(t)) return t;  // the work queue is shared
        Cycle got = t;
        if (!ray_buffer_) {
            s.start = t;
            if (!source_->next(s.work, t)) {
                // A held ray (a sampled run's next window waits for the chip to drain): the
                // slot parks until the source wakes it.
                engine.idle(i, t, !source_->holding());
                return kRunOn;
            }
            s.pos = 0;
            s.stack.reset();
            s.stack_pos = ~size_t(0);
        } else if (s.phase != kSetUp) {
            if (s.phase == kTakeRay) {
                if (batch_.empty()) {
                    const bool any = ray_buffer_->next_batch(t, batch_treelet_, batch_);
                    engine.records_written(t);  // admissions
                    if (!any) {
                        engine.idle(i, t, ray_buffer_->finished());
                        return kRunOn;
                    }
                    if (params_.treelet_prefetch && batch_treelet_ != loaded_treelet_) {
                        load_treelet(batch_treelet_);
                        engine.start_loader(t);
                    }
                    engine.work_changed(t);  // admissions queue rays
                }
                s.handle = batch_.front();
                batch_.pop_front();
                s.treelet = batch_treelet_;
                s.start = t;
                s.phase = kReadRecord;
                // A record still being written is read once it is there: the buffer's ports
                // serve in time order.
                const Cycle written = ray_buffer_->record_written(s.handle);
                if (written > t || Engine::kTimeOrdered) {
                    engine.ready(i, std::max(t, written));
                    return kRunOn;
                }
            }
            got = ray_buffer_->read(s.handle, t, s.work, s.pos);
            s.phase = kSetUp;
            if (engine.read_record(i, got)) return kRunOn;
            stall_cycles[kRayBuffer] += got - s.start;
            // The ray waited in the buffer, its steps long out of the host's caches: start
            // loading them now, before the slot runs them. (Rays straight from the source had
            // theirs prefetched by the source a few rays ahead.)
            const char* p = reinterpret_cast<const char*>(s.work.steps.data() + s.pos);
            for (size_t b = 0; b < (s.work.steps.size() - s.pos) * sizeof(Step); b += 64)
                __builtin_prefetch(p + b);
            if (got > t || Engine::kTimeOrdered) {  // its setup issues when the record is there
                engine.ready(i, got);
                return kRunOn;
            }
        }
        s.busy = true;
        s.phase = kTakeRay;
        // A ray missing the root box has no steps and ends after its setup.
        const Cycle done = issue(got, params_.ray_setup_instructions);
        engine.ready(i, done);
        stall_cycles[kIssue] += done - got;
        if (finish_at_step_end() && s.work.steps.empty()) {
            finish_ray(s, done);
            engine.work_changed(t);
        }
        return kRunOn;
    }
    const int lanes = unit_lanes();
    if (s.unit_pending) {
        if (params_.units_shared && engine.beyond(t)) return t;
        s.unit_pending = false;
        step_done(i, s.unit_kind, t, unit_by_kind_[s.unit_kind]->issue(t, s.unit_items, lanes), t,
                  engine);
        return kRunOn;
    }
    if (s.pos == s.work.steps.size()) {  // its hit records are due (then it leaves)
        if (engine.beyond(t)) return t;
        if (const uint32_t bytes = hit_record_size(s.work)) {
            if (engine.write_entry_busy(i, t)) return kRunOn;
            count_hit_records(bytes);
            engine.post_write(hit_record_address(s.work.ray_id), bytes, t);
        }
        if (ray_buffer_) ray_buffer_->release(s.handle);
        finish_ray(s, t);
        engine.work_changed(t);  // the ray buffer's work, or a source's held ray
        engine.ready(i, t);
        return kRunOn;
    }
    if (ray_buffer_) {
        // Moving to another treelet's queue is shared work (as leaving the buffer, above).
        const uint32_t next_treelet = s.work.steps[s.pos].treelet;
        if (next_treelet != s.treelet) {
            if (engine.beyond(t)) return t;
            const Cycle done = ray_buffer_->requeue(s.handle, s.work, s.pos, next_treelet, t);
            engine.records_written(t);
            stall_cycles[kRayBuffer] += done - t;
            ray_latency_cycles += done - s.start;
            s.busy = false;
            engine.work_changed(t);
            engine.ready(i, done);
            return kRunOn;
        }
    }
    const Step& st = s.work.steps[s.pos];
    if (params_.short_stack_entries > 0 && s.stack_pos != s.pos) {
        // The stack's traffic before the step: spills posted, a refill waited for (the step
        // fetches the popped entry's node). Both reach the shared levels.
        ShortStack after = s.stack;
        const StackTraffic traffic = after.before(st);
        if (traffic.any() && engine.beyond(t)) return t;
        if (traffic.spill_entries) {
            if (engine.write_entry_busy(i, t))
                return kRunOn;  // the step waits, its stack as it was
            engine.post_write(stack_address(i, traffic.spill_from), count_stack_spill(traffic), t);
        }
        s.stack = after;
        s.stack_pos = s.pos;
        if (traffic.refill_entries) {
            count_stack_refill(traffic);
            engine.read_stack(i, stack_address(i, traffic.refill_from),
                              traffic.refill_entries * params_.stack_entry_bytes, t);
            return kRunOn;
        }
    }
    // Nodes and triangles interleave unpredictably: what differs is looked up by kind.
    const auto kind = size_t(st.kind);
    // Issue, then fetch; a fetch the engine holds back (shared work past its horizon) waits for
    // its turn with the issue port as it was.
    PortCalendar saved_port;
    uint64_t saved_issue_stall = 0;
    if (!Engine::kTimeOrdered) {
        saved_port = issue_port_;
        saved_issue_stall = issue_stall_cycles;
    }
    const Cycle issued = issue(t, instructions_by_kind_[kind]);
    Fetch fetch;  // filled in place: a copy of it stalled the step loop on store forwarding
    engine.fetch(i, st, issued, fetch);
    if (!Engine::kTimeOrdered && fetch.kind == Fetch::kHold) {
        issue_port_ = saved_port;
        issue_stall_cycles = saved_issue_stall;
        s.fetch_is_shared = true;
        return fetch.cycle;
    }
    ++s.pos;
    ++steps;
    // A packet's operations occupy every lane, active or not (lockstep SIMD).
    if (params_.packet_lanes > 0) {
        active_lanes += st.lanes;
        lane_slots += uint64_t(params_.packet_lanes);
    }
    stall_cycles[kIssue] += issued - t;
    s.unit_kind = uint8_t(kind);
    s.unit_items = st.count;
    if (fetch.kind == Fetch::kPending) return kRunOn;  // step_fetched goes on
    for (int l = 0; l < kMemLevels; ++l) stall_cycles[kL1 + l] += fetch.bd.cycles[l];
    PipelinedUnit* unit = unit_by_kind_[kind];
    // The unit serves operations in the order their data arrives. A step's fetch may arrive
    // before that of a step run earlier (a hit after a miss): an operation booked when its step
    // runs would hold the pipeline ahead of one whose data came first. One cycle slips into a
    // gap; a longer run (a packet's lanes, several triangles) waits until its data is there and
    // books then, when it is this core's earliest work (and, on a unit shared by several cores,
    // the chip's): against the time-ordered reference, booking at once cost packets +2.3% cycles.
    if (params_.units_shared || unit->span_cycles(st.count, lanes) > 1) {
        s.unit_pending = true;
        engine.ready(i, fetch.cycle);
        return kRunOn;
    }
    step_done(i, int(kind), fetch.cycle, unit->issue(fetch.cycle, st.count, lanes), t, engine);
    // (No host prefetch of the L1 sets the slot's next step will look up: it comes dozens of
    // steps later, by when the prefetched lines were mostly gone again; dropping it made replays
    // 1-5% faster on an AMD Zen 5 host.)
    return kRunOn;
}

}  // namespace rtsim

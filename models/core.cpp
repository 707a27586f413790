#include "models/core.h"

#include <algorithm>
#include <chrono>
#include <queue>
#include <utility>

namespace rtsim {

Core::Core(sc_core::sc_module_name name, const CoreParams& params, MemoryPort* l1,
           PipelinedUnit* box_unit, PipelinedUnit* triangle_unit, RayWorkSource* source,
           MemoryPort* triangle_l1)
    : sc_core::sc_module(name),
      params_(params),
      l1_(l1),
      l1_tri_(triangle_l1 ? triangle_l1 : l1),
      box_(box_unit),
      tri_(triangle_unit),
      source_(source),
      slots_(static_cast<size_t>(params.ray_slots)),
      ready_(slots_.size(), 0) {}

// Issues `instructions` instructions ready at t through the core's shared issue port
// (issue_width per cycle); returns when the step's fetch can start.
Cycle Core::issue(Cycle t, int instructions) {
    if (t > issue_cycle_) {
        issue_cycle_ = t;
        issued_in_cycle_ = 0;
    }
    for (int i = 0; i < instructions; ++i) {
        if (issued_in_cycle_ == params_.issue_width) {
            ++issue_cycle_;
            issued_in_cycle_ = 0;
        }
        ++issued_in_cycle_;
        if (i == 0) issue_stall_cycles += issue_cycle_ - t;  // waiting for the first issue slot
    }
    return issue_cycle_ + params_.issue_latency_cycles;
}

void Core::finish_ray(Slot& s, Cycle done) {
    ++rays;
    ray_latency_cycles += done - s.start;
    if (rays_series_) rays_series_->add(done, 1);
    last_cycle = std::max(last_cycle, done);
    s.busy = false;
}

Cycle Core::advance(Cycle horizon) {
    const size_t n = ready_.size();
    for (;;) {
        size_t i = 0;
        for (size_t j = 1; j < n; ++j)
            if (ready_[j] < ready_[i]) i = j;
        const Cycle t = ready_[i];
        if (t == kNeverCycle) return kNeverCycle;  // every slot retired
        Slot& s = slots_[i];
        // Private work may run ahead of the other cores: this core's own calendars still see
        // its requests in time order, because it always runs its earliest slot.
        if (!s.busy) {
            if (t > horizon) return t;  // the work queue is shared
            if (!source_->next(s.work)) {
                ready_[i] = kNeverCycle;
                continue;
            }
            // The steps were written on another host thread: start loading them now, long
            // before the slot runs them.
            const char* p = reinterpret_cast<const char*>(s.work.steps.data());
            for (size_t b = 0; b < s.work.steps.size() * sizeof(Step); b += 64)
                __builtin_prefetch(p + b);
            s.busy = true;
            s.pos = 0;
            s.start = t;
            // A ray missing the root box has no steps and ends here.
            const Cycle done = issue(t, params_.ray_setup_instructions);
            ready_[i] = done;
            stall_cycles[kIssue] += done - t;
            if (s.work.steps.empty()) finish_ray(s, done);
            continue;
        }
        const Step& st = s.work.steps[s.pos];
        const bool node = st.kind == StepKind::Node;
        MemoryPort* mem = node ? l1_ : l1_tri_;
        // Shared units order by the step's start: a unit request follows its fetch, so
        // requests from different cores reach a shared unit out of order by up to a fetch.
        if (t > horizon && params_.units_shared) return t;
        // Issue, then try the fetch as a private hit; a fetch that needs a shared level waits
        // for its turn with the issue port as it was.
        const Cycle saved_issue_cycle = issue_cycle_;
        const int saved_issued = issued_in_cycle_;
        const uint64_t saved_issue_stall = issue_stall_cycles;
        const Cycle issued =
            issue(t, node ? params_.node_step_instructions : params_.triangle_step_instructions);
        AccessBreakdown bd;
        Cycle fetched;
        if (s.fetch_is_shared || !mem->access_local(st.addr, st.size_bytes, issued, fetched, &bd)) {
            // The request leaves the core at `issued`: that is its place in the global order.
            // (Resumed, the slot is still this core's earliest and the port the same, so it
            // issues at the same cycle.)
            if (issued > horizon) {
                issue_cycle_ = saved_issue_cycle;
                issued_in_cycle_ = saved_issued;
                issue_stall_cycles = saved_issue_stall;
                s.fetch_is_shared = true;
                return issued;
            }
            fetched = mem->access(st.addr, st.size_bytes, issued, &bd);
            s.fetch_is_shared = false;
        }
        ++s.pos;
        ++steps;
        const Cycle done = node ? box_->issue(fetched, st.count) : tri_->issue(fetched);
        ready_[i] = done;
        stall_cycles[kIssue] += issued - t;
        stall_cycles[kL1] += bd.cycles[kLevelL1];
        stall_cycles[kL2] += bd.cycles[kLevelL2];
        stall_cycles[kDram] += bd.cycles[kLevelDram];
        stall_cycles[node ? kBoxUnit : kTriangleUnit] += done - fetched;
        if (s.pos == s.work.steps.size()) finish_ray(s, done);
    }
}

const char* Core::stall_name(int s) {
    static const char* const names[kStallKinds] = {"issue", "l1",       "l2",
                                                   "dram",  "box_unit", "triangle_unit"};
    return names[s];
}

void Core::register_stats(StatsRegistry& reg, const std::string& block) {
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
}

CoreScheduler::CoreScheduler(sc_core::sc_module_name name, std::vector<Core*> cores,
                             Cycle quantum_cycles)
    : sc_core::sc_module(name), cores_(std::move(cores)), quantum_cycles_(quantum_cycles) {
    SC_THREAD(run);
}

void CoreScheduler::run() {
    using Entry = std::pair<Cycle, size_t>;  // (cycle of the next shared work, core index)
    std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> ready;
    for (size_t i = 0; i < cores_.size(); ++i) ready.push({0, i});
    auto resumed = std::chrono::steady_clock::now();
    Cycle kernel_cycle = 0;
    while (!ready.empty()) {
        const Entry e = ready.top();
        ready.pop();
        if (e.first >= kernel_cycle + kKernelSyncCycles) {
            host_busy_seconds_ +=
                std::chrono::duration<double>(std::chrono::steady_clock::now() - resumed).count();
            wait(cycles_to_time(e.first - kernel_cycle));
            resumed = std::chrono::steady_clock::now();
            kernel_cycle = e.first;
        }
        // Ties go to the lower core index (the heap's order), so runs are deterministic.
        const Cycle others = ready.empty() ? kNeverCycle : ready.top().first;
        const Cycle horizon =
            others >= kNeverCycle - quantum_cycles_ ? kNeverCycle : others + quantum_cycles_;
        const Cycle next = cores_[e.second]->advance(horizon);
        if (next != kNeverCycle) ready.push({next, e.second});
    }
    host_busy_seconds_ +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - resumed).count();
}

}  // namespace rtsim

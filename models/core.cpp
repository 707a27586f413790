#include "models/core.h"

#include <algorithm>
#include <chrono>

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
      slots_(static_cast<size_t>(params.ray_slots)) {
    SC_THREAD(run);
}

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

void Core::run() {
    // Host time this process spends running (between resumptions and its next wait): summed over
    // cores it splits the simulation's host time into models and SystemC kernel.
    auto resumed = std::chrono::steady_clock::now();
    auto account = [&] {
        host_busy_seconds_ +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - resumed).count();
    };
    for (;;) {
        Slot* s = nullptr;
        for (Slot& c : slots_)
            if (!c.retired && (!s || c.ready < s->ready)) s = &c;
        if (!s) break;  // every slot retired: the queue is empty and all rays are done
        const Cycle t = s->ready;
        // Only work that touches shared state (the work queue, a level beyond the private L1)
        // must happen in global time order. Private work runs ahead of simulated time: this
        // core's own calendars still see its requests in time order, because it always runs
        // the earliest slot, so this equals waiting before every step (up to the order of
        // requests from different cores in the same cycle).
        const bool shared =
            !s->busy || params_.units_shared ||
            !(s->work.steps[s->pos].kind == StepKind::Node ? l1_ : l1_tri_)
                 ->served_locally(s->work.steps[s->pos].addr, s->work.steps[s->pos].size_bytes);
        if (shared) {
            const Cycle now = now_cycles();
            if (t > now + params_.quantum_cycles) {
                account();
                wait(cycles_to_time(t - now));
                resumed = std::chrono::steady_clock::now();
                continue;
            }
        }
        if (!s->busy) {
            if (!source_->next(s->work)) {
                s->retired = true;
                continue;
            }
            s->busy = true;
            s->pos = 0;
            s->start = t;
            s->ready =
                issue(t, params_.ray_setup_instructions);  // a ray missing the root box ends here
            stall_cycles[kIssue] += s->ready - t;
        } else {
            const Step& st = s->work.steps[s->pos++];
            ++steps;
            const bool node = st.kind == StepKind::Node;
            const Cycle issued = issue(
                t, node ? params_.node_step_instructions : params_.triangle_step_instructions);
            AccessBreakdown bd;
            const Cycle fetched =
                (node ? l1_ : l1_tri_)->access(st.addr, st.size_bytes, issued, &bd);
            s->ready = node ? box_->issue(fetched, st.count) : tri_->issue(fetched);
            stall_cycles[kIssue] += issued - t;
            stall_cycles[kL1] += bd.cycles[kLevelL1];
            stall_cycles[kL2] += bd.cycles[kLevelL2];
            stall_cycles[kDram] += bd.cycles[kLevelDram];
            stall_cycles[node ? kBoxUnit : kTriangleUnit] += s->ready - fetched;
        }
        if (s->pos == s->work.steps.size()) {
            ++rays;
            ray_latency_cycles += s->ready - s->start;
            if (rays_series_) rays_series_->add(s->ready, 1);
            last_cycle = std::max(last_cycle, s->ready);
            s->busy = false;
        }
    }
    account();
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

}  // namespace rtsim

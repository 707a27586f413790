// A fixed-function pipelined unit (ray-box or ray-triangle): `count` identical pipelines, each
// accepting one operation every `interval_cycles` and finishing it `latency_cycles` later.
// A passive resource calendar: it has no process and costs nothing while idle.
//
// Its requesters (the cores, one or several: box_unit.shared_by) reach it through its target
// socket `up`. An operation is a generic payload (TLM_IGNORE_COMMAND) with a UnitOp extension;
// b_transport books it, the annotated delay placing it at its ready cycle and returning with the
// cycle its last result is there. Both engines issue an operation at its cycle (the fast one in
// each core's time order, the accurate one in global time order), and a core issues one on
// every step, so a core asks the unit once, through the same socket, for direct access
// (DirectAccess, models/transaction.h) and then calls issue() inline: the same booking as
// b_transport's, without a payload per step.
#pragma once

#include <algorithm>
#include <array>
#include <string>
#include <systemc>
#include <vector>

#include "models/calendar.h"
#include "models/stats.h"
#include "models/timing.h"
#include "models/transaction.h"

namespace rtsim {

// Defaults: the schema's box_unit defaults (tests/sim/test_params.cpp checks they agree).
struct UnitParams {
    int count = 1;
    Cycle latency_cycles = 8;
    Cycle interval_cycles = 1;
    // Items (child boxes) one operation handles; wider work takes several operations.
    int width = 8;
    // Ideal mode: as many pipelines as needed, so an operation never waits for one.
    bool unlimited = false;
};

class PipelinedUnit;

// A unit operation's extension: `items` items `rays` times over (issue() below), and, on return,
// the cycle the last result is there.
struct UnitOp : tlm::tlm_extension<UnitOp> {
    int items = 1, rays = 1;
    Cycle done = 0;
    tlm::tlm_extension_base* clone() const override { return new UnitOp(*this); }
    void copy_from(const tlm::tlm_extension_base& other) override {
        *this = static_cast<const UnitOp&>(other);
    }
};

class PipelinedUnit : public sc_core::sc_module {
  public:
    PipelinedUnit(sc_core::sc_module_name name, const UnitParams& params);
    TargetSocket<PipelinedUnit> up;
    // Through a requester's socket bound to a unit's `up`: one operation ready at `ready`
    // (loosely timed, at or after the kernel's time); the cycle its last result is there.
    static Cycle transport(tlm::tlm_fw_transport_if<>& unit, Cycle ready, int items, int rays);
    // Issues the operations for `items` items (ceil(items / width), back to back on one pipeline)
    // that are ready at `ready`, `rays` times over (the lanes of a packet); returns the cycle
    // the last result is available. Operations need not come in `ready` order: each takes the
    // earliest cycles from `ready` on where a pipeline is free (first come, first served by
    // the time operands arrive, to within operations already booked).
    Cycle issue(Cycle ready, int items = 1, int rays = 1);
    // The operations issue() books for `items` items, `rays` times over.
    Cycle operations(int items, int rays) const;
    // The cycles those hold a pipeline.
    Cycle span_cycles(int items, int rays) const {
        return operations(items, rays) * params_.interval_cycles;
    }
    // No operation will come ready before `floor` (its users' earliest cycle).
    void follow(const TimeFloor* floor) { calendar_.follow(floor); }
    // Registers the counters under this module's name (box_unit[0].ops).
    void register_stats(StatsRegistry& reg);
    // stats.json "units" section: counters and utilisation of this unit's pipelines.
    nlohmann::json report(const ReportContext& ctx) const;
    // The same over several units (the "_total" entry).
    static nlohmann::json report_total(const std::vector<const PipelinedUnit*>& units,
                                       const ReportContext& ctx);
    void set_series(TimeSeries* busy_cycles) { busy_series_ = busy_cycles; }
    const UnitParams& params() const { return params_; }

    uint64_t ops = 0;
    uint64_t busy_cycles = 0;   // pipeline issue slots occupied, summed over pipelines
    uint64_t queue_cycles = 0;  // cycles operations waited for a free pipeline

  private:
    void b_transport(int requester, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay);
    UnitParams params_;
    ReservationCalendar calendar_;  // issue slots of the pipelines, cycle by cycle
    std::array<uint16_t, 257>
        ops_for_items_{};  // operations for 0..256 items (a BVH node's children)
    TimeSeries* busy_series_ = nullptr;
};

// Inline: a core issues to a unit on every step.
inline Cycle PipelinedUnit::operations(int items, int rays) const {
    // Operations per item count from a table: a division per operation costs more than the rest.
    const int per_ray = items >= 0 && size_t(items) < ops_for_items_.size()
                            ? ops_for_items_[size_t(items)]
                            : std::max(1, (items + params_.width - 1) / params_.width);
    return Cycle(per_ray) * Cycle(rays > 1 ? rays : 1);
}

// (Forced: the core's step loop is large enough that gcc would otherwise call it.)
[[gnu::always_inline]] inline Cycle PipelinedUnit::issue(Cycle ready, int items, int rays) {
    const Cycle n = operations(items, rays);
    // The n operations run back to back on one pipeline.
    const Cycle start =
        params_.unlimited ? ready : calendar_.reserve(ready, n * params_.interval_cycles);
    ops += n;
    busy_cycles += n * params_.interval_cycles;
    if (busy_series_) busy_series_->add(start, n * params_.interval_cycles);
    queue_cycles += start - ready;
    return start + (n - 1) * params_.interval_cycles + params_.latency_cycles;
}

}  // namespace rtsim

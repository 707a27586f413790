#include "models/unit.h"

#include <algorithm>

namespace rtsim {

PipelinedUnit::PipelinedUnit(sc_core::sc_module_name name, const UnitParams& params)
    : sc_core::sc_module(name), params_(params), calendar_(params.count) {}

Cycle PipelinedUnit::issue(Cycle ready, int items, int rays) {
    const Cycle n =
        Cycle(std::max(1, (items + params_.width - 1) / params_.width)) * Cycle(std::max(1, rays));
    // The n operations run back to back on one pipeline.
    const Cycle start =
        params_.unlimited ? ready : calendar_.reserve(ready, n * params_.interval_cycles);
    ops += n;
    busy_cycles += n * params_.interval_cycles;
    if (busy_series_) busy_series_->add(start, n * params_.interval_cycles);
    queue_cycles += start - ready;
    return start + (n - 1) * params_.interval_cycles + params_.latency_cycles;
}

void PipelinedUnit::register_stats(StatsRegistry& reg, const std::string& block) {
    reg.add(block, "ops", &ops, "operations issued");
    reg.add(block, "busy_cycles", &busy_cycles,
            "pipeline issue slots occupied, summed over pipelines");
    reg.add(block, "queue_cycles", &queue_cycles, "cycles operations waited for a free pipeline");
}

}  // namespace rtsim

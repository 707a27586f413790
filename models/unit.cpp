#include "models/unit.h"

#include <algorithm>

namespace rtsim {

PipelinedUnit::PipelinedUnit(sc_core::sc_module_name name, const UnitParams& params)
    : sc_core::sc_module(name), params_(params), calendar_(params.count) {
    const int width = std::max(1, params_.width);
    params_.width = width;
    for (int items = 0; items < int(ops_for_items_.size()); ++items)
        ops_for_items_[size_t(items)] = uint16_t(std::max(1, (items + width - 1) / width));
}

Cycle PipelinedUnit::issue(Cycle ready, int items, int rays) {
    // Operations per item count from a table: a division per operation costs more than the rest.
    const int per_ray = items >= 0 && size_t(items) < ops_for_items_.size()
                            ? ops_for_items_[size_t(items)]
                            : std::max(1, (items + params_.width - 1) / params_.width);
    const Cycle n = Cycle(per_ray) * Cycle(rays > 1 ? rays : 1);
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

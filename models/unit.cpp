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

void PipelinedUnit::register_stats(StatsRegistry& reg, const std::string& block) {
    reg.add(block, "ops", &ops, "operations issued");
    reg.add(block, "busy_cycles", &busy_cycles,
            "pipeline issue slots occupied, summed over pipelines");
    reg.add(block, "queue_cycles", &queue_cycles, "cycles operations waited for a free pipeline");
}

}  // namespace rtsim

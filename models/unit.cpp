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

void PipelinedUnit::register_stats(StatsRegistry& reg) {
    const std::string block = name();
    reg.add(block, "ops", &ops, "operations issued");
    reg.add(block, "busy_cycles", &busy_cycles,
            "pipeline issue slots occupied, summed over pipelines");
    reg.add(block, "queue_cycles", &queue_cycles, "cycles operations waited for a free pipeline");
}

nlohmann::json PipelinedUnit::report(const ReportContext& ctx) const {
    return {{"ops", ops},
            {"busy_cycles", busy_cycles},
            {"queue_cycles", queue_cycles},
            {"utilization",
             ReportContext::ratio(double(busy_cycles), double(ctx.total_cycles) * params_.count)}};
}

nlohmann::json PipelinedUnit::report_total(const std::vector<const PipelinedUnit*>& units,
                                           const ReportContext& ctx) {
    uint64_t all_ops = 0, busy = 0, pipelines = 0;
    for (const PipelinedUnit* u : units) {
        all_ops += u->ops;
        busy += u->busy_cycles;
        pipelines += uint64_t(u->params_.count);
    }
    return {{"ops", all_ops},
            {"busy_cycles", busy},
            {"utilization",
             ReportContext::ratio(double(busy), double(ctx.total_cycles) * double(pipelines))}};
}

}  // namespace rtsim

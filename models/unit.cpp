#include "models/unit.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace rtsim {

PipelinedUnit::PipelinedUnit(sc_core::sc_module_name name, const UnitParams& params)
    : sc_core::sc_module(name), up("up"), params_(params), calendar_(params.count) {
    up.register_b_transport<&PipelinedUnit::b_transport>(this);
    const int width = std::max(1, params_.width);
    params_.width = width;
    for (int items = 0; items < int(ops_for_items_.size()); ++items)
        ops_for_items_[size_t(items)] = uint16_t(std::max(1, (items + width - 1) / width));
}

void PipelinedUnit::b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
    if (answer_direct(this, gp)) return;
    UnitOp* op = gp.get_extension<UnitOp>();
    if (!op || gp.get_command() != tlm::TLM_IGNORE_COMMAND) {
        gp.set_response_status(tlm::TLM_COMMAND_ERROR_RESPONSE);
        return;
    }
    gp.set_response_status(tlm::TLM_OK_RESPONSE);
    const Cycle kernel = kernel_cycle();
    op->done = issue(kernel + delay_cycles(delay), op->items, op->rays);
    delay = cycles_delay(op->done - kernel);
}

Cycle PipelinedUnit::transport(tlm::tlm_fw_transport_if<>& unit, Cycle ready, int items, int rays) {
    UnitOp op;
    op.items = items;
    op.rays = rays;
    ExtensionCall<UnitOp> call(op);
    const Cycle kernel = kernel_cycle();
    if (ready < kernel)
        throw std::logic_error("a unit operation at " + std::to_string(ready) +
                               " came before the kernel's time " + std::to_string(kernel));
    sc_core::sc_time delay = cycles_delay(ready - kernel);
    unit.b_transport(call.gp, delay);
    if (!call.gp.is_response_ok())
        throw std::logic_error("a unit operation was refused by its target");
    return op.done;
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

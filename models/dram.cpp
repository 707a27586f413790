#include "models/dram.h"

#include <algorithm>

namespace rtsim {

Dram::Dram(sc_core::sc_module_name name, const DramParams& params)
    : sc_core::sc_module(name),
      params_(params),
      banks_(size_t(std::max(1, params.channels)) * size_t(std::max(1, params.banks))),
      buses_(size_t(std::max(1, params.channels)), BandwidthCalendar(params.bytes_per_cycle)) {}

Cycle Dram::access(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) {
    // Both stages at once: the bus is a calendar, so the transfer finds its place however
    // requests interleave; the bank serves in the order it is called (counted out of order).
    DramRequest r;
    r.addr = addr;
    r.size_bytes = size_bytes;
    bool done = false;
    Cycle t = now;
    while (!done) t = advance(r, t, done);
    if (bd) bd->cycles[kLevelDram] += t - now;
    return t;
}

Cycle Dram::write(uint64_t addr, uint32_t size_bytes, Cycle now) {
    DramRequest r;
    r.addr = addr;
    r.size_bytes = size_bytes;
    r.write = true;
    bool done = false;
    Cycle t = now;
    while (!done) t = advance(r, t, done);
    return now;
}

Cycle Dram::advance(DramRequest& r, Cycle now, bool& done) {
    const uint64_t block = r.addr / params_.row_bytes;
    const auto channels = uint64_t(buses_.size());
    const uint64_t channel = block % channels;
    if (r.stage == 0) {
        r.arrived = now;
        const uint64_t bank_index = (block / channels) % uint64_t(params_.banks);
        const uint64_t row = block / (channels * uint64_t(params_.banks));
        Bank& bank = banks_[channel * uint64_t(params_.banks) + bank_index];
        bank_out_of_order += now < bank.latest_request;
        bank.latest_request = std::max(bank.latest_request, now);
        const Cycle start = std::max(now, bank.ready);
        Cycle column = start;  // when the column (read) command issues
        if (!bank.open) {
            column += params_.t_rcd_cycles;
            ++row_empty;
        } else if (bank.open_row != row) {
            column += params_.t_rp_cycles + params_.t_rcd_cycles;
            ++row_conflicts;
        } else {
            ++row_hits;
        }
        bank.open = true;
        bank.open_row = row;
        bank.ready = column + params_.t_ccd_cycles;
        queue_cycles += start - now;
        r.stage = 1;
        done = false;
        return column + params_.t_cas_cycles;  // the data is ready for the bus
    }
    const Cycle data_ready = now;
    const uint32_t moved = uint32_t(bytes_moved(r.size_bytes));
    // Reads from different banks reach the bus out of order: the bus is a calendar.
    const auto [bus_start, bus_end] = buses_[channel].transfer(data_ready, moved);
    reads += !r.write;
    writes += r.write;
    bytes += moved;
    write_bytes += r.write ? moved : 0;
    if (bytes_series_) bytes_series_->add(bus_start, moved);
    busy_cycles += buses_[channel].idle_cycles(moved);
    queue_cycles += bus_start - data_ready;
    r.stage = 2;
    done = true;
    // Data is usable once its last byte has crossed the bus and the controller latency passed.
    return bus_end + params_.latency_cycles;
}

void Dram::register_stats(StatsRegistry& reg) {
    const std::string block = name();
    reg.add(block, "reads", &reads, "read requests");
    reg.add(block, "writes", &writes, "write requests");
    reg.add(block, "bytes", &bytes, "bytes read and written");
    reg.add(block, "write_bytes", &write_bytes, "bytes written");
    reg.add(block, "row_hits", &row_hits, "requests to the open row of their bank");
    reg.add(block, "row_empty", &row_empty, "requests to a bank with no open row");
    reg.add(block, "row_conflicts", &row_conflicts, "requests that closed another row first");
    reg.add(block, "busy_cycles", &busy_cycles, "cycles the buses were transferring");
    reg.add(block, "queue_cycles", &queue_cycles, "cycles requests waited for a bank or a bus");
    reg.add(block, "bank_out_of_order", &bank_out_of_order,
            "requests a bank served after one that arrived later in simulated time");
}

nlohmann::json Dram::report(const ReportContext& ctx) const {
    using R = ReportContext;
    return {{"bytes", bytes},
            {"gbps", ctx.gbps(bytes)},
            {"write_bytes", write_bytes},
            {"busy_cycles", busy_cycles},
            {"row_hits", row_hits},
            {"row_empty", row_empty},
            {"row_conflicts", row_conflicts},
            {"row_hit_rate", R::ratio(double(row_hits), double(reads + writes))},
            {"utilization",
             R::ratio(double(busy_cycles), double(ctx.total_cycles) * params_.channels)}};
}

namespace {
std::unique_ptr<DramModel> make_simple(const char* module_name, const DramParams& p) {
    return std::make_unique<Dram>(module_name, p);
}
}  // namespace

DramPort::DramPort(sc_core::sc_module_name name, DramModel& model)
    : sc_core::sc_module(name), up("up"), model_(model) {
    up.register_nb_transport_fw<&DramPort::nb_transport_fw>(this);
    up.register_b_transport<&DramPort::b_transport>(this);
}

// A request reaches the DRAM at the annotated cycle: its first stage runs then, within the call
// or, when it is queued, as a stage of its own.
tlm::tlm_sync_enum DramPort::nb_transport_fw(int id, tlm::tlm_generic_payload& gp,
                                             tlm::tlm_phase& phase, sc_core::sc_time& delay) {
    const Cycle at = stages_->now() + delay_cycles(delay);
    if (gp.is_write()) {
        DramRequest request;
        request.addr = gp.get_address();
        request.size_bytes = gp.get_data_length();
        request.write = true;
        const uint32_t w = writes_.add(request);
        if (memory_request(gp).queued)
            stages_->schedule(at, StageQueue::kMemoryOrder, this, kWriteStage, w);
        else
            write_stage(w, at);
        gp.set_response_status(tlm::TLM_OK_RESPONSE);
        return tlm::TLM_COMPLETED;
    }
    memory_request(gp).push_route(id);
    Read read;
    read.request.addr = gp.get_address();
    read.request.size_bytes = gp.get_data_length();
    read.gp = &gp;
    const uint32_t r = reads_.add(read);
    if (memory_request(gp).queued)
        stages_->schedule(at, StageQueue::kMemoryOrder, this, kReadStage, r);
    else
        read_stage(r, at);
    phase = tlm::END_REQ;
    return tlm::TLM_UPDATED;
}

void DramPort::run_stage(uint32_t kind, uint32_t id, uint32_t, Cycle t) {
    switch (kind) {
        case kReadStage:
            read_stage(id, t);
            break;
        case kWriteStage:
            write_stage(id, t);
            break;
        case kAnswerStage: {
            tlm::tlm_generic_payload& gp = *reads_[id].gp;
            reads_.remove(id);
            gp.set_response_status(tlm::TLM_OK_RESPONSE);
            tlm::tlm_phase phase = tlm::BEGIN_RESP;
            sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
            up[memory_request(gp).pop_route()]->nb_transport_bw(gp, phase, delay);
            break;
        }
    }
}

void DramPort::read_stage(uint32_t r, Cycle t) {
    bool done = false;
    const Cycle next = model_.advance(reads_[r].request, t, done);
    if (!done) {
        stages_->schedule(next, StageQueue::kMemoryOrder, this, kReadStage, r);
        return;
    }
    memory_request(*reads_[r].gp).timeline.add(next, kLevelDram);
    // The data is there at `next`: the fill it answers completes then, first in its cycle.
    stages_->schedule(next, StageQueue::kFillOrder, this, kAnswerStage, r);
}

void DramPort::write_stage(uint32_t w, Cycle t) {
    bool done = false;
    const Cycle next = model_.advance(writes_[w], t, done);
    if (done)
        writes_.remove(w);
    else
        stages_->schedule(next, StageQueue::kMemoryOrder, this, kWriteStage, w);
}

RTSIM_REGISTER(DramModelEntry,
               {"simple",
                "open-page banks (tRCD, tCAS, tRP, tCCD), a bus per channel as the bandwidth cap, "
                "a fixed controller latency",
                {"latency_cycles", "bytes_per_cycle", "channels", "banks", "row_bytes",
                 "burst_bytes", "t_rcd_cycles", "t_cas_cycles", "t_ccd_cycles", "t_rp_cycles"},
                &make_simple})

}  // namespace rtsim

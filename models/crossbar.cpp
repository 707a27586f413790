#include "models/crossbar.h"

#include <algorithm>

namespace rtsim {

Crossbar::Crossbar(sc_core::sc_module_name name, double bytes_per_cycle, TargetSocketBase* below)
    : sc_core::sc_module(name),
      up("up"),
      down("down"),
      link_(bytes_per_cycle),
      write_link_(bytes_per_cycle) {
    if (below) down.bind(*below);
    up.register_nb_transport_fw<&Crossbar::nb_transport_fw>(this);
    up.register_b_transport<&Crossbar::b_transport>(this);
    down.register_nb_transport_bw(this, &Crossbar::nb_transport_bw);
}

tlm::tlm_sync_enum Crossbar::nb_transport_fw(int id, tlm::tlm_generic_payload& gp,
                                             tlm::tlm_phase& phase, sc_core::sc_time& delay) {
    memory_request(gp).push_route(id);
    if (gp.is_write()) {
        const Cycle now = stages_->now();
        delay = cycles_delay(carry_up(now + delay_cycles(delay), gp.get_data_length()) - now);
    }
    const tlm::tlm_sync_enum status = down->nb_transport_fw(gp, phase, delay);
    if (status == tlm::TLM_COMPLETED) memory_request(gp).pop_route();
    return status;
}

// The L2's answer: a read's line takes the link, a write's acceptance goes up at once.
tlm::tlm_sync_enum Crossbar::nb_transport_bw(tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                             sc_core::sc_time&) {
    if (gp.is_write()) {
        pass_up(gp);
    } else {
        const Cycle end = carry(stages_->now(), gp.get_data_length());
        memory_request(gp).timeline.add(end, kLevelCrossbar);
        const uint32_t c = crossing_.add(&gp);
        // Crossed at `end`: a fill completes then, first in its cycle.
        stages_->schedule(end, StageQueue::kFillOrder, this, 0, c);
    }
    phase = tlm::END_RESP;
    return tlm::TLM_COMPLETED;
}

void Crossbar::run_stage(uint32_t, uint32_t c, uint32_t, Cycle) {
    tlm::tlm_generic_payload& gp = *crossing_[c];
    crossing_.remove(c);
    pass_up(gp);
}

void Crossbar::pass_up(tlm::tlm_generic_payload& gp) {
    tlm::tlm_phase phase = tlm::BEGIN_RESP;
    sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
    up[memory_request(gp).pop_route()]->nb_transport_bw(gp, phase, delay);
}

Cycle Crossbar::carry_up(Cycle ready, uint32_t size_bytes) {
    const auto [first, end] = write_link_.transfer(ready, size_bytes);
    ++write_transfers;
    write_bytes += size_bytes;
    queue_cycles += first - ready;
    return end;
}

Cycle Crossbar::access(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) {
    // Requests are small and cross at once; the line crosses when the L2 returns it (a line the
    // L2 fetches from DRAM holds no bandwidth while it waits).
    return carry_back(below_.read(addr, size_bytes, now, bd), size_bytes, bd);
}

Cycle Crossbar::carry_back(Cycle returned, uint32_t size_bytes, AccessBreakdown* bd) {
    const Cycle end = carry(returned, size_bytes);
    if (bd) bd->cycles[kLevelCrossbar] += end - returned;  // waiting for the link, crossing
    return end;
}

// A timed read passes through as it came (a request crosses at once) and its answer takes the
// link: access() without a payload of its own.
void Crossbar::b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
    MemoryRequest& r = memory_request(gp);
    if (r.lt != MemoryRequest::Lt::kTimed || gp.is_write()) {
        serve_loosely_timed(*this, gp, delay);
        return;
    }
    below_.forward(gp, delay);
    r.lt_done = carry_back(r.lt_done, gp.get_data_length(), r.breakdown);
    delay = cycles_delay(r.lt_done - r.lt_kernel);
}

Cycle Crossbar::carry(Cycle returned, uint32_t size_bytes) {
    const auto [first, end] = link_.transfer(returned, size_bytes);
    ++transfers;
    bytes += size_bytes;
    busy_cycles += link_.idle_cycles(size_bytes);
    queue_cycles += first - returned;
    return end;
}

void Crossbar::register_stats(StatsRegistry& reg) {
    const std::string block = name();
    reg.add(block, "transfers", &transfers, "line transfers from the L2 to the L1s");
    reg.add(block, "bytes", &bytes, "bytes moved");
    reg.add(block, "busy_cycles", &busy_cycles, "cycles spent transferring");
    reg.add(block, "queue_cycles", &queue_cycles, "cycles requests waited for bandwidth");
    reg.add(block, "write_transfers", &write_transfers, "writes from the cores to the L2");
    reg.add(block, "write_bytes", &write_bytes, "bytes written towards the L2");
}

nlohmann::json Crossbar::report(const ReportContext& ctx) const {
    return {{"bytes", bytes},
            {"gbps", ctx.gbps(bytes)},
            {"write_bytes", write_bytes},
            {"queue_cycles", queue_cycles},
            {"utilization", ReportContext::ratio(double(busy_cycles), double(ctx.total_cycles))}};
}

}  // namespace rtsim

// The on-chip network between the cores' L1s and the shared L2: a crossbar with a per-cycle
// bandwidth, carrying lines from the L2 to the L1s. A request (a few bytes) crosses at once; its
// line takes the link when the L2 returns it, as a fluid share of each cycle's bytes (so the cap
// holds however returns interleave, and a line returned early slips into gaps left by later
// ones). Waiting for the link and crossing it are charged to the crossbar in stall attribution.
#pragma once

#include <string>
#include <systemc>

#include "models/calendar.h"
#include "models/stats.h"
#include "models/timing.h"
#include "models/transaction.h"

namespace rtsim {

class Crossbar final : public sc_core::sc_module, public MemoryPort, private StageHandler {
  public:
    // `below`, when given, is bound to `down` here (the L2's target socket).
    Crossbar(sc_core::sc_module_name name, double bytes_per_cycle, TargetSocketBase* below);
    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* breakdown = nullptr) override;
    void register_stats(StatsRegistry& reg);  // under this module's name
    // stats.json "bandwidth.crossbar": bytes, GB/s, queueing and utilisation.
    nlohmann::json report(const ReportContext& ctx) const;
    void follow(const TimeFloor* floor) {
        link_.follow(floor);
        write_link_.follow(floor);
    }
    // A line of `size_bytes` the L2 returned at `returned` takes the link; returns the cycle it
    // has crossed. (access() is the L2 access and this; the time-ordered reference calls it
    // alone, at the cycle the L2 returns the line.)
    Cycle carry(Cycle returned, uint32_t size_bytes);
    // carry() for a read's answer, its crossing charged to the crossbar in `bd`.
    Cycle carry_back(Cycle returned, uint32_t size_bytes, AccessBreakdown* bd);
    void warm(uint64_t addr, uint32_t size_bytes) override { below_.warm(addr, size_bytes); }
    // Writes cross the other way, on a link of their own (a crossbar's request and response
    // networks are separate), then reach the L2; returns the cycle the L2 accepted the write.
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        return below_.write(addr, size_bytes, carry_up(now, size_bytes));
    }
    void warm_write(uint64_t addr, uint32_t size_bytes) override {
        below_.warm(addr, size_bytes, true);
    }
    // Write data of `size_bytes` ready at `ready` crosses towards the L2; returns when it has.
    Cycle carry_up(Cycle ready, uint32_t size_bytes);

    // The time-ordered engine's side (models/transaction.h): a read request crosses at once and
    // goes on through `down`; its answer takes the link (carry) when the L2 gives it and is
    // passed up at the cycle it has crossed. A write takes the write link (carry_up) first.
    // The fast engine's b_transport is access(), write() or warm(), on through `down` alike.
    TargetSocket<Crossbar> up;
    InitiatorSocket<Crossbar> down;
    void set_stage_queue(StageQueue* queue) { stages_ = queue; }

    uint64_t transfers = 0;
    uint64_t bytes = 0;
    uint64_t busy_cycles = 0;                       // transfer time, rounded up per transfer
    uint64_t queue_cycles = 0;                      // cycles requests waited for bandwidth
    uint64_t write_transfers = 0, write_bytes = 0;  // towards the L2

  private:
    void run_stage(uint32_t kind, uint32_t id, uint32_t k, Cycle t) override;
    tlm::tlm_sync_enum nb_transport_fw(int id, tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time& delay);
    tlm::tlm_sync_enum nb_transport_bw(tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time& delay);
    void pass_up(tlm::tlm_generic_payload& gp);
    void b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay);
    StageQueue* stages_ = nullptr;
    IdPool<tlm::tlm_generic_payload*> crossing_;  // answers on the link, by stage id
    BandwidthCalendar link_;
    BandwidthCalendar write_link_;  // write data, from the cores to the L2
    LtPort below_{down};
};

}  // namespace rtsim

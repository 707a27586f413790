// DRAM models, registered by name (dram.model; `rtsim list`): DramModel is what the L2 and the
// chip see of one. This file also holds the "simple" model:
// channels of banks with row buffers (open-page policy) and a data bus per channel.
// A read waits for its bank, pays tCAS on a row hit, tRCD + tCAS on an empty bank, and
// tRP + tRCD + tCAS on a row conflict; a bank takes its next column command tCCD after the last
// (so reads to an open row pipeline); the data then crosses the channel's bus at
// bytes_per_cycle (the bandwidth cap); latency_cycles covers the controller and interconnect.
// Passive, like the caches: each bank knows the cycle it next takes a command (a bank serves
// requests in the order they come, as its open row is state); each bus is a calendar, since
// reads from different banks reach it out of order.
#pragma once

#include <memory>
#include <string>
#include <systemc>
#include <vector>

#include "models/calendar.h"
#include "models/registry.h"
#include "models/stats.h"
#include "models/timing.h"
#include "models/transaction.h"

namespace rtsim {

// Defaults: the schema's (tests/sim/test_params.cpp checks they agree).
struct DramParams {
    Cycle latency_cycles = 150;
    double bytes_per_cycle = 16.0;  // per channel
    int channels = 2;
    int banks = 8;              // per channel
    uint32_t row_bytes = 2048;  // row-buffer size; consecutive rows interleave channels, then banks
    uint32_t burst_bytes = 64;  // reads are whole bursts
    Cycle t_rcd_cycles = 14, t_cas_cycles = 14, t_rp_cycles = 14;
    Cycle t_ccd_cycles = 4;  // column command to column command in one bank (reads pipeline)
    // The command-level model (dram.model = command): a device preset, its controller policy,
    // and the chip's clock (its cycles convert to the device's).
    std::string device = "DDR4_8Gb_x8_3200";
    std::string page_policy = "open";
    std::string address_mapping;  // empty: the device's
    bool refresh = true;
    // The TLM-2.0 stand-in (dram.model = tlm): the shared library that makes its target.
    std::string tlm_target;
    double chip_clock_ghz = 0;  // set by chip assembly from clock_ghz
};

// A request moving through a DRAM model stage by stage (DramModel::advance): what the model
// keeps between stages is its own (`state`).
struct DramRequest {
    uint64_t addr = 0;
    uint32_t size_bytes = 0;
    Cycle arrived = 0;
    bool write = false;  // a posted write: done once accepted, nothing waits for its data
    int stage = 0;       // 0: not yet arrived
    uint64_t state[4] = {0, 0, 0, 0};
};

// A DRAM model: a memory level that owns its counters and its report section, and may run
// requests out of time order but never behind the time floor it follows.
class DramModel : public MemoryPort {
  public:
    // Split-phase use (the time-ordered reference, sim.fidelity = accurate): runs the request's
    // next stage at `now` (its arrival, then each cycle this returned) and returns the cycle of
    // its next stage; once the last stage has run, sets `done` and returns the cycle the data is
    // usable. A model whose stages all run in time order serves every bank and bus in order.
    virtual Cycle advance(DramRequest& request, Cycle now, bool& done) = 0;
    virtual void register_stats(StatsRegistry& reg) = 0;  // under its module's name
    // stats.json "bandwidth.dram": bytes and GB/s, row-buffer figures, utilisation.
    virtual nlohmann::json report(const ReportContext& ctx) const = 0;
    // Requests served after one that arrived later in simulated time (0 for a model that serves
    // in time order by construction).
    virtual uint64_t out_of_order_requests() const = 0;
    // The bytes a request of size_bytes moves on the bus, counted in "bytes" (whole bursts).
    virtual uint64_t bytes_moved(uint32_t size_bytes) const = 0;
    virtual void set_series(TimeSeries* bytes) = 0;  // bytes moved per window
    virtual void follow(const TimeFloor* floor) = 0;
};

// The chip's way into a DRAM model (models/transaction.h). The time-ordered engine's requests
// (nb_transport_fw) run their stages (DramModel::advance) at their cycles on the StageQueue, and
// a read is answered when its data is usable; a posted write is accepted on arrival (the call
// returns TLM_COMPLETED) and its stages still run, each at its cycle. The fast engine's
// (b_transport) are the model's MemoryPort calls.
class DramPort final : public sc_core::sc_module, private StageHandler {
  public:
    DramPort(sc_core::sc_module_name name, DramModel& model);
    TargetSocket<DramPort> up;
    void set_stage_queue(StageQueue* queue) { stages_ = queue; }

  private:
    void b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
        serve_loosely_timed(model_, gp, delay);
    }
    enum Stage : uint32_t { kReadStage, kAnswerStage, kWriteStage };
    void run_stage(uint32_t kind, uint32_t id, uint32_t k, Cycle t) override;
    tlm::tlm_sync_enum nb_transport_fw(int id, tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time& delay);
    void read_stage(uint32_t r, Cycle t);
    void write_stage(uint32_t w, Cycle t);
    struct Read {
        DramRequest request;
        tlm::tlm_generic_payload* gp = nullptr;
    };
    DramModel& model_;
    StageQueue* stages_ = nullptr;
    IdPool<Read> reads_;
    IdPool<DramRequest> writes_;
};

struct DramModelEntry {
    static constexpr const char* kKind = "dram_model";
    std::string name, description;
    std::vector<std::string> params;
    std::unique_ptr<DramModel> (*make)(const char* module_name, const DramParams&) = nullptr;
};
using DramModelRegistry = Registry<DramModelEntry>;

class Dram final : public sc_core::sc_module, public DramModel {
  public:
    Dram(sc_core::sc_module_name name, const DramParams& params);
    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* breakdown = nullptr) override;
    // A write takes its bank and the bus as a read does (write data crosses the same bus), and
    // is accepted on arrival.
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override;
    // Two stages: the bank (at arrival), then the channel's bus (when the data is ready).
    Cycle advance(DramRequest& request, Cycle now, bool& done) override;
    void register_stats(StatsRegistry& reg) override;
    nlohmann::json report(const ReportContext& ctx) const override;
    uint64_t out_of_order_requests() const override { return bank_out_of_order; }
    uint64_t bytes_moved(uint32_t size_bytes) const override {
        return std::max<uint64_t>(1, (size_bytes + params_.burst_bytes - 1) / params_.burst_bytes) *
               params_.burst_bytes;
    }
    void set_series(TimeSeries* bytes) override { bytes_series_ = bytes; }
    void follow(const TimeFloor* floor) override {
        for (auto& bus : buses_) bus.follow(floor);
    }
    const DramParams& params() const { return params_; }

    uint64_t reads = 0, writes = 0;
    uint64_t bytes = 0;        // read and written
    uint64_t write_bytes = 0;  // of which written
    uint64_t row_hits = 0, row_empty = 0, row_conflicts = 0;
    uint64_t busy_cycles = 0;   // cycles the buses spent transferring (rounded up per access)
    uint64_t queue_cycles = 0;  // cycles requests waited for a bank or a bus
    // Requests a bank served after a request that arrived later in simulated time (a bank
    // keeps one next-free cycle and its open row, so it serves in arrival order to the model).
    uint64_t bank_out_of_order = 0;

  private:
    struct Bank {
        uint64_t open_row = 0;
        bool open = false;
        Cycle ready = 0;           // next cycle it accepts a command
        Cycle latest_request = 0;  // the latest arrival it has served
    };
    DramParams params_;
    std::vector<Bank> banks_;               // channels * banks
    std::vector<BandwidthCalendar> buses_;  // per channel
    TimeSeries* bytes_series_ = nullptr;
};

}  // namespace rtsim

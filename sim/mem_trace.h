// `rtsim run --mem-trace FILE`: the request stream that reaches DRAM, in DRAMsim3's trace
// format ("0x<address> READ|WRITE <cycle>", a line per burst, in time order), so the same requests
// can be run through rtsim dram, DRAMsim3 or Ramulator.
#pragma once

#include <string>
#include <vector>

#include "models/dram.h"

namespace rtsim {

// Sits between the L2 and the DRAM model, forwarding everything and keeping each request's
// arrival (functional warming is not traffic and is not kept).
class MemTraceRecorder final : public DramModel {
  public:
    explicit MemTraceRecorder(DramModel& inner) : inner_(inner) {}

    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* breakdown = nullptr) override {
        keep(addr, size_bytes, now);
        return inner_.access(addr, size_bytes, now, breakdown);
    }
    void warm(uint64_t addr, uint32_t size_bytes) override { inner_.warm(addr, size_bytes); }
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        keep(addr, size_bytes, now, true);
        return inner_.write(addr, size_bytes, now);
    }
    Cycle advance(DramRequest& r, Cycle now, bool& done) override {
        if (r.stage == 0) keep(r.addr, r.size_bytes, now, r.write);
        return inner_.advance(r, now, done);
    }
    void register_stats(StatsRegistry& reg) override { inner_.register_stats(reg); }
    nlohmann::json report(const ReportContext& ctx) const override { return inner_.report(ctx); }
    uint64_t out_of_order_requests() const override { return inner_.out_of_order_requests(); }
    uint64_t bytes_moved(uint32_t size_bytes) const override {
        return inner_.bytes_moved(size_bytes);
    }
    void set_series(TimeSeries* bytes) override { inner_.set_series(bytes); }
    void follow(const TimeFloor* floor) override { inner_.follow(floor); }

    // Writes the trace: requests sorted by arrival (the fast model meets them slightly out of
    // order), split into bursts of `burst_bytes`, cycles converted to the memory's clock
    // (device_tck_ns; 0: chip cycles). Written whole or not at all.
    void save(const std::string& path, uint32_t burst_bytes, double chip_clock_ghz,
              double device_tck_ns) const;
    size_t requests() const { return kept_.size(); }

  private:
    struct Request {
        uint64_t addr;
        uint32_t size_bytes;
        Cycle cycle;
        bool write;
    };
    void keep(uint64_t addr, uint32_t size_bytes, Cycle now, bool write = false) {
        kept_.push_back({addr, size_bytes, now, write});
    }
    DramModel& inner_;
    std::vector<Request> kept_;
};

}  // namespace rtsim

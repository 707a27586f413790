// DRAM as one channel: fixed access latency plus a transfer time at `bytes_per_cycle`, with
// transfers serialised on the channel (the bandwidth cap). Row buffers and banks come later.
#pragma once

#include <string>
#include <systemc>

#include "models/stats.h"
#include "models/timing.h"

namespace rtsim {

struct DramParams {
    Cycle latency_cycles = 200;
    double bytes_per_cycle = 32.0;
};

class Dram : public sc_core::sc_module, public MemoryPort {
  public:
    Dram(sc_core::sc_module_name name, const DramParams& params);
    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* breakdown = nullptr) override;
    void register_stats(StatsRegistry& reg, const std::string& block);
    void set_series(TimeSeries* bytes) { bytes_series_ = bytes; }
    const DramParams& params() const { return params_; }

    uint64_t reads = 0;
    uint64_t bytes = 0;
    uint64_t busy_cycles = 0;   // cycles the channel spent transferring (rounded up per access)
    uint64_t queue_cycles = 0;  // cycles requests waited for the channel

  private:
    DramParams params_;
    double next_free_ = 0.0;
    TimeSeries* bytes_series_ =
        nullptr;  // fractional, so that e.g. 12.8 bytes per cycle is exact over time
};

}  // namespace rtsim

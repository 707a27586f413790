// Test double: a memory level with a fixed latency and no contention.
#pragma once

#include <vector>

#include "models/timing.h"

namespace rtsim::test {

class FixedLatencyMemory : public MemoryPort {
  public:
    explicit FixedLatencyMemory(Cycle latency) : latency_(latency) {}
    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* bd = nullptr) override {
        addrs.push_back(addr);
        times.push_back(now);
        bytes += size_bytes;
        if (bd) bd->cycles[level] += latency_;
        return now + latency_;
    }
    // Posted writes: recorded apart from reads, accepted `write_latency` after they come.
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        write_addrs.push_back(addr);
        write_times.push_back(now);
        write_bytes += size_bytes;
        return now + write_latency;
    }
    Cycle write_latency = 0;
    std::vector<uint64_t> write_addrs;
    std::vector<Cycle> write_times;
    uint64_t write_bytes = 0;
    std::vector<uint64_t> addrs;
    std::vector<Cycle> times;  // cycle of each request, in arrival order
    uint64_t bytes = 0;
    int level = kLevelDram;  // where its latency is attributed

  private:
    Cycle latency_;
};

}  // namespace rtsim::test

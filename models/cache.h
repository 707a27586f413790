// A set-associative, read-only (BVH data is never written during traversal), LRU cache.
// Loosely timed: a hit costs `hit_latency_cycles`; a miss adds the next level's latency.
// A line stays "filling" until its data arrives, so a second access to it waits for the same
// fill instead of issuing another (miss merging). A miss holds one of `mshrs` registers until its
// data returns; with all of them busy, the next miss waits (Little's law bounds the bandwidth).
#pragma once

#include <string>
#include <systemc>
#include <vector>

#include "models/stats.h"
#include "models/timing.h"

namespace rtsim {

struct CacheParams {
    uint64_t size_bytes = 32 * 1024;
    int ways = 4;
    uint32_t line_bytes = 64;
    Cycle hit_latency_cycles = 4;
    int mshrs = 0;  // misses in flight at once (miss status holding registers); 0: unlimited
    enum class Replacement : uint8_t { Lru, Fifo, Random };
    Replacement replacement = Replacement::Lru;
    int banks = 1;  // line-interleaved banks, each starting one lookup per cycle

    uint64_t sets() const { return size_bytes / (uint64_t(ways) * line_bytes); }
};

// Ideal memory: every access is an L1 hit (an upper bound on what caches can give).
class IdealMemory : public MemoryPort {
  public:
    explicit IdealMemory(Cycle hit_latency_cycles) : latency_(hit_latency_cycles) {}
    Cycle access(uint64_t, uint32_t, Cycle now, AccessBreakdown* bd = nullptr) override {
        if (bd) bd->cycles[kLevelL1] += latency_;
        return now + latency_;
    }
    bool served_locally(uint64_t, uint32_t) const override { return true; }

  private:
    Cycle latency_;
};

class Cache : public sc_core::sc_module, public MemoryPort {
  public:
    // `level` names the level for stall attribution (kLevelL1, kLevelL2).
    Cache(sc_core::sc_module_name name, const CacheParams& params, MemoryPort* next_level,
          int level = kLevelL1);
    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* breakdown = nullptr) override;
    // Every line of the request is present (or already being filled): a hit, no next-level access.
    bool served_locally(uint64_t addr, uint32_t size_bytes) const override;
    void register_stats(StatsRegistry& reg, const std::string& block);
    void set_series(TimeSeries* fill_bytes) { fill_series_ = fill_bytes; }
    const CacheParams& params() const { return params_; }

    uint64_t accesses = 0;  // line lookups (a request spanning two lines counts two)
    uint64_t hits = 0;
    uint64_t misses = 0;
    uint64_t merged_misses = 0;         // hits on a line whose fill was still in flight
    uint64_t bytes_requested = 0;       // bytes delivered to the level above
    uint64_t fill_bytes = 0;            // bytes read from the level below
    uint64_t mshr_wait_cycles = 0;      // cycles misses waited for a free MSHR
    uint64_t bank_conflict_cycles = 0;  // cycles lookups waited for their bank

  private:
    // Tags apart from the rest (structure of arrays): a lookup scans one set's tags, a few
    // contiguous words, and touches the rest only on a hit or a fill.
    static constexpr uint64_t kNoTag = ~uint64_t(0);  // no line address reaches this
    struct WayState {
        uint64_t last_use = 0;
        Cycle ready = 0;  // cycle the line's data is present
    };
    Cycle access_line(uint64_t line_addr, Cycle now, AccessBreakdown* breakdown);
    bool present(uint64_t line_addr) const;

    CacheParams params_;
    MemoryPort* next_;
    int level_;
    std::vector<Cycle> mshr_free_;          // per MSHR: cycle its miss completes
    std::vector<Cycle> bank_free_;          // per bank: next cycle it starts a lookup
    uint64_t rng_ = 0x9E3779B97F4A7C15ull;  // random replacement: deterministic xorshift state
    TimeSeries* fill_series_ = nullptr;
    std::vector<uint64_t> tags_;   // sets * ways, set-major; kNoTag when invalid
    std::vector<WayState> state_;  // same indexing
    uint64_t bank_mask_ = 0;
    uint64_t set_mask_;
    uint32_t line_shift_;
    uint64_t use_clock_ = 0;
};

}  // namespace rtsim

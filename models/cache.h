// A set-associative, read-only (BVH data is never written during traversal), LRU cache.
// Loosely timed: a hit costs `hit_latency_cycles`; a miss adds the next level's latency.
// A line stays "filling" until its data arrives, so a second access to it waits for the same
// fill instead of issuing another (miss merging). A miss holds one of `mshrs` registers until its
// data returns; with all of them busy, the next miss waits (Little's law bounds the bandwidth).
#pragma once

#include <algorithm>
#include <string>
#include <systemc>
#include <utility>
#include <vector>

#include "models/calendar.h"
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
    bool access_local(uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
                      AccessBreakdown* bd = nullptr) override {
        ready = access(addr, size_bytes, now, bd);
        return true;
    }

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
    void expect(uint64_t addr, uint32_t size_bytes) const override {
        const auto [first, last] = line_range(addr, size_bytes);
        for (uint64_t line = first; line <= last; ++line) __builtin_prefetch(tags(set_of(line)));
    }
    // Served locally when every line of the request is present (or already being filled).
    bool access_local(uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
                      AccessBreakdown* breakdown = nullptr) override;
    void register_stats(StatsRegistry& reg, const std::string& block);
    void set_series(TimeSeries* fill_bytes) { fill_series_ = fill_bytes; }
    const CacheParams& params() const { return params_; }
    // The earliest cycle a lookup may still come at (the requesters' floor).
    void follow(const TimeFloor* floor) {
        for (auto& bank : banks_) bank.follow(floor);
    }

    uint64_t accesses = 0;  // line lookups (a request spanning two lines counts two)
    uint64_t hits = 0;
    uint64_t misses = 0;
    uint64_t merged_misses = 0;         // hits on a line whose fill was still in flight
    uint64_t bytes_requested = 0;       // bytes delivered to the level above
    uint64_t fill_bytes = 0;            // bytes read from the level below
    uint64_t mshr_wait_cycles = 0;      // cycles misses waited for a free MSHR
    uint64_t bank_conflict_cycles = 0;  // cycles lookups waited for their bank

  private:
    // A set's tags and fill cycles share one block (one host cache line for 4 ways), so a hit
    // touches one line; replacement ages live apart, read only to choose a victim.
    static constexpr uint64_t kNoTag = ~uint64_t(0);  // no line address reaches this
    uint64_t set_of(uint64_t line_addr) const { return line_addr & set_mask_; }
    uint64_t* tags(uint64_t set) { return set_block_ + set * 2 * uint64_t(params_.ways); }
    const uint64_t* tags(uint64_t set) const {
        return set_block_ + set * 2 * uint64_t(params_.ways);
    }
    // First and last line address a request touches.
    std::pair<uint64_t, uint64_t> line_range(uint64_t addr, uint32_t size_bytes) const {
        return {addr >> line_shift_, (addr + std::max<uint32_t>(size_bytes, 1) - 1) >> line_shift_};
    }
    Cycle* fill_ready(uint64_t set) { return tags(set) + params_.ways; }
    // The way holding `line_addr` in `set`, or -1. Scans every way without an early exit: a
    // data-dependent exit mispredicts on most lookups, the extra compares cost less.
    int find_way(uint64_t set, uint64_t line_addr) {
        const uint64_t* t = tags(set);
        int found = -1;
        for (int w = 0; w < params_.ways; ++w) found = t[w] == line_addr ? w : found;
        return found;
    }
    void replace_earliest_mshr(Cycle ready);
    // Counts the lookups of lines first..last and waits for their banks, each of which reads
    // its lines of the request back to back; done[k]: the cycle line first + k is looked up.
    void look_up(uint64_t first, uint64_t last, Cycle now, Cycle* done);
    // A hit's bookkeeping; returns the cycle the line's data is (or will be) there.
    Cycle hit(uint64_t set, int way, Cycle lookup_done);
    // The slowest line of a request and where its cycles went. Hits keep two scalars, not a
    // breakdown copied per line (copying small structs per line stalled store forwarding).
    struct Slowest {
        Cycle done = 0;
        bool any = false, is_hit = true;
        Cycle hit_lookup_done = 0;
        AccessBreakdown miss_bd;
        void hit(Cycle lookup_done, Cycle ready);
        void miss(Cycle done, const AccessBreakdown& line_bd);
        void charge(AccessBreakdown* bd, int level, Cycle now) const;
    };
    Cycle access_line(uint64_t line_addr, Cycle now, Cycle lookup_done, Slowest& slowest,
                      bool breakdown);

    CacheParams params_;
    MemoryPort* next_;
    int level_;
    std::vector<Cycle> mshr_free_;            // per MSHR: cycle its miss completes
    std::vector<ReservationCalendar> banks_;  // per bank: the cycles it starts a lookup
    uint64_t rng_ = 0x9E3779B97F4A7C15ull;    // random replacement: deterministic xorshift state
    TimeSeries* fill_series_ = nullptr;
    std::vector<uint64_t> set_storage_;  // per set: tags (kNoTag: invalid), then fill cycles
    uint64_t* set_block_ = nullptr;      // set_storage_ aligned to a host cache line
    std::vector<uint64_t> last_use_;     // per set and way: LRU use or FIFO fill stamp
    uint64_t bank_mask_ = 0;
    uint32_t bank_shift_ = 0;  // log2 of the bank count
    uint64_t set_mask_;
    uint32_t line_shift_;
    uint64_t use_clock_ = 0;
    std::vector<Cycle> lookup_done_;  // scratch for requests of many lines
};

}  // namespace rtsim

// One registry of named counters for every block (gem5/SST style): blocks keep plain integer
// members, so counting costs one increment, and register their addresses once at elaboration.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace rtsim {

// A counter per window of simulated cycles, for plots of bandwidth and utilisation over time.
// Blocks share one series per quantity; a run without windows passes none, so it costs nothing.
class TimeSeries {
  public:
    explicit TimeSeries(uint64_t window_cycles) : window_(window_cycles) {}
    void add(uint64_t cycle, uint64_t value) {
        const size_t w = size_t(cycle / window_);
        if (w >= buckets_.size()) buckets_.resize(w + 1, 0);
        buckets_[w] += value;
    }
    uint64_t window_cycles() const { return window_; }
    const std::vector<uint64_t>& buckets() const { return buckets_; }

  private:
    uint64_t window_;
    std::vector<uint64_t> buckets_;
};

// What a block's report section needs of the run beyond its own counters (gem5-style derived
// figures, computed at dump time so that counting stays one increment).
struct ReportContext {
    uint64_t total_cycles = 0;
    double clock_ghz = 1.0;
    uint64_t rays = 0;  // rays simulated
    double seconds() const { return double(total_cycles) / (clock_ghz * 1e9); }
    double gbps(uint64_t bytes) const {
        return seconds() > 0 ? double(bytes) / seconds() / 1e9 : 0.0;
    }
    // a / b, 0 when b is 0 (a rate of nothing).
    static double ratio(double a, double b) { return b > 0 ? a / b : 0.0; }
};

// A counter summed over several blocks of one kind (all L1s' fill bytes, all cores' lanes).
template <typename Block>
uint64_t sum_of(const std::vector<const Block*>& blocks, uint64_t Block::*counter) {
    uint64_t n = 0;
    for (const Block* b : blocks) n += b->*counter;
    return n;
}

class StatsRegistry {
  public:
    struct Entry {
        std::string name;  // "l1[3].misses": block instance, dot, counter (unit in the name)
        const uint64_t* value;
        std::string description;
    };

    // Throws std::logic_error on a duplicate name: two blocks must never share a counter.
    void add(const std::string& block, const std::string& counter, const uint64_t* value,
             const std::string& description);
    const std::vector<Entry>& entries() const { return entries_; }
    bool has(const std::string& name) const;
    // Value of a registered counter; throws std::out_of_range for an unknown name.
    uint64_t get(const std::string& name) const;
    // Sum of `counter` over every block whose name starts with `block_prefix` ("l1[").
    uint64_t sum(const std::string& block_prefix, const std::string& counter) const;

  private:
    std::vector<Entry> entries_;
};

}  // namespace rtsim

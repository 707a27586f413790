// One registry of named counters for every block (gem5/SST style): blocks keep plain integer
// members, so counting costs one increment, and register their addresses once at elaboration.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace rtsim {

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

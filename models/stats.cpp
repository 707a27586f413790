#include "models/stats.h"

#include <stdexcept>

namespace rtsim {

void StatsRegistry::add(const std::string& block, const std::string& counter, const uint64_t* value,
                        const std::string& description) {
    std::string name = block + "." + counter;
    if (has(name)) throw std::logic_error("duplicate statistic " + name);
    entries_.push_back({std::move(name), value, description});
}

bool StatsRegistry::has(const std::string& name) const {
    for (const Entry& e : entries_)
        if (e.name == name) return true;
    return false;
}

uint64_t StatsRegistry::get(const std::string& name) const {
    for (const Entry& e : entries_)
        if (e.name == name) return *e.value;
    throw std::out_of_range("unknown statistic " + name);
}

uint64_t StatsRegistry::sum(const std::string& block_prefix, const std::string& counter) const {
    uint64_t total = 0;
    const std::string suffix = "." + counter;
    for (const Entry& e : entries_)
        if (e.name.rfind(block_prefix, 0) == 0 && e.name.size() > suffix.size() &&
            e.name.compare(e.name.size() - suffix.size(), suffix.size(), suffix) == 0)
            total += *e.value;
    return total;
}

}  // namespace rtsim

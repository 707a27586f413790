#include "models/dram.h"

#include <algorithm>
#include <cmath>

namespace rtsim {

Dram::Dram(sc_core::sc_module_name name, const DramParams& params)
    : sc_core::sc_module(name), params_(params) {}

Cycle Dram::access(uint64_t /*addr*/, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) {
    const double start = std::max(static_cast<double>(now), next_free_);
    const double transfer = size_bytes / params_.bytes_per_cycle;
    next_free_ = start + transfer;
    ++reads;
    bytes += size_bytes;
    if (bytes_series_) bytes_series_->add(static_cast<uint64_t>(start), size_bytes);
    busy_cycles += static_cast<uint64_t>(std::ceil(transfer));
    queue_cycles += static_cast<uint64_t>(std::ceil(start - static_cast<double>(now)));
    // Data is usable once its last byte has crossed the channel and the access latency passed.
    const Cycle done = static_cast<Cycle>(std::ceil(next_free_)) + params_.latency_cycles;
    if (bd) bd->cycles[kLevelDram] += done - now;
    return done;
}

void Dram::register_stats(StatsRegistry& reg, const std::string& block) {
    reg.add(block, "reads", &reads, "read bursts");
    reg.add(block, "bytes", &bytes, "bytes read");
    reg.add(block, "busy_cycles", &busy_cycles, "cycles the channel was transferring");
    reg.add(block, "queue_cycles", &queue_cycles, "cycles requests waited for the channel");
}

}  // namespace rtsim

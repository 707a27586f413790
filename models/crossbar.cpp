#include "models/crossbar.h"

#include <algorithm>

namespace rtsim {

Crossbar::Crossbar(sc_core::sc_module_name name, double bytes_per_cycle, MemoryPort* next_level)
    : sc_core::sc_module(name), link_(bytes_per_cycle), up_(bytes_per_cycle), next_(next_level) {}

Cycle Crossbar::carry_up(Cycle ready, uint32_t size_bytes) {
    const auto [first, end] = up_.transfer(ready, size_bytes);
    ++write_transfers;
    write_bytes += size_bytes;
    queue_cycles += first - ready;
    return end;
}

Cycle Crossbar::access(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) {
    // Requests are small and cross at once; the line crosses when the L2 returns it (a line the
    // L2 fetches from DRAM holds no bandwidth while it waits).
    const Cycle returned = next_->access(addr, size_bytes, now, bd);
    const Cycle end = carry(returned, size_bytes);
    if (bd) bd->cycles[kLevelCrossbar] += end - returned;  // waiting for the link, crossing
    return end;
}

Cycle Crossbar::carry(Cycle returned, uint32_t size_bytes) {
    const auto [first, end] = link_.transfer(returned, size_bytes);
    ++transfers;
    bytes += size_bytes;
    busy_cycles += link_.idle_cycles(size_bytes);
    queue_cycles += first - returned;
    return end;
}

void Crossbar::register_stats(StatsRegistry& reg) {
    const std::string block = name();
    reg.add(block, "transfers", &transfers, "line transfers from the L2 to the L1s");
    reg.add(block, "bytes", &bytes, "bytes moved");
    reg.add(block, "busy_cycles", &busy_cycles, "cycles spent transferring");
    reg.add(block, "queue_cycles", &queue_cycles, "cycles requests waited for bandwidth");
    reg.add(block, "write_transfers", &write_transfers, "writes from the cores to the L2");
    reg.add(block, "write_bytes", &write_bytes, "bytes written towards the L2");
}

nlohmann::json Crossbar::report(const ReportContext& ctx) const {
    return {{"bytes", bytes},
            {"gbps", ctx.gbps(bytes)},
            {"write_bytes", write_bytes},
            {"queue_cycles", queue_cycles},
            {"utilization", ReportContext::ratio(double(busy_cycles), double(ctx.total_cycles))}};
}

}  // namespace rtsim

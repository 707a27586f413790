#include "sim/mem_trace.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "workloads/output_file.h"

namespace rtsim {

void MemTraceRecorder::save(const std::string& path, uint32_t burst_bytes, double chip_clock_ghz,
                            double device_tck_ns) const {
    std::vector<Request> sorted = kept_;
    std::stable_sort(sorted.begin(), sorted.end(),
                     [](const Request& a, const Request& b) { return a.cycle < b.cycle; });
    const double scale = device_tck_ns > 0 ? 1.0 / (chip_clock_ghz * device_tck_ns) : 1.0;
    std::string text;
    text.reserve(sorted.size() * 24);
    const uint64_t burst = std::max<uint32_t>(1, burst_bytes);
    for (const Request& r : sorted) {
        const auto cycle = uint64_t(std::ceil(double(r.cycle) * scale - 1e-9));
        const uint64_t first = r.addr / burst * burst;
        const uint64_t end = r.addr + std::max<uint32_t>(1, r.size_bytes);
        for (uint64_t a = first; a < end; a += burst)
            text += fmt::format("0x{:x} {} {}\n", a, r.write ? "WRITE" : "READ", cycle);
    }
    write_file_atomically(path, text);
}

}  // namespace rtsim

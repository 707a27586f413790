#include "workloads/memory_limit.h"

#include <fmt/format.h>

#include <cctype>
#include <cstdlib>
#include <fstream>
#include <string>

#include "workloads/error.h"

namespace rtsim {

namespace {

uint64_t parse_limit(const std::string& text) {
    size_t used = 0;
    unsigned long long v = 0;
    try {
        v = std::stoull(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    std::string rest = text.substr(used);
    for (char& c : rest) c = char(std::toupper(static_cast<unsigned char>(c)));
    if (!rest.empty() && rest.back() == 'B') rest.pop_back();
    if (!rest.empty() && rest.back() == 'I') rest.pop_back();  // "GiB"
    int shift = -1;
    if (rest.empty()) shift = 0;
    if (rest == "K") shift = 10;
    if (rest == "M") shift = 20;
    if (rest == "G") shift = 30;
    if (rest == "T") shift = 40;
    if (used == 0 || shift < 0 || v == 0 || v > (~0ull >> shift))
        throw InputError(fmt::format(
            "RTSIM_MEMORY_LIMIT: expected a positive number of bytes, optionally with K, M, G or "
            "T, got '{}'",
            text));
    return uint64_t(v) << shift;
}

// /proc/meminfo's MemAvailable, in bytes (0: not found).
uint64_t available_bytes() {
    std::ifstream in("/proc/meminfo");
    std::string key;
    uint64_t kib = 0;
    std::string unit;
    while (in >> key >> kib >> unit)
        if (key == "MemAvailable:") return kib * 1024;
    return 0;
}

double gib(uint64_t bytes) {
    return double(bytes) / double(1ull << 30);
}

}  // namespace

uint64_t memory_limit_bytes(std::string* source) {
    if (const char* env = std::getenv("RTSIM_MEMORY_LIMIT"); env && *env) {
        if (source) *source = "RTSIM_MEMORY_LIMIT";
        return parse_limit(env);
    }
    if (source) *source = "the machine's available memory";
    return available_bytes();
}

void check_prepare_memory(const std::string& what, uint64_t triangles, uint64_t instances) {
    std::string source;
    const uint64_t limit = memory_limit_bytes(&source);
    const uint64_t need =
        triangles * kPrepareBytesPerTriangle + instances * kPrepareBytesPerInstance;
    if (limit == 0 || need <= limit) return;
    throw InputError(fmt::format(
        "{}: preparing it needs about {:.1f} GiB ({} triangles at {} bytes{}), above the {:.1f} "
        "GiB limit ({}); use a smaller scene, instances, or a machine with more memory",
        what, gib(need), triangles, kPrepareBytesPerTriangle,
        instances ? fmt::format(", {} instances at {} bytes", instances, kPrepareBytesPerInstance)
                  : std::string(),
        gib(limit), source));
}

}  // namespace rtsim

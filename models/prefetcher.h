// A cache's hardware prefetcher, registered by name (l1.prefetcher, l2.prefetcher; `rtsim
// list`), one file each in models/prefetcher/. It is told of each demand miss and names the
// lines to fetch ahead of it; the cache does the rest, the same way in both engines:
//   * a named line already held (or filling) is left alone;
//   * otherwise it takes an MSHR free at the miss's lookup cycle, or is dropped: a prefetch
//     never waits for an MSHR, so it never delays a demand miss behind it;
//   * it is installed as a miss installs a line (the policy's victim, a dirty victim written
//     back) and fetched from the next level at that cycle; a demand access meeting it while it
//     fills waits for it as for any fill in flight (a merged miss);
//   * its counters: prefetches issued, dropped for want of an MSHR, and useful (lines hit by a
//     demand access before they left).
// Functional warming (sampled runs) prefetches as a miss does (Cache::warm_prefetches), uncounted;
// a sampled run's first fills are then the lines rays first ask for (LineFirstTouches).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "models/registry.h"

namespace rtsim {

struct PrefetcherParams {
    int degree = 1;  // lines named per demand miss, at most
};

class Prefetcher {
  public:
    virtual ~Prefetcher() = default;
    // A demand miss of line `line` (a line address: the byte address over the line size):
    // appends the line addresses to fetch, nearest first, to `out`.
    virtual void on_miss(uint64_t line, std::vector<uint64_t>& out) = 0;
};

struct PrefetcherEntry {
    static constexpr const char* kKind = "prefetcher";
    std::string name, description;
    std::vector<std::string> params;
    // nullptr: no prefetcher ("none").
    std::unique_ptr<Prefetcher> (*make)(const PrefetcherParams&) = nullptr;
};
using PrefetcherRegistry = Registry<PrefetcherEntry>;

}  // namespace rtsim

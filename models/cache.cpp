#include "models/cache.h"

#include <algorithm>
#include <functional>

namespace rtsim {

Cache::Cache(sc_core::sc_module_name name, const CacheParams& params, MemoryPort* next_level,
             int level)
    : sc_core::sc_module(name), params_(params), next_(next_level), level_(level) {
    tags_.assign(params_.sets() * params_.ways, kNoTag);
    state_.resize(params_.sets() * params_.ways);
    set_mask_ = params_.sets() - 1;  // sets and line size are powers of two (config validates)
    mshr_free_.assign(size_t(std::max(0, params_.mshrs)), 0);
    bank_free_.assign(size_t(std::max(1, params_.banks)), 0);
    bank_mask_ = bank_free_.size() - 1;  // a power of two (config validates)
    line_shift_ = 0;
    while ((1u << line_shift_) < params_.line_bytes) ++line_shift_;
}

Cycle Cache::access_line(uint64_t line_addr, Cycle now, AccessBreakdown* bd) {
    ++accesses;
    const size_t base = size_t(line_addr & set_mask_) * size_t(params_.ways);
    const uint64_t* tags = &tags_[base];
    // One lookup per bank per cycle; waiting for the bank is charged to this level.
    Cycle& bank = bank_free_[line_addr & bank_mask_];
    const Cycle start = std::max(now, bank);
    bank = start + 1;
    bank_conflict_cycles += start - now;
    const Cycle lookup_done = start + params_.hit_latency_cycles;
    for (int w = 0; w < params_.ways; ++w) {
        if (tags[w] != line_addr) continue;
        WayState& way = state_[base + w];
        ++hits;
        if (params_.replacement == CacheParams::Replacement::Lru)
            way.last_use = ++use_clock_;  // FIFO: fill order
        if (way.ready > lookup_done) ++merged_misses;
        if (bd) {
            bd->cycles[level_] += lookup_done - now;
            // Waiting for a fill already in flight is time spent below this level.
            if (way.ready > lookup_done)
                bd->cycles[std::min(level_ + 1, kMemLevels - 1)] += way.ready - lookup_done;
        }
        return std::max(lookup_done, way.ready);
    }
    // Miss: an invalid way if any, else the policy's victim.
    int victim = -1;
    for (int w = 0; w < params_.ways && victim < 0; ++w)
        if (tags[w] == kNoTag) victim = w;
    if (victim < 0) {
        if (params_.replacement == CacheParams::Replacement::Random) {
            rng_ ^= rng_ << 13;
            rng_ ^= rng_ >> 7;
            rng_ ^= rng_ << 17;
            victim = int(rng_ % uint64_t(params_.ways));
        } else {
            victim = 0;
            for (int w = 1; w < params_.ways; ++w)
                if (state_[base + w].last_use < state_[base + victim].last_use) victim = w;
        }
    }
    ++misses;
    fill_bytes += params_.line_bytes;
    if (fill_series_) fill_series_->add(lookup_done, params_.line_bytes);
    // MSHRs as a min-heap of the cycles they free: take the earliest, give it back busy until
    // this miss's data returns.
    Cycle issue_at = lookup_done;
    const bool limited = !mshr_free_.empty();
    if (limited) {
        std::pop_heap(mshr_free_.begin(), mshr_free_.end(), std::greater<Cycle>());
        issue_at = std::max(lookup_done, mshr_free_.back());
        mshr_wait_cycles += issue_at - lookup_done;
    }
    if (bd) bd->cycles[level_] += issue_at - now;
    const Cycle ready = next_->access(line_addr << line_shift_, params_.line_bytes, issue_at, bd);
    if (limited) {
        mshr_free_.back() = ready;
        std::push_heap(mshr_free_.begin(), mshr_free_.end(), std::greater<Cycle>());
    }
    tags_[base + victim] = line_addr;
    state_[base + victim] = {++use_clock_, ready};
    return ready;
}

bool Cache::present(uint64_t line_addr) const {
    const uint64_t* tags = &tags_[size_t(line_addr & set_mask_) * size_t(params_.ways)];
    for (int w = 0; w < params_.ways; ++w)
        if (tags[w] == line_addr) return true;
    return false;
}

bool Cache::served_locally(uint64_t addr, uint32_t size_bytes) const {
    const uint64_t last = (addr + std::max<uint32_t>(size_bytes, 1) - 1) >> line_shift_;
    for (uint64_t line = addr >> line_shift_; line <= last; ++line)
        if (!present(line)) return false;
    return true;
}

Cycle Cache::access(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) {
    bytes_requested += size_bytes;
    const uint64_t first = addr >> line_shift_;
    const uint64_t last = (addr + std::max<uint32_t>(size_bytes, 1) - 1) >> line_shift_;
    Cycle done = now;
    // Lines are looked up in parallel; the access waits for the slowest, whose breakdown it adds
    // to what the requester's levels already charged.
    AccessBreakdown slowest;
    for (uint64_t line = first; line <= last; ++line) {
        AccessBreakdown line_bd;
        const Cycle d = access_line(line, now, bd ? &line_bd : nullptr);
        if (d > done || line == first) {
            done = std::max(done, d);
            slowest = line_bd;
        }
    }
    if (bd)
        for (int l = 0; l < kMemLevels; ++l) bd->cycles[l] += slowest.cycles[l];
    return done;
}

void Cache::register_stats(StatsRegistry& reg, const std::string& block) {
    reg.add(block, "accesses", &accesses, "line lookups");
    reg.add(block, "hits", &hits, "lookups that found the line (including lines still filling)");
    reg.add(block, "misses", &misses, "lookups that fetched the line from the next level");
    reg.add(block, "merged_misses", &merged_misses, "hits that waited for an in-flight fill");
    reg.add(block, "bytes_requested", &bytes_requested, "bytes delivered to the level above");
    reg.add(block, "fill_bytes", &fill_bytes, "bytes read from the level below");
    reg.add(block, "mshr_wait_cycles", &mshr_wait_cycles, "cycles misses waited for a free MSHR");
    reg.add(block, "bank_conflict_cycles", &bank_conflict_cycles,
            "cycles lookups waited for their bank");
}

}  // namespace rtsim

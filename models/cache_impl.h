// The cache's hot paths as templates of the set layout G and the replacement policy P. Included
// by each policy's file (models/replacement/*.cpp), which instantiates them for its policy through
// Cache::use_policy; the cache calls the instance through two function pointers set once.
#pragma once

#include <algorithm>

#include "models/cache.h"

namespace rtsim {

template <typename P>
void Cache::use_policy(Cache& c) {
    switch (c.layout_) {
        case 1:
            c.access_fn_ = &Cache::access_entry<1, P>;
            c.local_fn_ = &Cache::local_entry<1, P>;
            c.tag_fn_ = &Cache::tag_entry<1, P>;
            c.warm_fn_ = &Cache::tag_entry<1, P, false>;
            c.write_fn_ = &Cache::write_entry<1, P>;
            c.prefetch_fn_ = &Cache::prefetch_entry<1, P>;
            break;
        case 2:
            c.access_fn_ = &Cache::access_entry<2, P>;
            c.local_fn_ = &Cache::local_entry<2, P>;
            c.tag_fn_ = &Cache::tag_entry<2, P>;
            c.warm_fn_ = &Cache::tag_entry<2, P, false>;
            c.write_fn_ = &Cache::write_entry<2, P>;
            c.prefetch_fn_ = &Cache::prefetch_entry<2, P>;
            break;
        case 4:
            c.access_fn_ = &Cache::access_entry<4, P>;
            c.local_fn_ = &Cache::local_entry<4, P>;
            c.tag_fn_ = &Cache::tag_entry<4, P>;
            c.warm_fn_ = &Cache::tag_entry<4, P, false>;
            c.write_fn_ = &Cache::write_entry<4, P>;
            c.prefetch_fn_ = &Cache::prefetch_entry<4, P>;
            break;
        default:
            c.access_fn_ = &Cache::access_entry<0, P>;
            c.local_fn_ = &Cache::local_entry<0, P>;
            c.tag_fn_ = &Cache::tag_entry<0, P>;
            c.warm_fn_ = &Cache::tag_entry<0, P, false>;
            c.write_fn_ = &Cache::write_entry<0, P>;
            c.prefetch_fn_ = &Cache::prefetch_entry<0, P>;
    }
}

template <int G, typename P, bool kCount>
bool Cache::tag_entry(Cache& c, uint64_t line, Cycle at) {
    (void)at;  // only counted fills are put in the time series
    const uint64_t set = c.set_of(line);
    const int found = c.find_way<G>(set, line);
    if (found >= 0) {
        if constexpr (kCount) ++c.hits;
        if (!c.prefetched_.empty()) c.note_prefetch_hit(set, found, kCount);
        P::template hit<G>(c.stamps<G>(set), found, c.repl_);
        return true;
    }
    c.demand(line, kCount);
    // The same steps as fill(), in the same order (the random policy draws in victim()).
    const int victim = P::template victim<G>(c.tags<G>(set), c.stamps<G>(set), c.repl_);
    c.evict(set, victim, c.tags<G>(set)[victim], at, kCount ? kQueueWriteBack : kWarmWriteBack);
    c.mark_filled(line, kCount);
    if constexpr (kCount) {
        ++c.misses;
        c.fill_bytes += c.params_.line_bytes;
        if (c.fill_series_) c.fill_series_->add(at, c.params_.line_bytes);
    }
    c.tags<G>(set)[victim] = c.tag_of(line);
    c.fill_ready<G>(set)[victim] = 0;  // the reference keeps fills in flight itself
    c.clear_prefetched(set, victim);
    P::template filled<G>(c.stamps<G>(set), victim, c.repl_);
    return false;
}

template <int G, typename P>
int Cache::install_prefetched(uint64_t set, uint64_t line, Cycle at, int mode) {
    const int victim = P::template victim<G>(tags<G>(set), stamps<G>(set), repl_);
    evict(set, victim, tags<G>(set)[victim], at, WritebackMode(mode));
    mark_filled(line, true);
    ++prefetches;
    fill_bytes += params_.line_bytes;
    if (fill_series_) fill_series_->add(at, params_.line_bytes);
    tags<G>(set)[victim] = tag_of(line);
    fill_ready<G>(set)[victim] = 0;
    prefetched_[way_index(set, victim)] = kTimedPrefetch;
    P::template filled<G>(stamps<G>(set), victim, repl_);
    return victim;
}

template <int G, typename P>
bool Cache::prefetch_entry(Cache& c, uint64_t line, Cycle at) {
    const uint64_t set = c.set_of(line);
    if (c.find_way<G>(set, line) >= 0) return false;
    c.install_prefetched<G, P>(set, line, at, kQueueWriteBack);
    return true;
}

template <int G, typename P>
void Cache::prefetch(uint64_t line, Cycle at) {
    prefetch_candidates(line, prefetch_lines_);
    const bool limited = few_mshrs_ || !mshr_free_.empty();
    for (const uint64_t l : prefetch_lines_) {
        const uint64_t set = set_of(l);
        if (find_way<G>(set, l) >= 0) continue;  // held or filling
        if (limited && earliest_mshr() > at) {   // never waits for an MSHR
            ++prefetches_dropped;
            continue;
        }
        const int way = install_prefetched<G, P>(set, l, at, kSendWriteBack);
        if (limited) request_mshr(at);
        // Its timeline, for a demand access that waits on it (charge_wait).
        AccessBreakdown bd;
        const Cycle ready = below_.read(l << line_shift_, params_.line_bytes, at, &bd);
        remember_fill(l, at, AccessBreakdown{}, bd, ready);
        if (limited) replace_earliest_mshr(ready);  // the MSHR the check above found free
        fill_ready<G>(set)[way] = ready;
    }
}

template <int G, typename P>
void Cache::write_entry(Cache& c, uint64_t line, Cycle at, WritebackMode mode) {
    const uint64_t set = c.set_of(line);
    if (c.dirty_.empty()) c.dirty_.assign(c.params_.sets() * uint64_t(c.params_.ways), 0);
    int way = c.find_way<G>(set, line);
    const bool counted = mode != kWarmWriteBack;
    if (way >= 0) {
        c.write_hits += counted;
        P::template hit<G>(c.stamps<G>(set), way, c.repl_);
    } else {
        way = P::template victim<G>(c.tags<G>(set), c.stamps<G>(set), c.repl_);
        c.evict(set, way, c.tags<G>(set)[way], at, mode);
        c.write_misses += counted;
        c.tags<G>(set)[way] = c.tag_of(line);
        c.fill_ready<G>(set)[way] = at;  // its bytes are the write's: there once looked up
        c.clear_prefetched(set, way);
        P::template filled<G>(c.stamps<G>(set), way, c.repl_);
    }
    c.dirty_[c.way_index(set, way)] = 1;
}

template <int G, typename P>
Cycle Cache::access_line(uint64_t line_addr, Cycle now, Cycle lookup_done, Slowest& slowest,
                         bool breakdown) {
    const uint64_t set = set_of(line_addr);
    const int found = find_way<G>(set, line_addr);
    if (found >= 0) {
        const Cycle ready = hit<G, P>(set, found, lookup_done);
        slowest.hit(lookup_done, ready, line_addr);
        return std::max(lookup_done, ready);
    }
    AccessBreakdown line_bd;
    const Cycle ready =
        fill<G, P>(set, line_addr, now, lookup_done, breakdown ? &line_bd : nullptr);
    slowest.miss(ready, line_bd);
    return ready;
}

template <int G, typename P>
Cycle Cache::fill(uint64_t set, uint64_t line_addr, Cycle now, Cycle lookup_done,
                  AccessBreakdown* bd) {
    // Miss: the policy's victim (an invalid way if there is one).
    const int victim = P::template victim<G>(tags<G>(set), stamps<G>(set), repl_);
    evict(set, victim, tags<G>(set)[victim], lookup_done, kSendWriteBack);
    mark_filled(line_addr, true);
    demand(line_addr);
    ++misses;
    fill_bytes += params_.line_bytes;
    if (fill_series_) fill_series_->add(lookup_done, params_.line_bytes);
    // MSHRs as the cycles they free, in order: take the earliest, give it back busy until this
    // miss's data returns.
    Cycle issue_at = lookup_done;
    const bool limited = few_mshrs_ || !mshr_free_.empty();
    if (limited) {
        request_mshr(lookup_done);
        issue_at = std::max(lookup_done, earliest_mshr());
        mshr_wait_cycles += issue_at - lookup_done;
    }
    if (bd) bd->cycles[level_] += issue_at - now;
    // A cache keeps the timeline of its fills in flight, so that a later hit waiting on one is
    // charged to the levels it actually waits on.
    const bool keep = bd != nullptr;
    AccessBreakdown before;
    if (keep) before = *bd;
    const Cycle ready = below_.read(line_addr << line_shift_, params_.line_bytes, issue_at, bd);
    if (keep) remember_fill(line_addr, issue_at, before, *bd, ready);
    if (limited) replace_earliest_mshr(ready);
    tags<G>(set)[victim] = tag_of(line_addr);
    fill_ready<G>(set)[victim] = ready;
    clear_prefetched(set, victim);
    P::template filled<G>(stamps<G>(set), victim, repl_);
    if (prefetcher_) prefetch<G, P>(line_addr, lookup_done);
    return ready;
}

template <int G, typename P>
inline bool Cache::access_local_in(uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
                                   AccessBreakdown* bd) {
    const auto [first, last] = line_range(addr, size_bytes);
    const uint64_t lines = last - first + 1;
    // Find every line before touching any state: a request with one missing line is not local.
    constexpr uint64_t kMaxLines = 16;
    if (lines > kMaxLines) return false;
    int ways[kMaxLines];
    for (uint64_t k = 0; k < lines; ++k) {
        ways[k] = find_way<G>(set_of(first + k), first + k);
        if (ways[k] < 0) return false;
    }
    bytes_requested += size_bytes;
    note_lookup(now);
    Cycle done[kMaxLines];
    Cycle first_done = 0;
    const bool one_bank = one_bank_reads(lines);
    if (one_bank)
        first_done = look_up_in_one_bank(first, lines, now);
    else
        look_up(first, last, now, done);
    // The slowest line decides (the first of equals); a hit waits for a fill still in flight.
    Cycle slowest = 0, slowest_lookup = 0;
    uint64_t slowest_line = first;
    for (uint64_t k = 0; k < lines; ++k) {
        const Cycle lookup_done = one_bank ? first_done + k : done[k];
        const Cycle d = std::max(lookup_done, hit<G, P>(set_of(first + k), ways[k], lookup_done));
        const bool slower = k == 0 || d > slowest;
        slowest = slower ? d : slowest;
        slowest_lookup = slower ? lookup_done : slowest_lookup;
        slowest_line = slower ? first + k : slowest_line;
    }
    if (bd) charge_hit(bd, now, slowest_lookup, slowest, slowest_line);
    ready = slowest;
    return true;
}

template <int G, typename P>
inline Cycle Cache::access_in(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) {
    bytes_requested += size_bytes;
    note_lookup(now);
    const auto [first, last] = line_range(addr, size_bytes);
    if (first == last) {  // one line (every request from the level above): no slowest to find
        const Cycle lookup_done = look_up_in_one_bank(first, 1, now);
        const uint64_t set = set_of(first);
        const int found = find_way<G>(set, first);
        if (found < 0) return fill<G, P>(set, first, now, lookup_done, bd);
        const Cycle ready = std::max(lookup_done, hit<G, P>(set, found, lookup_done));
        if (bd) charge_hit(bd, now, lookup_done, ready, first);
        return ready;
    }
    // Lines are looked up in parallel; the access waits for the slowest, whose breakdown it adds
    // to what the requester's levels already charged.
    const uint64_t lines = last - first + 1;
    Cycle first_done = 0;
    const bool one_bank = one_bank_reads(lines);
    if (one_bank) {
        first_done = look_up_in_one_bank(first, lines, now);
    } else {
        if (lookup_done_.size() < lines) lookup_done_.resize(lines);
        look_up(first, last, now, lookup_done_.data());
    }
    Slowest slowest;
    for (uint64_t k = 0; k < lines; ++k)
        access_line<G, P>(first + k, now, one_bank ? first_done + k : lookup_done_[k], slowest,
                          bd != nullptr);
    slowest.charge(*this, bd, now);
    return std::max(now, slowest.done);
}

}  // namespace rtsim

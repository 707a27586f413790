#include "models/cache.h"

#include <algorithm>
#include <functional>
#include <stdexcept>
#include <string>

namespace rtsim {

Cache::Cache(sc_core::sc_module_name name, const CacheParams& params, MemoryPort* next_level,
             int level)
    : sc_core::sc_module(name), params_(params), next_(next_level), level_(level) {
    block_bytes_ = 16 * uint64_t(params_.ways);
    tag_groups_ = params_.ways % 4 == 0 ? params_.ways / 4 : 0;
#ifdef __SSE2__
    layout_ = tag_groups_ == 1 || tag_groups_ == 2 || tag_groups_ == 4 ? tag_groups_ : 0;
#endif
    set_storage_.assign(params_.sets() * block_bytes_ / 8 + 8, 0);
    set_blocks_ = reinterpret_cast<char*>(set_storage_.data());
    while (reinterpret_cast<uintptr_t>(set_blocks_) % 64) set_blocks_ += 8;
    for (uint64_t set = 0; set < params_.sets(); ++set)
        std::fill(tags(set), tags(set) + params_.ways, kNoTag);
    set_mask_ = params_.sets() - 1;  // sets and line size are powers of two (config validates)
    while ((uint64_t(1) << set_shift_) < params_.sets()) ++set_shift_;
    const auto mshrs = size_t(std::max(0, params_.mshrs));
    few_mshrs_ = mshrs > 0 && mshrs <= kFewMshrs;
    if (few_mshrs_) {
        mshr_keys_.assign(kFewMshrs, ~uint64_t(0));
        for (size_t m = 0; m < mshrs; ++m) mshr_keys_[m] = m;  // free from cycle 0
    } else {
        mshr_free_.assign(mshrs, 0);
    }
    banks_.assign(size_t(std::max(1, params_.banks)), ReservationCalendar(1));
    if (params_.in_order_requests)
        for (auto& bank : banks_) bank.assume_in_order();
    bank_mask_ = banks_.size() - 1;  // a power of two (config validates)
    while ((uint64_t(1) << bank_shift_) < banks_.size()) ++bank_shift_;
    line_shift_ = 0;
    while ((1u << line_shift_) < params_.line_bytes) ++line_shift_;
    const uint64_t top_tag = ((params_.address_limit_bytes - 1) >> line_shift_) >> set_shift_;
    if (top_tag >= kNoTag)
        throw std::invalid_argument(
            std::string(name) + ": addresses up to " + std::to_string(params_.address_limit_bytes) +
            " bytes need tags wider than 32 bits with this cache's sets and lines");
    // Every level remembers its fills' timelines: a request merged on one is charged where the
    // fill was at each cycle (the L2's merged waits were all charged to DRAM: 7 points of stall
    // share off the time-ordered reference with 4 L2 MSHRs).
    size_t fills = params_.mshrs > 0 ? std::max<size_t>(128, 4 * size_t(params_.mshrs)) : 1024;
    size_t slots = 1;
    while (slots < fills) slots *= 2;
    in_flight_.resize(slots);
    in_flight_mask_ = slots - 1;
    if (auto* next = dynamic_cast<Cache*>(next_level); next && next->level_ == level_)
        same_level_next_ = next;
    repl_.ways = params_.ways;
    repl_.rrpv_bits = params_.rrpv_bits;
    repl_.words_base = params_.sets() ? stamps(0) : nullptr;
    repl_.stride_words = block_bytes_ / 4;
    repl_.sets = params_.sets();
    const ReplacementEntry& policy = ReplacementRegistry::at(params_.replacement);
    if (policy.check) {
        const std::string why = policy.check(params_.ways);
        if (!why.empty())
            throw std::invalid_argument(std::string(name) + ": replacement " + policy.name + ": " +
                                        why);
    }
    policy.bind(*this);
    const PrefetcherEntry& prefetcher = PrefetcherRegistry::at(params_.prefetcher);
    if (prefetcher.make) {
        PrefetcherParams pp;
        pp.degree = std::max(1, params_.prefetch_degree);
        prefetcher_ = prefetcher.make(pp);
        prefetched_.assign(params_.sets() * uint64_t(params_.ways), 0);
    }
}

void Cache::warm_prefetches(uint64_t line) {
    prefetch_candidates(line, prefetch_lines_);
    LineFirstTouches* const touches = first_touch_;
    first_touch_ = nullptr;                     // a prefetch is no ray's demand
    for (const uint64_t l : prefetch_lines_) {  // the next level warms with its own list
        if (contains(line_address(l))) continue;
        warm_fn_(*this, l, 0);
        // Marked, so that the first demand lookup to find it counts it asked for.
        const uint64_t set = set_of(l);
        prefetched_[way_index(set, find_way<0>(set, l))] = kWarmPrefetch;
        if (next_) next_->warm(line_address(l), params_.line_bytes);
    }
    first_touch_ = touches;
}

void Cache::prefetch_candidates(uint64_t line, std::vector<uint64_t>& out) {
    out.clear();
    prefetcher_->on_miss(line, out);
    const uint64_t limit_line = (params_.address_limit_bytes - 1) >> line_shift_;
    out.erase(std::remove_if(out.begin(), out.end(),
                             [&](uint64_t l) { return l == line || l > limit_line; }),
              out.end());
}

void Cache::look_up(uint64_t first, uint64_t last, Cycle now, Cycle* done) {
    const uint64_t lines = last - first + 1;
    if (one_bank_reads(lines)) {  // one bank reads the lines back to back (the common cases)
        const Cycle first_done = look_up_in_one_bank(first, lines, now);
        for (Cycle j = 0; j < lines; ++j) done[j] = first_done + j;
        return;
    }
    accesses += lines;
    // One lookup per bank per cycle; waiting for the bank is charged to this level. Lookups
    // come out of time order (a miss above waited for an MSHR): a bank is a calendar.
    const uint64_t nb = banks_.size();
    for (uint64_t k = 0; k < std::min(lines, nb); ++k) {
        const Cycle span =
            (lines - k + nb - 1) >> bank_shift_;  // lines k, k + nb, ... share a bank
        const Cycle start = banks_[(first + k) & bank_mask_].reserve(now, span);
        bank_conflict_cycles += span * (start - now) + span * (span - 1) / 2;
        for (Cycle j = 0; j < span; ++j) done[k + j * nb] = start + j + params_.hit_latency_cycles;
    }
}

uint64_t Cache::arrive(uint64_t addr, uint32_t size_bytes, Cycle now,
                       std::vector<Cycle>& lookup_done) {
    bytes_requested += size_bytes;
    note_lookup(now);
    const auto [first, last] = line_range(addr, size_bytes);
    lookup_done.resize(last - first + 1);
    look_up(first, last, now, lookup_done.data());
    return first;
}

Cycle Cache::write(uint64_t addr, uint32_t size_bytes, Cycle now) {
    // The reference's two stages at once: each line's bank, then its tag at its lookup cycle.
    const uint64_t first = arrive_write(addr, size_bytes, now, lookup_done_);
    Cycle done = now;
    for (size_t k = 0; k < lookup_done_.size(); ++k) {
        done = std::max(done, lookup_done_[k]);
        if (params_.write_back) write_fn_(*this, first + k, lookup_done_[k], kSendWriteBack);
    }
    // Write-through: on to the next level once looked up, nothing allocated.
    if (!params_.write_back && next_) next_->write(addr, size_bytes, done);
    return done;
}

uint64_t Cache::arrive_write(uint64_t addr, uint32_t size_bytes, Cycle now,
                             std::vector<Cycle>& lookup_done) {
    ++write_requests;
    write_bytes += size_bytes;
    note_lookup(now);
    const auto [first, last] = line_range(addr, size_bytes);
    lookup_done.resize(last - first + 1);
    for (uint64_t line = first; line <= last; ++line) {
        const Cycle start = banks_[line & bank_mask_].reserve(now, 1);
        bank_conflict_cycles += start - now;
        lookup_done[line - first] = start + params_.hit_latency_cycles;
    }
    return first;
}

void Cache::write_tag(uint64_t line, Cycle at) {
    if (params_.write_back) write_fn_(*this, line, at, kQueueWriteBack);
}

void Cache::Slowest::hit(Cycle lookup_done, Cycle ready, uint64_t line) {
    const Cycle d = std::max(lookup_done, ready);
    if (d > done || !any) {
        done = d;
        any = true;
        hit_lookup_done = lookup_done;
        hit_line = line;
        is_hit = true;
    }
}

void Cache::Slowest::miss(Cycle d, const AccessBreakdown& line_bd) {
    if (d > done || !any) {
        done = d;
        any = true;
        is_hit = false;
        miss_bd = line_bd;
    }
}

void Cache::Slowest::charge(const Cache& cache, AccessBreakdown* bd, Cycle now) const {
    if (!bd) return;
    if (is_hit) {
        cache.charge_hit(bd, now, hit_lookup_done, done, hit_line);
    } else {
        for (int l = 0; l < kMemLevels; ++l) bd->cycles[l] += miss_bd.cycles[l];
    }
}

void Cache::charge_wait(AccessBreakdown* bd, uint64_t line, Cycle from, Cycle until) const {
    const int below = level_ == kLevelL1 ? kLevelL2 : kLevelDram;
    const InFlightFill* fill = &in_flight_[line & in_flight_mask_];
    if (!fill || fill->line != line || fill->ready != until) {
        bd->cycles[below] += until - from;
        return;
    }
    // The part of [from, until) inside [lo, hi).
    auto overlap = [&](Cycle lo, Cycle hi) {
        const Cycle a = std::max(from, lo), b = std::min(until, hi);
        return b > a ? b - a : 0;
    };
    bd->cycles[level_] += overlap(0, fill->issue_at);  // the fill still waited for an MSHR
    bd->cycles[kLevelL1] += overlap(fill->issue_at, fill->l1_end);  // an L1 below this cache
    bd->cycles[kLevelL2] += overlap(fill->l1_end, fill->l2_end);
    bd->cycles[kLevelDram] += overlap(fill->l2_end, fill->dram_end);
    bd->cycles[kLevelCrossbar] += overlap(fill->dram_end, fill->ready);
}

uint32_t Cache::free_mshrs_at(Cycle t) const {
    if (params_.mshrs <= 0) return UINT32_MAX;
    uint32_t n = 0;
    if (few_mshrs_) {
        for (const uint64_t key : mshr_keys_) n += key != ~uint64_t(0) && (key >> kMshrBits) <= t;
    } else {
        for (const Cycle free : mshr_free_) n += free <= t;
    }
    return n;
}

// The earliest-free MSHR (the ring's front) now frees at `ready`, which is never earlier: it
// leaves the front and `ready` goes in order from the back. A miss mostly completes after the
// ones in flight, so it usually stays at the back: one compare where a heap sifts log2(n) levels.
void Cache::replace_earliest_mshr(Cycle ready) {
    if (few_mshrs_) {
        mshr_keys_[mshr_pick_] = ready << kMshrBits | mshr_pick_;
        return;
    }
    Cycle* h = mshr_free_.data();
    const size_t n = mshr_free_.size();
    // The ring is full: the front's slot is the one after the back once the front leaves.
    size_t slot = mshr_front_;
    mshr_front_ = slot + 1 == n ? 0 : slot + 1;
    for (size_t k = 1; k < n; ++k) {
        const size_t before = slot == 0 ? n - 1 : slot - 1;
        if (h[before] <= ready) break;
        h[slot] = h[before];
        slot = before;
    }
    h[slot] = ready;
}

void Cache::count_first_fills(uint64_t base, uint64_t end) {
    first_fills_ = std::make_unique<LineFirstTouches>(base, end, params_.line_bytes);
}

void Cache::register_stats(StatsRegistry& reg) {
    const std::string block = name();
    reg.add(block, "accesses", &accesses, "line lookups");
    reg.add(block, "hits", &hits, "lookups that found the line (including lines still filling)");
    reg.add(block, "misses", &misses, "lookups that fetched the line from the next level");
    reg.add(block, "merged_misses", &merged_misses, "hits that waited for an in-flight fill");
    reg.add(block, "bytes_requested", &bytes_requested, "bytes delivered to the level above");
    reg.add(block, "fill_bytes", &fill_bytes, "bytes read from the level below");
    reg.add(block, "mshr_wait_cycles", &mshr_wait_cycles, "cycles misses waited for a free MSHR");
    reg.add(block, "bank_conflict_cycles", &bank_conflict_cycles,
            "cycles lookups waited for their bank");
    reg.add(block, "lookup_out_of_order", &lookup_out_of_order,
            "lookups that touched tag state after a lookup later in simulated time");
    reg.add(block, "mshr_out_of_order", &mshr_out_of_order,
            "misses that took an MSHR after a miss later in simulated time");
    if (first_fills_)
        reg.add(block, "first_fills", &first_fills_->count,
                "misses on lines of the BVH never held before (compulsory misses; sampled runs)");
    if (level_ == kLevelL1) return;  // the L1s are read-only
    if (prefetcher_) {
        reg.add(block, "prefetches", &prefetches, "lines fetched by the prefetcher");
        reg.add(block, "prefetches_dropped", &prefetches_dropped,
                "lines the prefetcher named that found no free MSHR (never fetched)");
        reg.add(block, "prefetch_hits", &prefetch_hits,
                "prefetched lines a demand lookup found before they left (useful prefetches)");
    }
    reg.add(block, "write_requests", &write_requests, "writes from the level above");
    reg.add(block, "write_bytes", &write_bytes, "bytes written from the level above");
    reg.add(block, "write_hits", &write_hits, "written lines that were present");
    reg.add(block, "write_misses", &write_misses,
            "written lines allocated without a fetch (write-back)");
    reg.add(block, "writebacks", &writebacks, "dirty lines written to the next level on eviction");
    reg.add(block, "writeback_bytes", &writeback_bytes, "bytes of dirty lines written back");
}

namespace {
nlohmann::json cache_entry(uint64_t accesses, uint64_t hits, uint64_t misses, uint64_t merged) {
    return {{"accesses", accesses},
            {"hits", hits},
            {"misses", misses},
            {"merged_misses", merged},
            {"hit_rate", ReportContext::ratio(double(hits), double(accesses))}};
}

// The prefetcher's figures, in a cache section that has one.
void add_prefetch_entry(nlohmann::json& e, uint64_t issued, uint64_t dropped, uint64_t useful) {
    e["prefetch"] = {{"issued", issued},
                     {"dropped", dropped},
                     {"useful", useful},
                     {"accuracy", ReportContext::ratio(double(useful), double(issued))}};
}
}  // namespace

nlohmann::json Cache::report(const ReportContext&) const {
    nlohmann::json e = cache_entry(accesses, hits, misses, merged_misses);
    if (prefetcher_) add_prefetch_entry(e, prefetches, prefetches_dropped, prefetch_hits);
    if (level_ != kLevelL1) {
        e["write_requests"] = write_requests;
        e["write_bytes"] = write_bytes;
        e["writebacks"] = writebacks;
        e["writeback_bytes"] = writeback_bytes;
        e["dirty_lines_at_end"] = uint64_t(std::count(dirty_.begin(), dirty_.end(), uint8_t(1)));
    }
    return e;
}

nlohmann::json Cache::report_total(const std::vector<const Cache*>& caches, const ReportContext&) {
    nlohmann::json e =
        cache_entry(sum_of(caches, &Cache::accesses), sum_of(caches, &Cache::hits),
                    sum_of(caches, &Cache::misses), sum_of(caches, &Cache::merged_misses));
    if (!caches.empty() && caches.front()->prefetching())
        add_prefetch_entry(e, sum_of(caches, &Cache::prefetches),
                           sum_of(caches, &Cache::prefetches_dropped),
                           sum_of(caches, &Cache::prefetch_hits));
    return e;
}

}  // namespace rtsim

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
}

// Stamps only order the ways of a set: replacing them by their rank within the set keeps every
// decision the same, and frees the 32-bit counter for another four billion uses.
void Cache::renumber_stamps() {
    const auto ways = size_t(params_.ways);
    std::vector<size_t> order(ways);
    for (uint64_t set = 0; set < params_.sets(); ++set) {
        uint32_t* st = stamps(set);
        for (size_t w = 0; w < ways; ++w) order[w] = w;
        std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return st[a] < st[b]; });
        uint32_t rank = 0;
        for (size_t w : order) st[w] = st[w] == 0 ? 0 : ++rank;  // invalid ways keep stamp 0
    }
    use_clock_ = uint32_t(ways);
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

void Cache::Slowest::hit(Cycle lookup_done, Cycle ready) {
    const Cycle d = std::max(lookup_done, ready);
    if (d > done || !any) {
        done = d;
        any = true;
        hit_lookup_done = lookup_done;
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

void Cache::Slowest::charge(AccessBreakdown* bd, int level, Cycle now) const {
    if (!bd) return;
    if (is_hit) {
        charge_hit(bd, level, now, hit_lookup_done, done);
    } else {
        for (int l = 0; l < kMemLevels; ++l) bd->cycles[l] += miss_bd.cycles[l];
    }
}

void Cache::charge_hit(AccessBreakdown* bd, int level, Cycle now, Cycle lookup_done, Cycle done) {
    // Waiting for a fill already in flight is time spent below this level.
    bd->cycles[level] += lookup_done - now;
    bd->cycles[std::min(level + 1, kMemLevels - 1)] += done - lookup_done;
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

template <int G>
Cycle Cache::access_line(uint64_t line_addr, Cycle now, Cycle lookup_done, Slowest& slowest,
                         bool breakdown) {
    const uint64_t set = set_of(line_addr);
    const int found = find_way<G>(set, line_addr);
    if (found >= 0) {
        const Cycle ready = hit<G>(set, found, lookup_done);
        slowest.hit(lookup_done, ready);
        return std::max(lookup_done, ready);
    }
    AccessBreakdown line_bd;
    const Cycle ready = fill<G>(set, line_addr, now, lookup_done, breakdown ? &line_bd : nullptr);
    slowest.miss(ready, line_bd);
    return ready;
}

template <int G>
Cycle Cache::fill(uint64_t set, uint64_t line_addr, Cycle now, Cycle lookup_done,
                  AccessBreakdown* bd) {
    const uint32_t* tag = tags<G>(set);
    // Miss: an invalid way if any, else the policy's victim. Invalid ways have stamp 0 and valid
    // ones a later stamp, so the oldest stamp is the first invalid way when there is one.
    int victim = -1;
    if (params_.replacement == CacheParams::Replacement::Random)
        for (int w = 0; w < params_.ways && victim < 0; ++w)
            if (tag[w] == kNoTag) victim = w;
    if (victim < 0) {
        if (params_.replacement == CacheParams::Replacement::Random) {
            rng_ ^= rng_ << 13;
            rng_ ^= rng_ >> 7;
            rng_ ^= rng_ << 17;
            victim = int(rng_ % uint64_t(params_.ways));
        } else {
            victim = oldest_way<G>(set);
        }
    }
    ++misses;
    fill_bytes += params_.line_bytes;
    if (fill_series_) fill_series_->add(lookup_done, params_.line_bytes);
    // MSHRs as the cycles they free, in order: take the earliest, give it back busy until this
    // miss's data returns.
    Cycle issue_at = lookup_done;
    const bool limited = few_mshrs_ || !mshr_free_.empty();
    if (limited) {
        issue_at = std::max(lookup_done, earliest_mshr());
        mshr_wait_cycles += issue_at - lookup_done;
    }
    if (bd) bd->cycles[level_] += issue_at - now;
    const Cycle ready = next_->access(line_addr << line_shift_, params_.line_bytes, issue_at, bd);
    if (limited) replace_earliest_mshr(ready);
    tags<G>(set)[victim] = tag_of(line_addr);
    fill_ready<G>(set)[victim] = ready;
    stamps<G>(set)[victim] = next_stamp();
    return ready;
}

bool Cache::access_local(uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
                         AccessBreakdown* bd) {
    switch (layout_) {
        case 1:
            return access_local_in<1>(addr, size_bytes, now, ready, bd);
        case 2:
            return access_local_in<2>(addr, size_bytes, now, ready, bd);
        case 4:
            return access_local_in<4>(addr, size_bytes, now, ready, bd);
        default:
            return access_local_in<0>(addr, size_bytes, now, ready, bd);
    }
}

Cycle Cache::access(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) {
    switch (layout_) {
        case 1:
            return access_in<1>(addr, size_bytes, now, bd);
        case 2:
            return access_in<2>(addr, size_bytes, now, bd);
        case 4:
            return access_in<4>(addr, size_bytes, now, bd);
        default:
            return access_in<0>(addr, size_bytes, now, bd);
    }
}

template <int G>
bool Cache::access_local_in(uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
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
    Cycle done[kMaxLines];
    Cycle first_done = 0;
    const bool one_bank = one_bank_reads(lines);
    if (one_bank)
        first_done = look_up_in_one_bank(first, lines, now);
    else
        look_up(first, last, now, done);
    // The slowest line decides (the first of equals); a hit waits for a fill still in flight.
    Cycle slowest = 0, slowest_lookup = 0;
    for (uint64_t k = 0; k < lines; ++k) {
        const Cycle lookup_done = one_bank ? first_done + k : done[k];
        const Cycle d = std::max(lookup_done, hit<G>(set_of(first + k), ways[k], lookup_done));
        const bool slower = k == 0 || d > slowest;
        slowest = slower ? d : slowest;
        slowest_lookup = slower ? lookup_done : slowest_lookup;
    }
    if (bd) charge_hit(bd, level_, now, slowest_lookup, slowest);
    ready = slowest;
    return true;
}

template <int G>
Cycle Cache::access_in(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) {
    bytes_requested += size_bytes;
    const auto [first, last] = line_range(addr, size_bytes);
    if (first == last) {  // one line (every request from the level above): no slowest to find
        const Cycle lookup_done = look_up_in_one_bank(first, 1, now);
        const uint64_t set = set_of(first);
        const int found = find_way<G>(set, first);
        if (found < 0) return fill<G>(set, first, now, lookup_done, bd);
        const Cycle ready = std::max(lookup_done, hit<G>(set, found, lookup_done));
        if (bd) charge_hit(bd, level_, now, lookup_done, ready);
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
        access_line<G>(first + k, now, one_bank ? first_done + k : lookup_done_[k], slowest,
                       bd != nullptr);
    slowest.charge(bd, level_, now);
    return std::max(now, slowest.done);
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

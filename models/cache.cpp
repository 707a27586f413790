#include "models/cache.h"

#include "models/line_map.h"

#include <algorithm>
#include <deque>
#include <functional>
#include <stdexcept>
#include <string>

namespace rtsim {

// A request is held here from its arrival to its answer (`held`, the id its stages carry); a
// miss's fill from its tag check to its line's arrival, with the requests waiting on it.
struct Cache::Timed {
    struct Waiter {
        uint32_t held;
        uint32_t k;  // its line
        Cycle from;  // when its tag check found the line still filling
    };
    struct Fill {
        uint64_t line = 0;
        Cycle requested = 0;  // the miss's tag check: it asks for an MSHR then
        Timeline timeline;    // from `requested` to the data's arrival
        std::vector<Waiter> waiters;
    };
    struct Wake {
        StageHandler* block;
        uint32_t kind, id, k;
    };
    IdPool<tlm::tlm_generic_payload*> held;
    IdPool<Fill> fills;
    LineMap in_flight;   // line -> its newest fill
    uint32_t mshrs = 0;  // 0: unlimited
    uint32_t busy = 0;
    // Lines of requests that have arrived and not yet been looked up, absent when they
    // arrived: misses to come, each of which will take an MSHR (may_load counts them taken).
    uint32_t pending_misses = 0;
    std::deque<uint32_t> waiting;  // fills waiting for an MSHR, first come first served
    std::vector<Wake> loaders;     // treelet loaders waiting for a free MSHR
    PayloadPool payloads;          // requests this cache sends below (fills, writes)
    std::vector<Cycle> lookup_done;
    std::vector<uint64_t> prefetch_lines;

    uint32_t hold(tlm::tlm_generic_payload& gp) { return held.add(&gp); }
    void wake_loaders(StageQueue& stages, Cycle t) {
        for (const Wake& w : loaders)
            stages.schedule(t, StageQueue::kMemoryOrder, w.block, w.kind, w.id, w.k);
        loaders.clear();
    }
};

Cache::Cache(sc_core::sc_module_name name, const CacheParams& params, TargetSocketBase* below,
             int level)
    : sc_core::sc_module(name),
      up("up"),
      down("down"),
      timed_(std::make_unique<Timed>()),
      params_(params),
      level_(level) {
    timed_->mshrs = uint32_t(std::max(0, params_.mshrs));
    up.register_nb_transport_fw<&Cache::nb_transport_fw>(this);
    up.register_b_transport<&Cache::b_transport>(this);
    down.register_nb_transport_bw(this, &Cache::nb_transport_bw);
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
    if (below) down.bind(*below);  // once nothing above can refuse the parameters
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
        warm_below(line_address(l));
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
    if (!params_.write_back && below_.bound()) below_.write(addr, size_bytes, done);
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

// ---- The time-ordered side (sim.fidelity = accurate) ----

IdealMemory::IdealMemory(sc_core::sc_module_name name, Cycle hit_latency_cycles)
    : sc_core::sc_module(name), up("up"), latency_(hit_latency_cycles) {
    up.register_nb_transport_fw<&IdealMemory::nb_transport_fw>(this);
    up.register_b_transport<&IdealMemory::b_transport>(this);
}

tlm::tlm_sync_enum IdealMemory::nb_transport_fw(int id, tlm::tlm_generic_payload& gp,
                                                tlm::tlm_phase& phase, sc_core::sc_time& delay) {
    if (gp.is_write()) {  // nothing below to write to
        gp.set_response_status(tlm::TLM_OK_RESPONSE);
        return tlm::TLM_COMPLETED;
    }
    MemoryRequest& r = memory_request(gp);
    r.push_route(id);
    const uint32_t h = held_.add(&gp);
    const Cycle at = stages_->now() + delay_cycles(delay);
    if (r.queued)
        stages_->schedule(at, StageQueue::kMemoryOrder, this, kArriveStage, h);
    else
        arrive(h, at);
    phase = tlm::END_REQ;
    return tlm::TLM_UPDATED;
}

// The data is there after the hit latency (at once for a request that reads nothing).
void IdealMemory::arrive(uint32_t h, Cycle t) {
    const Cycle ready = held_[h]->get_data_length() == 0 ? t : access(0, 0, t);
    stages_->schedule(ready, StageQueue::kMemoryOrder, this, kAnswerStage, h);
}

void IdealMemory::run_stage(uint32_t kind, uint32_t h, uint32_t, Cycle t) {
    if (kind == kArriveStage) {
        arrive(h, t);
        return;
    }
    tlm::tlm_generic_payload& gp = *held_[h];
    held_.remove(h);
    MemoryRequest& r = memory_request(gp);
    r.timeline = Timeline(r.start);
    r.timeline.add(t, kLevelL1);
    gp.set_response_status(tlm::TLM_OK_RESPONSE);
    tlm::tlm_phase phase = tlm::BEGIN_RESP;
    sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
    up[r.pop_route()]->nb_transport_bw(gp, phase, delay);
}

// Requests the payload's owner tags mean at this cache's `down` socket.
namespace {
enum BelowRequest : uint32_t { kFillRequest, kWriteRequest };
}

Cache::~Cache() = default;

void Cache::run_stage(uint32_t kind, uint32_t id, uint32_t k, Cycle t) {
    switch (kind) {
        case kArriveStage:
            timed_arrive(id, t);
            break;
        case kTagStage:
            timed_tag(id, k, t);
            break;
        case kEmptyStage: {  // reads nothing: done at once, charged to the first level
            Timeline tl(memory_request(*timed_->held[id]).start);
            tl.add(t, kLevelL1);
            line_done(id, 0, t, tl);
            break;
        }
        case kWriteArriveStage:
            timed_write_arrive(id, t);
            break;
        case kWriteTagStage:
            timed_write_tag(id, k, t);
            break;
    }
}

// A request reaches the cache: it is looked up from the cycle it arrives, within the call or, when
// it is queued, as a stage of its own.
tlm::tlm_sync_enum Cache::nb_transport_fw(int id, tlm::tlm_generic_payload& gp,
                                          tlm::tlm_phase& phase, sc_core::sc_time& delay) {
    if (phase != tlm::BEGIN_REQ) throw std::logic_error(name() + std::string(": unexpected phase"));
    MemoryRequest& r = memory_request(gp);
    r.push_route(id);
    const Cycle at = stages_->now() + delay_cycles(delay);
    const uint32_t h = timed_->hold(gp);
    if (r.queued)
        stages_->schedule(at, StageQueue::kMemoryOrder, this,
                          gp.is_write() ? kWriteArriveStage : kArriveStage, h);
    else if (gp.is_write())
        timed_write_arrive(h, at);
    else
        timed_arrive(h, at);
    phase = tlm::END_REQ;
    return tlm::TLM_UPDATED;
}

void Cache::timed_arrive(uint32_t h, Cycle t) {
    tlm::tlm_generic_payload& gp = *timed_->held[h];
    MemoryRequest& r = memory_request(gp);
    if (gp.get_data_length() == 0) {  // reads nothing (an any-hit shader without alpha data)
        r.lines_left = 1;
        stages_->schedule(t, StageQueue::kMemoryOrder, this, kEmptyStage, h);
        return;
    }
    std::vector<Cycle>& lookup = timed_->lookup_done;
    r.first_line = arrive(gp.get_address(), gp.get_data_length(), t, lookup);
    r.lines_left = uint32_t(lookup.size());
    if (counts_pending_misses_) count_pending_misses(r);
    for (uint32_t k = 0; k < lookup.size(); ++k)
        stages_->schedule(lookup[k], StageQueue::kMemoryOrder, this, kTagStage, h, k);
}

// The lines of request r, just arrived, that will take an MSHR when looked up (pending_misses of
// the cache whose MSHRs they take): absent here, and, for a cache without MSHRs of its own (a
// treelet cache), absent from the cache behind it as well.
void Cache::count_pending_misses(MemoryRequest& r) {
    Cache* limit = mshr_owner();
    if (!limit) return;  // unlimited MSHRs
    const uint32_t lines = std::min<uint32_t>(r.lines_left, 64);
    for (uint32_t k = 0; k < lines; ++k) {
        const uint64_t addr = line_address(r.first_line + k);
        if (!contains(addr) && (limit == this || !limit->contains(addr))) {
            r.pending_lines |= uint64_t(1) << k;
            ++limit->timed_->pending_misses;
        }
    }
}

bool Cache::may_load(uint64_t addr, StageHandler* waker, uint32_t kind, uint32_t id, uint32_t k) {
    if (contains(addr)) return true;
    Cache* limit = mshr_owner();
    if (!limit) return true;
    Timed& st = *limit->timed_;
    if (st.busy + st.pending_misses < st.mshrs) return true;
    st.loaders.push_back({waker, kind, id, k});
    return false;
}

// Line k of a request is looked up at t.
void Cache::timed_tag(uint32_t h, uint32_t k, Cycle t) {
    MemoryRequest& r = memory_request(*timed_->held[h]);
    const uint64_t line = r.first_line + k;
    Timed* pending_at = nullptr;  // where it was counted as a miss to come
    if (k < 64 && (r.pending_lines >> k & 1)) {
        r.pending_lines &= ~(uint64_t(1) << k);
        pending_at = mshr_owner()->timed_.get();
        --pending_at->pending_misses;
    }
    const bool hit = check_tag(line, t);
    if (!queued_writebacks_.empty()) send_writebacks(t);
    Timed& st = *timed_;
    if (hit) {
        // A miss that did not come: a loader waiting on it may go on.
        if (pending_at && !pending_at->loaders.empty()) pending_at->wake_loaders(*stages_, t);
        if (const uint32_t* fill = st.in_flight.find(line)) {  // still filling: wait for it
            ++merged_misses;                                   // (a merged miss)
            st.fills[*fill].waiters.push_back({h, k, t});
            return;
        }
        Timeline tl(r.start);
        tl.add(t, level_);
        line_done(h, k, t, tl);
        return;
    }
    const uint32_t f = new_fill(line, t);
    st.fills[f].waiters.push_back({h, k, t});
    if (st.mshrs) request_mshr(t);
    if (st.mshrs == 0 || st.busy < st.mshrs) {
        if (st.mshrs) ++st.busy;
        issue_fill(f, t);
    } else {
        st.waiting.push_back(f);
    }
    if (prefetching()) timed_prefetch(line, t);
}

// After a demand miss of `line` at t, the prefetcher's lines (models/prefetcher.h): each one not
// held takes an MSHR free now or is dropped, and is fetched as a fill nobody waits for yet.
void Cache::timed_prefetch(uint64_t line, Cycle t) {
    Timed& st = *timed_;
    prefetch_candidates(line, st.prefetch_lines);
    for (const uint64_t l : st.prefetch_lines) {
        if (contains(line_address(l))) continue;  // held or filling
        if (st.mshrs && st.busy >= st.mshrs) {
            ++prefetches_dropped;
            continue;
        }
        install_prefetch(l, t);
        if (!queued_writebacks_.empty()) send_writebacks(t);
        if (st.mshrs) {
            request_mshr(t);
            ++st.busy;
        }
        issue_fill(new_fill(l, t), t);
    }
}

// A fill of `line` from its tag check at t, the line's newest in flight (an older fill of the
// line, evicted while filling, ends unseen).
uint32_t Cache::new_fill(uint64_t line, Cycle t) {
    Timed& st = *timed_;
    const uint32_t f = st.fills.take();
    Timed::Fill& F = st.fills[f];
    F.line = line;
    F.requested = t;
    F.timeline = Timeline(t);
    F.waiters.clear();
    st.in_flight.set(line, f);
    return f;
}

// A miss holding an MSHR from t asks the next level for its line.
void Cache::issue_fill(uint32_t f, Cycle t) {
    Timed::Fill& F = timed_->fills[f];
    mshr_wait_cycles += t - F.requested;
    F.timeline.add(t, level_);
    tlm::tlm_generic_payload& gp = timed_->payloads.acquire(
        tlm::TLM_READ_COMMAND, line_address(F.line), params_.line_bytes, t);
    MemoryRequest& r = memory_request(gp);
    r.owner_kind = kFillRequest;
    r.owner_id = f;
    tlm::tlm_phase phase = tlm::BEGIN_REQ;
    sc_core::sc_time delay = cycles_delay(t - stages_->now());
    down->nb_transport_fw(gp, phase, delay);
}

// An answer from the next level: a fill's line is there now; a write was accepted.
tlm::tlm_sync_enum Cache::nb_transport_bw(tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                          sc_core::sc_time&) {
    if (phase != tlm::BEGIN_RESP)
        throw std::logic_error(name() + std::string(": unexpected phase"));
    MemoryRequest& r = memory_request(gp);
    if (r.owner_kind == kFillRequest) {
        const uint32_t f = r.owner_id;
        timed_->fills[f].timeline.append(r.timeline);
        timed_->payloads.release(gp);
        fill_done(f, stages_->now());
    } else {
        timed_->payloads.release(gp);
    }
    phase = tlm::END_RESP;
    return tlm::TLM_COMPLETED;
}

// A fill's line is there at t: its MSHR goes to the next miss waiting, and every request that
// waited on the line goes on, charged for the wait where the fill was at each cycle.
void Cache::fill_done(uint32_t f, Cycle t) {
    Timed& st = *timed_;
    Timed::Fill& F = st.fills[f];
    if (uint32_t* newest = st.in_flight.find(F.line); newest && *newest == f)
        st.in_flight.erase(newest);
    if (st.mshrs) {
        if (!st.waiting.empty()) {
            const uint32_t next = st.waiting.front();
            st.waiting.pop_front();
            issue_fill(next, t);
        } else {
            --st.busy;
            st.wake_loaders(*stages_, t);
        }
    }
    std::vector<Timed::Waiter> waiters;
    waiters.swap(st.fills[f].waiters);
    const Timeline fill_timeline = st.fills[f].timeline;
    st.fills.remove(f);
    for (const Timed::Waiter& w : waiters) {
        Timeline tl(memory_request(*st.held[w.held]).start);
        tl.add(w.from, level_);
        tl.add_overlap(fill_timeline, w.from, t);
        line_done(w.held, w.k, t, tl);
    }
}

void Cache::line_done(uint32_t h, uint64_t k, Cycle t, const Timeline& timeline) {
    MemoryRequest& r = memory_request(*timed_->held[h]);
    if (!r.any || t > r.done || (t == r.done && k < r.slowest_k)) {
        r.any = true;
        r.done = t;
        r.slowest_k = k;
        r.timeline = timeline;
    }
    if (--r.lines_left == 0) respond(h);
}

// Every line of the request is done at t (a write: looked up): the answer goes back the way it
// came.
void Cache::respond(uint32_t h) {
    tlm::tlm_generic_payload& gp = *timed_->held[h];
    timed_->held.remove(h);
    gp.set_response_status(tlm::TLM_OK_RESPONSE);
    tlm::tlm_phase phase = tlm::BEGIN_RESP;
    sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
    up[memory_request(gp).pop_route()]->nb_transport_bw(gp, phase, delay);
}

void Cache::timed_write_arrive(uint32_t h, Cycle t) {
    tlm::tlm_generic_payload& gp = *timed_->held[h];
    MemoryRequest& r = memory_request(gp);
    r.first_line = arrive_write(gp.get_address(), gp.get_data_length(), t, timed_->lookup_done);
    r.lines_left = uint32_t(timed_->lookup_done.size());
    for (uint32_t k = 0; k < timed_->lookup_done.size(); ++k)
        stages_->schedule(timed_->lookup_done[k], StageQueue::kMemoryOrder, this, kWriteTagStage, h,
                          k);
}

void Cache::timed_write_tag(uint32_t h, uint32_t k, Cycle t) {
    tlm::tlm_generic_payload& gp = *timed_->held[h];
    MemoryRequest& r = memory_request(gp);
    write_tag(r.first_line + k, t);
    send_writebacks(t);
    if (--r.lines_left > 0) return;
    // Write-through: on to the next level once every line is looked up (as the fast model).
    if (!params_.write_back && below_.bound())
        send_write(gp.get_address(), gp.get_data_length(), t);
    respond(h);
}

// Dirty lines evicted (by a write's allocation, a miss's or a prefetch's fill) go below.
void Cache::send_writebacks(Cycle t) {
    for (const uint64_t line : queued_writebacks_)
        send_write(line_address(line), params_.line_bytes, t);
    queued_writebacks_.clear();
}

void Cache::send_write(uint64_t addr, uint32_t size_bytes, Cycle t) {
    tlm::tlm_generic_payload& gp =
        timed_->payloads.acquire(tlm::TLM_WRITE_COMMAND, addr, size_bytes, t);
    MemoryRequest& r = memory_request(gp);
    r.owner_kind = kWriteRequest;
    tlm::tlm_phase phase = tlm::BEGIN_REQ;
    sc_core::sc_time delay = cycles_delay(t - stages_->now());
    if (down->nb_transport_fw(gp, phase, delay) == tlm::TLM_COMPLETED) timed_->payloads.release(gp);
}

}  // namespace rtsim

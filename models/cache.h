// A set-associative, read-only (BVH data is never written during traversal) cache with a
// replacement policy chosen by name (models/replacement/, one file each).
// Loosely timed: a hit costs `hit_latency_cycles`; a miss adds the next level's latency.
// A line stays "filling" until its data arrives, so a second access to it waits for the same
// fill instead of issuing another (miss merging). A miss holds one of `mshrs` registers until its
// data returns; with all of them busy, the next miss waits (Little's law bounds the bandwidth).
#pragma once

#include <algorithm>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include <string>
#include <systemc>
#include <utility>
#include <vector>

#include "models/calendar.h"
#include "models/prefetcher.h"
#include "models/replacement.h"
#include "models/stats.h"
#include "models/timing.h"
#include "models/transaction.h"

namespace rtsim {

// Defaults: the schema's l1 defaults (tests/sim/test_params.cpp checks they agree).
struct CacheParams {
    uint64_t size_bytes = 32 * 1024;
    int ways = 4;
    uint32_t line_bytes = 64;
    Cycle hit_latency_cycles = 4;
    int mshrs = 16;  // misses in flight at once (miss status holding registers); 0: unlimited
    std::string replacement = "lru";  // a registered replacement policy (rtsim list)
    int rrpv_bits = 2;                // SRRIP: bits of a re-reference prediction value
    int banks = 1;                    // line-interleaved banks, each starting one lookup per cycle
    // Lookups come in non-decreasing time (a private L1 behind its core's in-order issue
    // port): the banks keep only their next free cycle (ReservationCalendar::assume_in_order).
    bool in_order_requests = false;
    // Writes (stack spills, hit records; only a cache below the L1s gets them): write_back keeps
    // a written line dirty until it is evicted (allocating a missing line without fetching it:
    // the writer supplies the bytes it reads back), write_through sends every write on.
    bool write_back = true;
    // A registered prefetcher (models/prefetcher.h; "none": demand misses only) and the lines it
    // may name per demand miss.
    std::string prefetcher = "none";
    int prefetch_degree = 1;
    // Addresses stay below this: tags are stored in 32 bits (the constructor refuses a cache
    // whose tags would not fit).
    uint64_t address_limit_bytes = uint64_t(1) << 36;

    uint64_t sets() const { return size_bytes / (uint64_t(ways) * line_bytes); }
};

// Ideal memory: every access is an L1 hit (an upper bound on what caches can give). It has no
// state: requests through `up` are answered after the latency, and writes are taken at once.
class IdealMemory final : public sc_core::sc_module, public MemoryPort, private StageHandler {
  public:
    IdealMemory(sc_core::sc_module_name name, Cycle hit_latency_cycles);
    Cycle access(uint64_t, uint32_t, Cycle now, AccessBreakdown* bd = nullptr) override {
        if (bd) bd->cycles[kLevelL1] += latency_;
        return now + latency_;
    }
    bool access_local(uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
                      AccessBreakdown* bd = nullptr) override {
        ready = access(addr, size_bytes, now, bd);
        return true;
    }
    TargetSocket<IdealMemory> up;
    void set_stage_queue(StageQueue* queue) { stages_ = queue; }

  private:
    void b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
        serve_loosely_timed(*this, gp, delay);
    }
    enum Stage : uint32_t { kArriveStage, kAnswerStage };
    void run_stage(uint32_t kind, uint32_t id, uint32_t k, Cycle t) override;
    tlm::tlm_sync_enum nb_transport_fw(int id, tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time& delay);
    void arrive(uint32_t held, Cycle t);
    Cycle latency_;
    StageQueue* stages_ = nullptr;
    IdPool<tlm::tlm_generic_payload*> held_;
};

// A bit per line of an address range (in lines of `line_bytes`), set at the line's first touch,
// and how many first touches counted (`count`; warming touches without counting). A sampled
// run's first fills: the L2's misses on BVH lines never held (Cache::count_first_fills), or, with
// a prefetcher, the lines a ray first asks for (Cache::count_first_demands).
struct LineFirstTouches {
    uint64_t first_line = 0, lines = 0, count = 0;
    uint32_t line_shift = 6;
    std::vector<uint64_t> bits;
    LineFirstTouches(uint64_t base, uint64_t end, uint32_t line_bytes) {
        line_shift = uint32_t(__builtin_ctz(line_bytes));
        first_line = base >> line_shift;
        lines = end > base ? ((end - 1) >> line_shift) - first_line + 1 : 0;
        bits.assign((lines + 63) / 64, 0);
    }
    void touch(uint64_t addr, bool counted) {
        const uint64_t k = (addr >> line_shift) - first_line;
        if ((addr >> line_shift) < first_line || k >= lines) return;
        const uint64_t bit = uint64_t(1) << (k % 64);
        count += counted && (bits[k / 64] & bit) == 0;
        bits[k / 64] |= bit;
    }
};

class Cache final : public sc_core::sc_module, public MemoryPort, private StageHandler {
  public:
    // `level` names the level for stall attribution (kLevelL1, kLevelL2).
    // `below`, when given, is bound to `down` here (the next level's target socket).
    Cache(sc_core::sc_module_name name, const CacheParams& params, TargetSocketBase* below,
          int level = kLevelL1);
    ~Cache() override;
    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* breakdown = nullptr) override {
        return access_fn_(*this, addr, size_bytes, now, breakdown);
    }
    // Served locally when every line of the request is present (or already being filled).
    bool access_local(uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
                      AccessBreakdown* breakdown = nullptr) override {
        return local_fn_(*this, addr, size_bytes, now, ready, breakdown);
    }
    void register_stats(StatsRegistry& reg);  // under this module's name (l1[3].hits)
    // Counts the first fills of lines in [base, end) (counter first_fills, registered only
    // then): misses on lines this cache never held, its compulsory misses. A sampled run knows
    // the frame's total of them (its distinct lines), and each measured unit's own count, timed
    // as its DRAM traffic is, is the regression's best auxiliary for that traffic. Call before
    // register_stats.
    void count_first_fills(uint64_t base, uint64_t end);
    // stats.json "caches" entry: lookups, hits, misses, merged misses, hit rate.
    nlohmann::json report(const ReportContext& ctx) const;
    // The same over several caches (all L1s: "l1_total").
    static nlohmann::json report_total(const std::vector<const Cache*>& caches,
                                       const ReportContext& ctx);
    void set_series(TimeSeries* fill_bytes) { fill_series_ = fill_bytes; }
    const CacheParams& params() const { return params_; }
    // Tests: start the replacement stamps' counter here (to see it wrap).
    void set_stamp_clock(uint32_t stamp) { repl_.clock = stamp; }
    // Compiles this cache's hot paths for policy P (a registered policy's `bind`; the template
    // body is in models/cache_impl.h, which a policy's file includes).
    template <typename P>
    static void use_policy(Cache& cache);
    // Whether a prefetcher is configured (the time-ordered reference then runs its prefetches).
    bool prefetching() const { return prefetcher_ != nullptr; }
    // The lines the prefetcher names after a demand miss of `line` (line addresses), those
    // beyond the cache's address limit left out; into `out`, replacing what it held.
    void prefetch_candidates(uint64_t line, std::vector<uint64_t>& out);
    // The reference's prefetch of `line` at `at`, its MSHR already taken: installed as a miss
    // installs a line (a dirty victim queued, queued_writebacks) and counted; false, changing
    // nothing, when the line is held or filling.
    bool install_prefetch(uint64_t line, Cycle at) { return prefetch_fn_(*this, line, at); }
    // Functional warming of the prefetches after a miss of `line`: each named line not held is
    // installed as warm() installs a line (uncounted), and warmed in the next level.
    void warm_prefetches(uint64_t line);
    // Sampled runs with a prefetcher: demand lookups here (a cache the cores ask first) mark
    // the frame's lines in `touches`, whose count stands for the L2's first fills. Lines a
    // prefetch brought are then counted when a ray first asks for them, as the frame's profile
    // counts its distinct lines, and never if none does.
    void count_first_demands(LineFirstTouches* touches) { first_touch_ = touches; }
    // The earliest cycle a lookup may still come at (the requesters' floor).
    void follow(const TimeFloor* floor) {
        for (auto& bank : banks_) bank.follow(floor);
    }

    // The time-ordered engine's side (sim.fidelity = accurate; models/transaction.h): requests
    // come through `up` and are served stage by stage on the StageQueue: each line's tag check
    // at its lookup cycle, a miss's MSHR (first come first served, the misses waiting for one
    // queued), its fill from the next level through `down`, the requests merged on it woken when
    // it completes. Dirty victims and write-through writes leave through `down` as posted writes.
    // The fast engine's side (sim.fidelity = fast): b_transport on `up` is access(), write(),
    // access_local() or warm() (models/transaction.h), whose misses and writes go on through
    // `down` the same way.
    TargetSocket<Cache> up;
    InitiatorSocket<Cache> down;
    void set_stage_queue(StageQueue* queue) { stages_ = queue; }
    // A treelet loader is about to send a line (Core::run_loader): whether its miss would find an
    // MSHR of the cache whose MSHRs it takes, counting the misses on their way to their lookup as
    // taking theirs (the fast engine books a miss's MSHR when it is issued). If not, the
    // loader's stage (`waker`, kind, id, k) is scheduled when one frees or such a miss turns out
    // a hit. Call set_treelet_loads first.
    bool may_load(uint64_t addr, StageHandler* waker, uint32_t kind, uint32_t id, uint32_t k);
    // A core's treelet loader sends lines here: arriving requests count their misses to come.
    void set_treelet_loads() { counts_pending_misses_ = true; }

    // Split-phase steps of a request (the time-ordered side above calls each at its own cycle).
    // A request arriving at `now`: counts it and reserves its banks; returns its first line and
    // sets `lookup_done[k]` to the cycle line first + k is looked up.
    uint64_t arrive(uint64_t addr, uint32_t size_bytes, Cycle now, std::vector<Cycle>& lookup_done);
    // Line `line`'s tag check at `at`: a hit updates the replacement state; a miss takes the
    // policy's victim and installs the line (counted as the fast path counts them). True on a hit.
    bool check_tag(uint64_t line, Cycle at) { return tag_fn_(*this, line, at); }
    // MemoryPort::warm: each line's tag check as check_tag makes it, uncounted, its fill ready
    // at once; a line missing here is warmed in the next level too.
    // With a prefetcher, a line missing here also warms the lines it would prefetch.
    void warm(uint64_t addr, uint32_t size_bytes) override {
        const auto [first, last] = line_range(addr, size_bytes);
        for (uint64_t line = first; line <= last; ++line)
            if (!warm_fn_(*this, line, 0)) {
                below_.warm(line << line_shift_, params_.line_bytes);
                if (prefetcher_) warm_prefetches(line);
            }
    }
    // Warms one line (an address in lines of this cache) here only, as warm() does, and says
    // whether it was held: the sampler's replay calls it directly and warms the next level itself
    // on a miss, without warm()'s virtual calls and loop over a request's lines.
    bool warm_line(uint64_t line) { return warm_fn_(*this, line, 0); }
    // A posted write: each line's lookup takes its bank; write-back marks the line dirty (a
    // missing line is allocated without a fetch, its victim written back if dirty);
    // write-through passes the write on. Returns the cycle the last line was looked up.
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override;
    void warm_write(uint64_t addr, uint32_t size_bytes) override {
        const auto [first, last] = line_range(addr, size_bytes);
        for (uint64_t line = first; line <= last; ++line) {
            if (params_.write_back)
                write_fn_(*this, line, 0, kWarmWriteBack);
            else
                below_.warm(line << line_shift_, params_.line_bytes, true);
        }
    }
    // The time-ordered reference's write: bank reservations at `now` (lookup_done as arrive()),
    // then write_tag at each line's lookup cycle. Dirty victims evicted by write_tag and by
    // check_tag are queued, not sent: the time-ordered side sends them as writes (send_writebacks).
    uint64_t arrive_write(uint64_t addr, uint32_t size_bytes, Cycle now,
                          std::vector<Cycle>& lookup_done);
    void write_tag(uint64_t line, Cycle at);
    uint64_t line_address(uint64_t line) const { return line << line_shift_; }
    // Warms the line holding `addr` in the levels below this one (a warming caller that has
    // found it missing here).
    void warm_below(uint64_t addr) { below_.warm(addr, params_.line_bytes); }
    // This cache's misses take the MSHRs of `next`, the cache of the same level behind it (a
    // treelet cache in front of its L1, which has no MSHRs of its own).
    void take_mshrs_of(Cache* next) { same_level_next_ = next; }
    int level() const { return level_; }
    // Whether the line holding `addr` is present (or being filled); changes nothing.
    bool contains(uint64_t addr) const {
        const uint64_t line = addr >> line_shift_;
        return find_way<0>(set_of(line), line) >= 0;
    }
    // First and last line address a request touches.
    std::pair<uint64_t, uint64_t> line_range(uint64_t addr, uint32_t size_bytes) const {
        return {addr >> line_shift_, (addr + std::max<uint32_t>(size_bytes, 1) - 1) >> line_shift_};
    }
    // A miss asks for one of a limited number of MSHRs at `t`: counted in mshr_out_of_order
    // when an earlier request came at a later cycle. The fast model's misses ask here from
    // fill(); the time-ordered reference, which keeps its own MSHR queue, asks as each miss
    // reaches it, so both engines' counts come from the cache.
    void request_mshr(Cycle t) {
        mshr_out_of_order += t < latest_mshr_request_;
        latest_mshr_request_ = std::max(latest_mshr_request_, t);
    }
    // MSHRs free at `t`, for misses from then on (UINT32_MAX when they are unlimited).
    uint32_t free_mshrs_at(Cycle t) const;
    // A miss looked up from `now` on: the cycle it can first leave for the next level, when all
    // MSHRs are busy until later (otherwise `now`). A cache with unlimited MSHRs in front of
    // another of the same level (a treelet cache before its L1) leaves through that one's.
    // The fast model's cores hold such a miss back until then: the shared levels below see it
    // in time order.
    Cycle miss_leaves_at(Cycle now) {
        if (few_mshrs_ || !mshr_free_.empty()) return std::max(now, earliest_mshr());
        return same_level_next_ ? same_level_next_->miss_leaves_at(now) : now;
    }

    uint64_t accesses = 0;  // line lookups (a request spanning two lines counts two)
    uint64_t hits = 0;
    uint64_t misses = 0;
    uint64_t merged_misses = 0;         // hits on a line whose fill was still in flight
    uint64_t bytes_requested = 0;       // bytes delivered to the level above
    uint64_t fill_bytes = 0;            // bytes read from the level below
    uint64_t mshr_wait_cycles = 0;      // cycles misses waited for a free MSHR
    uint64_t bank_conflict_cycles = 0;  // cycles lookups waited for their bank
    // Served out of simulated-time order (the cache meets requests in the order the simulator
    // does): lookups that touched tag and replacement state after a later lookup, and misses
    // that took an MSHR after a later miss.
    uint64_t lookup_out_of_order = 0;
    uint64_t mshr_out_of_order = 0;
    // Writes from the level above (posted): requests, line lookups that found or allocated the
    // line, bytes; dirty lines written back to the next level on eviction.
    uint64_t write_requests = 0, write_hits = 0, write_misses = 0, write_bytes = 0;
    uint64_t writebacks = 0, writeback_bytes = 0;
    // With count_first_fills: misses on lines never held before.
    uint64_t first_fills() const { return first_fills_ ? first_fills_->count : 0; }
    // With a prefetcher: lines prefetched, prefetches dropped for want of a free MSHR, and
    // demand lookups that found a prefetched line before any other demand lookup had (useful).
    uint64_t prefetches = 0, prefetches_dropped = 0, prefetch_hits = 0;

  private:
    // The time-ordered side (cache.cpp).
    struct Timed;
    std::unique_ptr<Timed> timed_;
    StageQueue* stages_ = nullptr;
    bool counts_pending_misses_ = false;
    enum TimedStage : uint32_t {
        kArriveStage,
        kTagStage,
        kEmptyStage,
        kWriteArriveStage,
        kWriteTagStage
    };
    void run_stage(uint32_t kind, uint32_t id, uint32_t k, Cycle t) override;
    tlm::tlm_sync_enum nb_transport_fw(int id, tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time& delay);
    tlm::tlm_sync_enum nb_transport_bw(tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time& delay);
    void timed_arrive(uint32_t held, Cycle t);
    void timed_tag(uint32_t held, uint32_t k, Cycle t);
    void timed_write_arrive(uint32_t held, Cycle t);
    void timed_write_tag(uint32_t held, uint32_t k, Cycle t);
    void count_pending_misses(MemoryRequest& r);
    uint32_t new_fill(uint64_t line, Cycle t);
    void issue_fill(uint32_t fill, Cycle t);
    void fill_done(uint32_t fill, Cycle t);
    void timed_prefetch(uint64_t line, Cycle t);
    void line_done(uint32_t held, uint64_t k, Cycle t, const Timeline& timeline);
    void respond(uint32_t held);
    void send_writebacks(Cycle t);
    void send_write(uint64_t addr, uint32_t size_bytes, Cycle t);
    // The cache whose MSHRs this one's misses take: its own, or, with unlimited MSHRs in front
    // of a cache of its level (a treelet cache before its L1), that one's; nullptr: unlimited.
    Cache* mshr_owner() {
        Cache* c = this;
        while (c && c->params_.mshrs == 0) c = c->same_level_next_;
        return c;
    }
    LineFirstTouches* first_touch_ = nullptr;
    [[gnu::always_inline]] void demand(uint64_t line, bool counted = true) {
        if (first_touch_) first_touch_->touch(line << line_shift_, counted);
    }
    // Per set and way with a prefetcher: nonzero while the line there came by a prefetch and no
    // demand lookup has found it yet (kTimedPrefetch, kWarmPrefetch).
    std::vector<uint8_t> prefetched_;
    std::unique_ptr<Prefetcher> prefetcher_;
    std::vector<uint64_t> prefetch_lines_;  // scratch: the prefetcher's lines for one miss
    // A demand lookup (`counted`: a timed one, not warming) found the line of `way`: a line a
    // prefetch brought is useful, and, with LineFirstTouches, asked for now. (A line any
    // other way brought was asked for when it came: demand() is called on misses only.)
    [[gnu::noinline]] void note_prefetch_hit(uint64_t set, int way, bool counted = true) {
        uint8_t& p = prefetched_[way_index(set, way)];
        if (p == 0) return;
        if (first_touch_)
            first_touch_->touch(
                uint64_t(tags(set)[way]) << set_shift_ << line_shift_ | set << line_shift_,
                counted);
        prefetch_hits += counted && p == kTimedPrefetch;
        p = 0;
    }
    // prefetched_ values: brought by a timed prefetch, or by warming's (never counted useful).
    static constexpr uint8_t kTimedPrefetch = 1, kWarmPrefetch = 2;
    // A way refilled by anything but a prefetch.
    [[gnu::always_inline]] void clear_prefetched(uint64_t set, int way) {
        if (!prefetched_.empty()) prefetched_[way_index(set, way)] = 0;
    }
    // Installs a prefetched line in `set` at `at` (victim, write-back per `mode`, counters);
    // returns its way. Its fill cycle is the caller's to set.
    template <int G, typename P>
    int install_prefetched(uint64_t set, uint64_t line, Cycle at, int mode);
    // The fast model's prefetches after a demand miss of `line` looked up at `at`.
    template <int G, typename P>
    [[gnu::noinline]] void prefetch(uint64_t line, Cycle at);
    bool (*prefetch_fn_)(Cache&, uint64_t, Cycle) = nullptr;
    template <int G, typename P>
    static bool prefetch_entry(Cache& c, uint64_t line, Cycle at);
    // A line filled (by a miss or by warming; `counted`: a counted miss): counts a first fill.
    [[gnu::always_inline]] void mark_filled(uint64_t line, bool counted) {
        if (first_fills_) first_fills_->touch(line << line_shift_, counted);
    }
    std::unique_ptr<LineFirstTouches> first_fills_;  // count_first_fills: the lines once held
    // A set is one block: its ways' 32-bit tags, their 32-bit replacement stamps (LRU use or
    // FIFO fill order), then their fill cycles; 64 bytes for 4 ways, so a lookup touches one
    // host cache line.
    static constexpr uint32_t kNoTag = ~uint32_t(0);
    uint64_t set_of(uint64_t line_addr) const { return line_addr & set_mask_; }
    // A way's place in per-way arrays (dirty bits, prefetch marks): set-major.
    size_t way_index(uint64_t set, int way) const {
        return size_t(set * uint64_t(params_.ways) + uint64_t(way));
    }
    uint32_t tag_of(uint64_t line_addr) const { return uint32_t(line_addr >> set_shift_); }
    // The hot paths see the set layout with a compile-time associativity of 4 * G ways, so sizes
    // and offsets are constants (G = 0: the configured associativity, read at run time).
    template <int G>
    int ways_of() const {
        return rtsim::ways_of<G>(repl_);
    }
    template <int G = 0>
    char* set_block(uint64_t set) {
        return set_blocks_ + set * (G ? 64 * uint64_t(G) : block_bytes_);
    }
    template <int G = 0>
    const char* set_block(uint64_t set) const {
        return set_blocks_ + set * (G ? 64 * uint64_t(G) : block_bytes_);
    }
    template <int G = 0>
    uint32_t* tags(uint64_t set) {
        return reinterpret_cast<uint32_t*>(set_block<G>(set));
    }
    template <int G = 0>
    const uint32_t* tags(uint64_t set) const {
        return reinterpret_cast<const uint32_t*>(set_block<G>(set));
    }
    template <int G = 0>
    uint32_t* stamps(uint64_t set) {
        return tags<G>(set) + ways_of<G>();
    }
    template <int G = 0>
    Cycle* fill_ready(uint64_t set) {
        return reinterpret_cast<Cycle*>(set_block<G>(set) + 8 * uint64_t(ways_of<G>()));
    }
    // The way holding `line_addr` in its set, or -1. Compares every way without an early exit:
    // a data-dependent exit mispredicts on most lookups, the extra compares cost less.
    template <int G>
    [[gnu::always_inline]] int find_way(uint64_t set, uint64_t line_addr) const {
        const uint32_t* t = tags<G>(set);
        const uint32_t tag = tag_of(line_addr);
#ifdef __SSE2__
        // Four tags per compare; a tag is in at most one way.
        if constexpr (G > 0) {
            return find_in_groups<G>(t, tag);
        } else if (tag_groups_ > 0) {
            for (int g = 0; g < tag_groups_; ++g) {
                const int found = find_in_groups<1>(t + 4 * g, tag);
                if (found >= 0) return 4 * g + found;
            }
            return -1;
        }
#endif
        int found = -1;
        for (int w = 0; w < ways_of<G>(); ++w) found = t[w] == tag ? w : found;
        return found;
    }
#ifdef __SSE2__
    // The way among the first 4 * kGroups tags of `t` equal to `tag`, or -1.
    template <int kGroups>
    [[gnu::always_inline]] static int find_in_groups(const uint32_t* t, uint32_t tag) {
        const __m128i key = _mm_set1_epi32(int(tag));
        uint32_t hits = 0;
        for (int g = 0; g < kGroups; ++g) {
            const __m128i four = _mm_load_si128(reinterpret_cast<const __m128i*>(t + 4 * g));
            hits |= uint32_t(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(four, key))))
                    << (4 * g);
        }
        return hits ? __builtin_ctz(hits) : -1;
    }
#endif
    // The cycle the earliest-free MSHR frees; replace_earliest_mshr then books it until `ready`
    // (with nothing else touching this cache's MSHRs in between).
    Cycle earliest_mshr() {
        if (!few_mshrs_) return mshr_free_[mshr_front_];
        const uint64_t least = least_of(mshr_keys_.data(), kFewMshrs);
        mshr_pick_ = size_t(least & (kFewMshrs - 1));
        return least >> kMshrBits;
    }
    void replace_earliest_mshr(Cycle ready);
    // Counts the lookups of lines first..last and waits for their banks, each of which reads
    // its lines of the request back to back; done[k]: the cycle line first + k is looked up.
    void look_up(uint64_t first, uint64_t last, Cycle now, Cycle* done);
    // look_up for `lines` lines from `first` that one bank reads (one bank, or one line):
    // returns the cycle the first is looked up; line k is looked up k cycles later. (Forced
    // inline: on the L1 hit path gcc otherwise calls it, which cost 1.5% of a replay.)
    [[gnu::always_inline]] Cycle look_up_in_one_bank(uint64_t first, uint64_t lines, Cycle now) {
        accesses += lines;
        const Cycle start = banks_[first & bank_mask_].reserve(now, lines);
        bank_conflict_cycles += lines * (start - now) + lines * (lines - 1) / 2;
        return start + params_.hit_latency_cycles;
    }
    bool one_bank_reads(uint64_t lines) const {
        return banks_.size() == 1 || lines == 1;
    }
    // A hit's bookkeeping; returns the cycle the line's data is (or will be) there.
    template <int G, typename P>
    Cycle hit(uint64_t set, int way, Cycle lookup_done) {
        ++hits;
        if (!prefetched_.empty()) note_prefetch_hit(set, way);
        P::template hit<G>(stamps<G>(set), way, repl_);
        const Cycle ready = fill_ready<G>(set)[way];
        merged_misses += ready > lookup_done;  // no branch: which lines are still filling is random
        return ready;
    }
    // A hit's cycles in `bd`: looking it up at this level until `lookup_done`, then waiting
    // for the fill of `line` until `done` (charge_wait).
    void charge_hit(AccessBreakdown* bd, Cycle now, Cycle lookup_done, Cycle done,
                    uint64_t line) const {
        bd->cycles[level_] += lookup_done - now;
        if (done > lookup_done) charge_wait(bd, line, lookup_done, done);
    }
    // A hit waiting from `from` to `until` on the fill of `line` still in flight: charges
    // each cycle to the level the fill was at then (its MSHR wait, the L2, DRAM, the crossbar,
    // in that order; an L1 below a treelet cache first), from the fill's recorded breakdown;
    // otherwise, or when the fill is no longer remembered, the wait is the next level's.
    void charge_wait(AccessBreakdown* bd, uint64_t line, Cycle from, Cycle until) const;
    // Recent fills: when each left for the next level and how long it spent at each
    // level below (the difference of the requester's breakdown across the fill).
    struct InFlightFill {
        uint64_t line = ~uint64_t(0);
        Cycle issue_at = 0, l1_end = 0, l2_end = 0, dram_end = 0, ready = 0;
    };
    // Direct-mapped by line: a fill overwritten by a newer one of the same slot falls back to
    // charging the next level. Sized for the fills the MSHRs allow in flight (a treelet load or
    // a cache with unlimited MSHRs has more: 1024 slots).
    std::vector<InFlightFill> in_flight_;
    uint64_t in_flight_mask_ = 0;
    void remember_fill(uint64_t line, Cycle issue_at, const AccessBreakdown& before,
                       const AccessBreakdown& after, Cycle ready) {
        InFlightFill& f = in_flight_[line & in_flight_mask_];
        f.line = line;
        f.issue_at = issue_at;
        f.l1_end = issue_at + (after.cycles[kLevelL1] - before.cycles[kLevelL1]);
        f.l2_end = f.l1_end + (after.cycles[kLevelL2] - before.cycles[kLevelL2]);
        f.dram_end = f.l2_end + (after.cycles[kLevelDram] - before.cycles[kLevelDram]);
        f.ready = ready;  // the crossbar's part ends it
    }
    // The slowest line of a request and where its cycles went. Hits keep two scalars, not a
    // breakdown copied per line (copying small structs per line stalled store forwarding).
    struct Slowest {
        Cycle done = 0;
        bool any = false, is_hit = true;
        Cycle hit_lookup_done = 0;
        uint64_t hit_line = 0;
        AccessBreakdown miss_bd;
        void hit(Cycle lookup_done, Cycle ready, uint64_t line);
        void miss(Cycle done, const AccessBreakdown& line_bd);
        void charge(const Cache& cache, AccessBreakdown* bd, Cycle now) const;
    };
    template <int G, typename P>
    Cycle access_line(uint64_t line_addr, Cycle now, Cycle lookup_done, Slowest& slowest,
                      bool breakdown);
    // A miss: picks a victim, waits for an MSHR, fetches the line from the next level (adding
    // its cycles to `bd`); returns the cycle the line is there.
    template <int G, typename P>
    Cycle fill(uint64_t set, uint64_t line_addr, Cycle now, Cycle lookup_done, AccessBreakdown* bd);
    // access() and access_local() for the set layout G (see ways_of) and the policy P.
    template <int G, typename P>
    [[gnu::always_inline]] Cycle access_in(uint64_t addr, uint32_t size_bytes, Cycle now,
                                           AccessBreakdown* bd);
    template <int G, typename P>
    [[gnu::always_inline]] bool access_local_in(uint64_t addr, uint32_t size_bytes, Cycle now,
                                                Cycle& ready, AccessBreakdown* bd);

    void b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
        serve_loosely_timed(*this, gp, delay);
    }
    CacheParams params_;
    int level_;
    Cache* same_level_next_ = nullptr;  // the next level when it is a cache of this level
    // MSHRs as the cycles they free. Up to kFewMshrs (an L1's): keys (cycle << kMshrBits | MSHR) in
    // any order, padded to kFewMshrs with ~0, the earliest found by branch-free minimums (a
    // miss served by the L2 often frees before misses still waiting for DRAM, so keeping them
    // sorted shifts an unpredictable number of entries). More: a ring in order.
    static constexpr int kMshrBits = 4;
    static constexpr size_t kFewMshrs = size_t(1) << kMshrBits;
    bool few_mshrs_ = false;
    std::vector<uint64_t> mshr_keys_;
    size_t mshr_pick_ = 0;                    // few: the MSHR earliest_mshr found
    std::vector<Cycle> mshr_free_;            // many: per MSHR the cycle it frees; a ring, in order
    size_t mshr_front_ = 0;                   // the ring's earliest
    std::vector<ReservationCalendar> banks_;  // per bank: the cycles it starts a lookup
    TimeSeries* fill_series_ = nullptr;
    std::vector<uint64_t> set_storage_;  // the sets' blocks (a tag of kNoTag: an invalid way)
    char* set_blocks_ = nullptr;         // set_storage_ aligned to a host cache line
    uint64_t block_bytes_ = 0;
    int tag_groups_ = 0;      // ways / 4 for tag compares four at a time; 0: one at a time
    int layout_ = 0;          // the G the hot paths run with: tag_groups_ if 1, 2 or 4, else 0
    uint32_t set_shift_ = 0;  // log2 of the set count: a tag is the line address above it
    uint64_t bank_mask_ = 0;
    uint32_t bank_shift_ = 0;  // log2 of the bank count
    uint64_t set_mask_;
    uint32_t line_shift_;
    ReplacementState repl_;  // the policy's state shared by the sets (stamp clock, random state)
    Cycle latest_lookup_ = 0, latest_mshr_request_ = 0;  // for the out-of-order counts
    void note_lookup(Cycle now) {
        lookup_out_of_order += now < latest_lookup_;
        latest_lookup_ = std::max(latest_lookup_, now);
    }
    // The hot paths compiled for this cache's set layout and policy (use_policy).
    // Plain function pointers to entry points with the whole path inlined (a member pointer adds
    // a virtual-bit test and keeps the body a separate call).
    Cycle (*access_fn_)(Cache&, uint64_t, uint32_t, Cycle, AccessBreakdown*) = nullptr;
    bool (*local_fn_)(Cache&, uint64_t, uint32_t, Cycle, Cycle&, AccessBreakdown*) = nullptr;
    template <int G, typename P>
    static Cycle access_entry(Cache& c, uint64_t addr, uint32_t size_bytes, Cycle now,
                              AccessBreakdown* bd) {
        return c.access_in<G, P>(addr, size_bytes, now, bd);
    }
    bool (*tag_fn_)(Cache&, uint64_t, Cycle) = nullptr;
    bool (*warm_fn_)(Cache&, uint64_t, Cycle) = nullptr;  // tag_entry without counting
    template <int G, typename P, bool kCount = true>
    static bool tag_entry(Cache& c, uint64_t line, Cycle at);
    template <int G, typename P>
    static bool local_entry(Cache& c, uint64_t addr, uint32_t size_bytes, Cycle now, Cycle& ready,
                            AccessBreakdown* bd) {
        return c.access_local_in<G, P>(addr, size_bytes, now, ready, bd);
    }
    std::vector<Cycle> lookup_done_;  // scratch for requests of many lines

    // Dirty bits per set and way, allocated at the first write (a read-only cache has none).
    std::vector<uint8_t> dirty_;
    std::vector<uint64_t> queued_writebacks_;
    // What to do with a dirty victim: write it to the next level now (the fast model), queue it
    // for the reference, or warm the next level with it.
    enum WritebackMode { kSendWriteBack, kQueueWriteBack, kWarmWriteBack };
    // (The test inline: most caches never see a write.)
    [[gnu::always_inline]] void evict(uint64_t set, int way, uint64_t victim_tag, Cycle at,
                                      WritebackMode mode) {
        if (!dirty_.empty()) evict_dirty(set, way, victim_tag, at, mode);
    }
    void evict_dirty(uint64_t set, int way, uint64_t victim_tag, Cycle at, WritebackMode mode) {
        uint8_t& d = dirty_[way_index(set, way)];
        if (!d || victim_tag == kNoTag) return;
        d = 0;
        const uint64_t line = uint64_t(victim_tag) << set_shift_ | set;
        if (mode == kWarmWriteBack) {
            below_.warm(line << line_shift_, params_.line_bytes, true);
            return;
        }
        ++writebacks;
        writeback_bytes += params_.line_bytes;
        if (mode == kQueueWriteBack)
            queued_writebacks_.push_back(line);
        else
            below_.write(line << line_shift_, params_.line_bytes, at);
    }
    // A write-back write of `line` looked up at `at` (hit: dirty; miss: allocated dirty).
    void (*write_fn_)(Cache&, uint64_t, Cycle, WritebackMode) = nullptr;
    template <int G, typename P>
    static void write_entry(Cache& c, uint64_t line, Cycle at, WritebackMode mode);
    // Loosely timed calls to the next level. Last: its payload would spread the fields above
    // over more of the host's cache lines.
    LtPort below_{down};
};

}  // namespace rtsim

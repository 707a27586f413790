// Resources reserved out of time order. Requests come in the order the simulator meets them, not
// the order they become ready: a step whose fetch missed to DRAM books its unit hundreds of
// cycles ahead, and the next step, an L1 hit, must still find the unit free in between. A single
// "next free cycle" would queue it behind the DRAM miss (a box unit 7% busy showed 22 cycles of
// queueing per operation that way; half the crossbar's requests came up to ~23 cycles late).
//
// Both calendars keep per-cycle use in a ring over the cycles still in play: from the floor
// they follow (the earliest cycle a request may still be ready at, which the cores raise as
// they go) to the latest cycle booked. The ring grows as needed and stays a few hundred cycles
// long, so it lives in the host's caches.
#pragma once

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

#include "models/timing.h"

namespace rtsim {

// The earliest cycle at which a request may still reach the blocks that follow it. A core keeps
// one for its private blocks (its own earliest ray slot); the core scheduler keeps one for the
// shared blocks (the earliest over all cores).
struct TimeFloor {
    Cycle cycle = 0;
};

namespace detail {
// A counter per cycle of [base, end); later cycles are empty, earlier ones forgotten.
template <typename Count>
class CycleRing {
  public:
    CycleRing();
    Count& at(Cycle c) { return counts_[c & mask_]; }
    Cycle base() const { return base_; }
    Cycle end() const { return end_; }
    void forget_before(Cycle floor) {
        if (floor <= base_) return;
        base_ = floor;
        if (end_ < base_) end_ = base_;
    }
    // Makes the cycles up to `end` (exclusive) part of the ring, empty.
    void extend(Cycle end) {
        if (end <= end_) return;
        if (end - base_ > counts_.size()) grow(end - base_);
        zero(end_, end);
        end_ = end;
    }
    // Empties cycles [from, to), which hold no live cycle's count (at most the ring's size).
    void zero(Cycle from, Cycle to) {
        if (from >= to) return;
        const Cycle a = from & mask_, n = to - from;
        const Cycle first = std::min<Cycle>(n, counts_.size() - a);  // up to the ring's end
        std::fill_n(counts_.begin() + Cycle(a), first, Count(0));
        std::fill_n(counts_.begin(), n - first, Count(0));
    }
    size_t size() const { return counts_.size(); }
    // For a caller that wrote the cycles from end() to `end` itself (they fit the ring).
    void set_end(Cycle end) { end_ = end; }

  private:
    void grow(Cycle cycles);
    std::vector<Count> counts_;
    Cycle mask_;
    Cycle base_ = 0, end_ = 0;
};
}  // namespace detail

// Requests served before the floor they follow, as if ready at it: a broken promise of the
// caller, counted over all calendars so runs can check it never happens (stats: sim.late_requests).
extern uint64_t g_calendar_late_requests;

// `capacity` users per cycle (the pipelines of a unit, a cache's bank); a reservation holds one
// user for `span` consecutive cycles. Whether overlapping reservations fit on `capacity`
// pipelines depends only on how many overlap at each cycle (interval graphs colour with as
// many colours as their largest overlap), so per-cycle counts are exact.
class ReservationCalendar {
  public:
    explicit ReservationCalendar(int capacity = 1)
        : capacity_(uint32_t(capacity > 0 ? capacity : 1)) {}
    // Forget the cycles before `floor->cycle` as it rises (nullptr: remember everything).
    void follow(const TimeFloor* floor) { floor_ = floor; }
    // Reserves one user for [start, start + span) with the earliest start >= ready at which
    // every cycle of the span has a free user; returns start. span >= 1.
    Cycle reserve(Cycle ready, Cycle span);
    size_t ring_cycles() const { return ring_.size(); }

  private:
    uint32_t capacity_;
    const TimeFloor* floor_ = nullptr;
    detail::CycleRing<uint16_t> ring_;
    Cycle full_until_ = 0;  // every cycle of [base, full_until_) is full: searches start here
};

// A link moving `bytes_per_cycle` (fractional allowed) as a fluid: a transfer takes what is left
// of each cycle from its start on until its bytes have moved, so the bandwidth cap holds exactly
// however requests interleave, and a transfer ready early slips into gaps left by later ones.
class BandwidthCalendar {
  public:
    explicit BandwidthCalendar(double bytes_per_cycle);
    void follow(const TimeFloor* floor) { floor_ = floor; }
    // Moves `bytes` from `ready` on; returns the cycle the first byte moves and the cycle after
    // the last one did.
    std::pair<Cycle, Cycle> transfer(Cycle ready, uint64_t bytes);

  private:
    // Fixed point in 1/10000 byte: rates given to four decimals (12.8 bytes per cycle) are exact.
    static constexpr uint64_t kUnitsPerByte = 10000;
    uint32_t capacity_units_;
    const TimeFloor* floor_ = nullptr;
    detail::CycleRing<uint32_t> ring_;
    Cycle full_until_ = 0;
};

}  // namespace rtsim

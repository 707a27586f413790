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
// A count per cycle of [base, end); all other cycles count zero. A cell holds its cycle beside
// the count, so a cell left from an earlier lap reads as zero: nothing is ever cleared, and a
// block that books nothing costs nothing however much time passes.
template <int kCountBits>
class CycleRing {
  public:
    static constexpr uint64_t kMaxCount = (uint64_t(1) << kCountBits) - 1;
    CycleRing();
    uint64_t count(Cycle c) const {
        const uint64_t cell = cells_[c & mask_];
        return (cell >> kCountBits) == c ? cell & kMaxCount : 0;
    }
    void set(Cycle c, uint64_t n) { cells_[c & mask_] = (c << kCountBits) | n; }
    Cycle base() const { return base_; }
    Cycle end() const { return end_; }
    size_t size() const { return cells_.size(); }
    // Without branches: whether the floor moved since the last request is unpredictable.
    void forget_before(Cycle floor) {
        base_ = std::max(base_, floor);
        end_ = std::max(end_, base_);
    }
    // Cycles up to `end` (exclusive) may be booked: grows the ring if they don't fit.
    void extend(Cycle end) {
        if (end <= end_) return;
        if (end - base_ > cells_.size()) grow(end - base_);
        end_ = end;
    }

  private:
    void grow(Cycle cycles);
    std::vector<uint64_t> cells_;  // cycle << kCountBits | count
    Cycle mask_;
    Cycle base_ = 0, end_ = 0;
};

constexpr int kBandwidthCountBits = 27;
extern const TimeFloor g_no_floor;  // a floor that never rises: remember everything
}  // namespace detail

// Calendars count cycles below this (2^37: 137 s of simulated time at 1 GHz); a run that goes
// past it is refused.
constexpr Cycle kCalendarCycleLimit = Cycle(1) << (64 - detail::kBandwidthCountBits);

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
    void follow(const TimeFloor* floor) { floor_ = floor ? floor : &detail::g_no_floor; }
    // The requests will come in non-decreasing `ready` order (a private L1's bank behind its
    // core's in-order issue port). With one user each then starts at its ready or at the end
    // of the bookings before it, so only that end is kept, no per-cycle counts. A request out
    // of order would break the promise: it is counted with the late ones (sim.late_requests,
    // which runs check stays zero) and starts at the end.
    void assume_in_order() { in_order_ = capacity_ == 1; }
    // Reserves one user for [start, start + span) with the earliest start >= ready at which
    // every cycle of the span has a free user; returns start. span >= 1.
    // (Inlined: a unit reserves on every step, and the core's step loop had it inline until that
    // loop grew past the compiler's own limit.)
    [[gnu::always_inline]] Cycle reserve(Cycle ready, Cycle span) {
        if (in_order_) {
            g_calendar_late_requests += ready < latest_ready_;
            latest_ready_ = ready;
            const Cycle start = std::max(ready, in_order_end_);
            in_order_end_ = start + span;
            return start;
        }
        ring_.forget_before(floor_->cycle);
        if (ready < ring_.base()) {
            ++g_calendar_late_requests;
            ready = ring_.base();
        }
        // One user, and no request so far was ready later than this one: every cycle from the
        // latest ready to the end is booked (each in-order booking starts at its ready or at the
        // end; an out-of-order one fills a gap or starts at the end), so the reservation starts
        // at the end, or at its ready if that is later. (The latest ready is never past the end,
        // so with one user a request ready before it is the only kind that must search; one
        // branch decides.)
        if (ready < (capacity_ == 1 ? latest_ready_ : ring_.end())) {
            // Out of order: most often the cycle asked for is still free (a unit a few percent
            // busy); only then is a search needed.
            if (span == 1) {
                const uint64_t used = ring_.count(ready);
                if (used < capacity_) {
                    ring_.set(ready, used + 1);
                    return ready;
                }
            }
            return reserve_among_bookings(ready, span);
        }
        const Cycle start = std::max(ready, ring_.end());
        latest_ready_ = ready;
        // Nothing booked from `start` on: no search.
        ring_.extend(start + span);
        for (Cycle c = start; c < start + span; ++c) ring_.set(c, 1);
        return start;
    }
    size_t ring_cycles() const { return ring_.size(); }

  private:
    Cycle reserve_among_bookings(Cycle ready, Cycle span);
    uint32_t capacity_;
    const TimeFloor* floor_ = &detail::g_no_floor;
    detail::CycleRing<16> ring_;  // cycles below 2^48
    Cycle latest_ready_ = 0;      // the latest `ready` asked for so far
    bool in_order_ = false;       // see assume_in_order
    Cycle in_order_end_ = 0;      // in order: the end of the bookings
};

// A link moving `bytes_per_cycle` (fractional allowed) as a fluid: a transfer takes what is left
// of each cycle from its start on until its bytes have moved, so the bandwidth cap holds exactly
// however requests interleave, and a transfer ready early slips into gaps left by later ones.
class BandwidthCalendar {
  public:
    explicit BandwidthCalendar(double bytes_per_cycle);
    void follow(const TimeFloor* floor) { floor_ = floor ? floor : &detail::g_no_floor; }
    // Cycles `bytes` take on an idle link (the link's busy time per transfer, in its own fixed
    // point, so it agrees with the cycles transfers book).
    Cycle idle_cycles(uint64_t bytes) const {
        split(std::max<uint64_t>(bytes, 1) * kUnitsPerByte);
        return split_.whole + (split_.rest > 0);
    }
    // Moves `bytes` from `ready` on; returns the cycle the first byte moves and the cycle after
    // the last one did.
    std::pair<Cycle, Cycle> transfer(Cycle ready, uint64_t bytes) {
        ring_.forget_before(floor_->cycle);
        if (ready < ring_.base()) {
            ++g_calendar_late_requests;
            ready = ring_.base();
        }
        const uint64_t units = std::max<uint64_t>(bytes, 1) * kUnitsPerByte;
        if (ready < ring_.end()) return transfer_among_bookings(ready, units);
        // An idle link from `ready` on: whole cycles, then the rest.
        split(units);
        const Cycle whole = split_.whole;
        const uint32_t rest = split_.rest;
        const Cycle end = ready + whole + (rest > 0);
        ring_.extend(end);
        for (Cycle c = ready; c < ready + whole; ++c) ring_.set(c, capacity_units_);
        if (rest) ring_.set(end - 1, rest);
        return {ready, end};
    }

  private:
    std::pair<Cycle, Cycle> transfer_among_bookings(Cycle ready, uint64_t units);
    // `units` on an idle link: whole cycles, then the rest, in split_. A link moves one size (a
    // line, a burst) again and again: the division is done once per size, not per transfer.
    void split(uint64_t units) const {
        if (units == split_.units) return;
        split_ = {units, units / capacity_units_, uint32_t(units % capacity_units_)};
    }
    struct Split {
        uint64_t units = 0;
        Cycle whole = 0;
        uint32_t rest = 0;
    };
    mutable Split split_;
    // Fixed point in 1/1000 byte: rates given to three decimals (12.8 bytes per cycle) are exact,
    // and up to 134 kB per cycle fit a cell's count.
    static constexpr uint64_t kUnitsPerByte = 1000;
    uint32_t capacity_units_;
    const TimeFloor* floor_ = &detail::g_no_floor;
    detail::CycleRing<detail::kBandwidthCountBits> ring_;
    Cycle full_until_ = 0;  // every cycle of [base, full_until_) is full: searches start here
};

}  // namespace rtsim

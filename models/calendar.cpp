#include "models/calendar.h"

#include <algorithm>
#include <cmath>

namespace rtsim {

uint64_t g_calendar_late_requests = 0;

namespace detail {
const TimeFloor g_no_floor{};

template <int kCountBits>
CycleRing<kCountBits>::CycleRing() : cells_(256, 0), mask_(255) {}

template <int kCountBits>
void CycleRing<kCountBits>::grow(Cycle cycles) {
    size_t size = cells_.size();
    while (size < cycles) size *= 2;  // a power of two: the ring index is a mask
    std::vector<uint64_t> grown(size, 0);
    for (Cycle c = base_; c < end_; ++c) grown[c & (size - 1)] = cells_[c & mask_];
    cells_.swap(grown);
    mask_ = size - 1;
}

template class CycleRing<16>;
template class CycleRing<kBandwidthCountBits>;
}  // namespace detail

Cycle ReservationCalendar::reserve_among_bookings(Cycle ready, Cycle span) {
    if (span == 1) {  // a cache bank's lookup: the first cycle with a free user
        Cycle c = ready;
        uint64_t used = ring_.count(c);
        while (used >= capacity_ && ++c < ring_.end()) used = ring_.count(c);
        if (c == ring_.end()) {
            ring_.extend(c + 1);
            used = 0;
        }
        ring_.set(c, used + 1);
        return c;
    }
    // Slide past any full cycle inside the candidate span; cycles from the end on are empty.
    Cycle start = ready;
    for (Cycle c = start; c < start + span && c < ring_.end(); ++c)
        if (ring_.count(c) >= capacity_) start = c + 1;
    ring_.extend(start + span);
    for (Cycle c = start; c < start + span; ++c) ring_.set(c, ring_.count(c) + 1);
    return start;
}

BandwidthCalendar::BandwidthCalendar(double bytes_per_cycle)
    : capacity_units_(uint32_t(std::clamp(std::round(bytes_per_cycle * double(kUnitsPerByte)), 1.0,
                                          double(decltype(ring_)::kMaxCount)))) {}

std::pair<Cycle, Cycle> BandwidthCalendar::transfer_among_bookings(Cycle ready, uint64_t left) {
    // Full cycles at the front stay full until the floor passes them: start searching after.
    if (full_until_ < ring_.base()) full_until_ = ring_.base();
    const Cycle from = std::max(ready, full_until_);
    // Cycles with room hold at least some; skip the full ones (never past the end: it is empty).
    Cycle c = from;
    uint64_t used = 0;
    while (c < ring_.end() && (used = ring_.count(c)) >= capacity_units_) ++c;
    if (c >= ring_.end()) used = 0;
    if (from == full_until_) full_until_ = c;  // everything skipped is full
    const Cycle first = c;
    if (used == 0 && left == capacity_units_) {  // one whole cycle (a line on a line-wide link)
        if (c >= ring_.end()) ring_.extend(c + 1);
        ring_.set(c++, left);
    } else {
        // Enough cycles if the link were idle from here; more are added if it is not.
        split(left);
        ring_.extend(c + split_.whole + (split_.rest > 0));
        for (;;) {
            const uint64_t take = std::min<uint64_t>(left, capacity_units_ - used);
            ring_.set(c, used + take);
            left -= take;
            ++c;
            if (left == 0) break;
            if (c >= ring_.end()) ring_.extend(c + 1);
            used = ring_.count(c);
        }
    }
    while (full_until_ < ring_.end() && ring_.count(full_until_) >= capacity_units_) ++full_until_;
    return {first, c};
}

}  // namespace rtsim

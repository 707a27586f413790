#include "models/calendar.h"

#include <algorithm>
#include <cmath>

namespace rtsim {

uint64_t g_calendar_late_requests = 0;

namespace detail {
template <typename Count>
CycleRing<Count>::CycleRing() : counts_(256, 0), mask_(255) {}

template <typename Count>
void CycleRing<Count>::grow(Cycle cycles) {
    size_t size = counts_.size();
    while (size < cycles) size *= 2;  // a power of two: the ring index is a mask
    std::vector<Count> grown(size, 0);
    for (Cycle c = base_; c < end_; ++c) grown[c & (size - 1)] = at(c);
    counts_.swap(grown);
    mask_ = size - 1;
}

template class CycleRing<uint16_t>;
template class CycleRing<uint32_t>;
}  // namespace detail

namespace {
// Forgets what the floor left behind; a request still older is served at the floor.
template <typename Ring>
Cycle settle(Ring& ring, const TimeFloor* floor, Cycle& full_until, Cycle ready) {
    if (floor) ring.forget_before(floor->cycle);
    if (full_until < ring.base()) full_until = ring.base();
    g_calendar_late_requests += ready < ring.base();
    return std::max(ready, full_until);
}
}  // namespace

Cycle ReservationCalendar::reserve(Cycle ready, Cycle span) {
    Cycle start = settle(ring_, floor_, full_until_, ready);
    if (start >= ring_.end() && start + span - ring_.base() <= ring_.size()) {
        // Nothing booked from here on (requests mostly come in order): no search.
        ring_.zero(ring_.end(), start);
        for (Cycle c = start; c < start + span; ++c) ring_.at(c) = 1;
        ring_.set_end(start + span);
        if (full_until_ == start && capacity_ == 1) full_until_ = start + span;
        return start;
    }
    // Slide past any full cycle inside the candidate span; cycles from the end on are empty.
    for (Cycle c = start; c < start + span && c < ring_.end(); ++c)
        if (ring_.at(c) >= capacity_) start = c + 1;
    ring_.extend(start + span);
    for (Cycle c = start; c < start + span; ++c) ++ring_.at(c);
    while (full_until_ < ring_.end() && ring_.at(full_until_) >= capacity_) ++full_until_;
    return start;
}

BandwidthCalendar::BandwidthCalendar(double bytes_per_cycle)
    : capacity_units_(
          uint32_t(std::max(1.0, std::round(bytes_per_cycle * double(kUnitsPerByte))))) {}

std::pair<Cycle, Cycle> BandwidthCalendar::transfer(Cycle ready, uint64_t bytes) {
    Cycle c = settle(ring_, floor_, full_until_, ready);
    uint64_t left = std::max<uint64_t>(bytes, 1) * kUnitsPerByte;
    // Cycles with room hold at least some; skip the full ones (never past the end: it is empty).
    while (c < ring_.end() && ring_.at(c) >= capacity_units_) ++c;
    const Cycle first = c;
    // Enough cycles if the link were idle from here; more are added if it is not.
    ring_.extend(c + (left + capacity_units_ - 1) / capacity_units_);
    while (left > 0) {
        if (c >= ring_.end()) ring_.extend(c + 1);
        uint32_t& used = ring_.at(c);
        const uint64_t take = std::min<uint64_t>(left, capacity_units_ - used);
        used += uint32_t(take);
        left -= take;
        ++c;
    }
    while (full_until_ < ring_.end() && ring_.at(full_until_) >= capacity_units_) ++full_until_;
    return {first, c};
}

}  // namespace rtsim

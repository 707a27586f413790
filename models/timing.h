// Time in the timing models is counted in cycles of the chip clock. SystemC time carries the same
// count at 1 ns per cycle; the configured clock only matters when converting to seconds.
#pragma once

#include <algorithm>
#include <cstdint>
#include <systemc>

namespace rtsim {

using Cycle = uint64_t;

inline sc_core::sc_time cycles_to_time(Cycle c) {
    return sc_core::sc_time(static_cast<double>(c), sc_core::SC_NS);
}
inline Cycle now_cycles() {
    return static_cast<Cycle>(sc_core::sc_time_stamp().to_seconds() * 1e9 + 0.5);
}

// The least of eight values, pairwise: three minimums deep instead of seven, and compiled to
// conditional moves (which of several is least changes unpredictably; a branch on it
// mispredicts half the time).
template <typename T>
[[gnu::always_inline]] inline T least_of_8(const T* v) {
    const T a = std::min(v[0], v[1]), b = std::min(v[2], v[3]);
    const T c = std::min(v[4], v[5]), d = std::min(v[6], v[7]);
    return std::min(std::min(a, b), std::min(c, d));
}
// The least of `n` values, n a multiple of eight (arrays padded with values that never win).
template <typename T>
[[gnu::always_inline]] inline T least_of(const T* v, size_t n) {
    T least = least_of_8(v);
    for (size_t j = 8; j < n; j += 8) least = std::min(least, least_of_8(v + j));
    return least;
}
// `n` rounded up to a multiple of eight: the size of an array least_of scans.
constexpr size_t padded_to_8(size_t n) {
    return (n + 7) / 8 * 8;
}

// A resource that starts at most `per_cycle` operations each cycle, first come first served: a
// core's issue port, an SRAM's ports. Requests arrive in non-decreasing `ready` order.
struct PortCalendar {
    int per_cycle = 1;
    Cycle cycle = 0;  // the latest cycle with an operation started
    int used = 0;     // operations started in it
    // Requests that came with a ready cycle before an earlier request's: served out of time
    // order (the port keeps no calendar), counted so that stats show where it happens.
    Cycle latest_ready = 0;
    uint64_t out_of_order = 0;
    // Starts one operation ready at `ready`; returns the cycle it starts.
    Cycle take(Cycle ready) {
        out_of_order += ready < latest_ready;
        latest_ready = std::max(latest_ready, ready);
        if (ready > cycle) {
            cycle = ready;
            used = 0;
        }
        if (used == per_cycle) {
            ++cycle;
            used = 0;
        }
        ++used;
        return cycle;
    }
};

// Where an access spent its cycles, by the memory level that spent them (stall attribution);
// the crossbar between the L1s and the L2 is a level of its own (its queueing and crossing).
enum MemLevel : int {
    kLevelL1 = 0,
    kLevelL2 = 1,
    kLevelDram = 2,
    kLevelCrossbar = 3,
    kMemLevels = 4
};
struct AccessBreakdown {
    Cycle cycles[kMemLevels] = {0, 0, 0, 0};
};

// A memory block's loosely timed behaviour (sim.fidelity = fast): an access that returns the
// cycle the data is available. Requesters reach it through the block's target socket with
// b_transport (LtPort and serve_loosely_timed, models/transaction.h), never by a pointer to the
// block. Requests may come out of time order, but never before the time floor the level follows
// (models/calendar.h).
class MemoryPort {
  public:
    virtual ~MemoryPort() = default;
    // `breakdown` (optional) receives the cycles each level spent on this access; they add up to
    // the returned cycle minus `now`.
    virtual Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                         AccessBreakdown* breakdown = nullptr) = 0;
    // Performs the access only if this block serves it entirely, touching no other block's
    // state (a private cache's hit): then sets `ready` as access() would return it and returns
    // true. Otherwise changes nothing and returns false. A requester may run a local access
    // ahead of simulated time; anything else may reach shared state and must wait for its turn.
    virtual bool access_local(uint64_t /*addr*/, uint32_t /*size_bytes*/, Cycle /*now*/,
                              Cycle& /*ready*/, AccessBreakdown* /*breakdown*/ = nullptr) {
        return false;
    }
    // Functional warming (sampled simulation): leaves the state an access would
    // (tags and replacement order of every level it reaches), taking no time, reserving nothing
    // and counting nothing. A level with no such state ignores it.
    virtual void warm(uint64_t /*addr*/, uint32_t /*size_bytes*/) {}
    // A posted write (a stack spill, a hit record, a dirty line written back): returns the cycle
    // this level has accepted it; the writer does not wait for anything below. A level with no
    // write path (a read-only L1) must never be given one.
    virtual Cycle write(uint64_t /*addr*/, uint32_t /*size_bytes*/, Cycle now) { return now; }
    // Functional warming of a write: the state it would leave (a write-back cache's line and
    // its dirty bit), taking no time and counting nothing.
    virtual void warm_write(uint64_t /*addr*/, uint32_t /*size_bytes*/) {}
};

}  // namespace rtsim

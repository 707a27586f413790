#include <gtest/gtest.h>

#include <map>
#include <random>

#include "models/calendar.h"

using namespace rtsim;

TEST(ReservationCalendar, EarlyRequestsFillGapsLeftByLaterOnes) {
    ReservationCalendar c(1);
    EXPECT_EQ(c.reserve(100, 1), 100u);  // a DRAM miss books far ahead...
    EXPECT_EQ(c.reserve(10, 1), 10u);    // ...and an L1 hit still goes first
    EXPECT_EQ(c.reserve(100, 1), 101u);
    EXPECT_EQ(c.reserve(8, 3), 11u);  // cycles 8, 9 are free but 10 is not: the span moves on
    EXPECT_EQ(c.reserve(8, 2), 8u);
}

TEST(ReservationCalendar, CapacityIsUsersPerCycle) {
    ReservationCalendar c(2);
    EXPECT_EQ(c.reserve(0, 1), 0u);
    EXPECT_EQ(c.reserve(0, 1), 0u);
    EXPECT_EQ(c.reserve(0, 1), 1u);
    EXPECT_EQ(c.reserve(0, 4), 1u);  // cycle 1 has one user, 2..4 none
    EXPECT_EQ(c.reserve(1, 1), 2u);
}

// An independent, deliberately simple model: a map of per-cycle counts searched cycle by cycle.
// Requests come up to 300 cycles out of order, or mostly in order (a private L1's bank sees only
// in-order requests, which take a shortcut; a few late ones still fill gaps).
TEST(ReservationCalendar, MatchesASimpleModelOnRandomRequests) {
    for (int capacity : {1, 2, 3})
        for (Cycle spread : {300, 4})
            for (bool follow : {false, true}) {
                std::mt19937 rng(uint32_t(7 + capacity + spread));
                ReservationCalendar c(capacity);
                TimeFloor floor_seen;  // following it, the ring's cells are reused lap after lap
                if (follow) c.follow(&floor_seen);
                std::map<Cycle, int> used;
                Cycle floor = 0;
                for (int i = 0; i < 20000; ++i) {
                    floor +=
                        rng() % 8;  // ~2 cycles booked per 3.5: busy, but the queue stays bounded
                    floor_seen.cycle = floor;
                    const Cycle ready = floor + rng() % spread;
                    const Cycle span = 1 + rng() % 3;
                    Cycle start = ready;
                    for (Cycle k = 0; k < span; ++k)
                        if (used[start + k] >= capacity) {
                            start += k + 1;
                            k = Cycle(-1);
                        }
                    for (Cycle k = 0; k < span; ++k) ++used[start + k];
                    ASSERT_EQ(c.reserve(ready, span), start) << "request " << i;
                }
                if (follow) {
                    EXPECT_LE(c.ring_cycles(), 1024u);
                }
            }
}

// A calendar told its requests come in order (a private L1's bank) keeps only its end: on
// in-order requests it must book exactly as the full calendar does, and a request out of order
// is counted as a broken promise.
TEST(ReservationCalendar, InOrderCalendarBooksAsTheFullOne) {
    std::mt19937 rng(11);
    ReservationCalendar full(1), in_order(1);
    in_order.assume_in_order();
    const uint64_t late_before = g_calendar_late_requests;
    Cycle ready = 0;
    for (int i = 0; i < 20000; ++i) {
        ready += rng() % 4;  // sometimes the same cycle, sometimes a gap
        const Cycle span = 1 + rng() % 4;
        ASSERT_EQ(in_order.reserve(ready, span), full.reserve(ready, span)) << "request " << i;
    }
    EXPECT_EQ(g_calendar_late_requests, late_before);
    const Cycle end = in_order.reserve(ready, 1) + 1;
    EXPECT_EQ(in_order.reserve(ready - 1, 1), end);  // out of order: at the end, and counted
    EXPECT_EQ(g_calendar_late_requests, late_before + 1);
    // A calendar with several users keeps its cells (in-order booking is only exact for one).
    ReservationCalendar two(2), two_full(2);
    two.assume_in_order();
    for (Cycle r : {Cycle(0), Cycle(0), Cycle(0), Cycle(5)})
        EXPECT_EQ(two.reserve(r, 2), two_full.reserve(r, 2));
}

TEST(ReservationCalendar, FollowingAFloorKeepsTheRingSmall) {
    TimeFloor floor;
    ReservationCalendar c(1);
    c.follow(&floor);
    const uint64_t late_before = g_calendar_late_requests;
    for (Cycle t = 0; t < 1000000; t += 2) {
        floor.cycle = t;
        c.reserve(t + (t % 7) * 40, 1);  // up to 240 cycles ahead of the floor
    }
    EXPECT_LE(c.ring_cycles(), 512u);
    EXPECT_EQ(g_calendar_late_requests, late_before);
    // A request behind the floor breaks the promise: served at the floor, and counted.
    floor.cycle = 2000000;
    EXPECT_EQ(c.reserve(floor.cycle - 50, 1), floor.cycle);
    EXPECT_EQ(g_calendar_late_requests, late_before + 1);
}

TEST(ReservationCalendar, WithoutAFloorTheRingGrowsAndForgetsNothing) {
    ReservationCalendar c(1);
    for (Cycle t = 0; t < 5000; ++t) c.reserve(t, 1);
    EXPECT_GE(c.ring_cycles(), 5000u);
    EXPECT_EQ(c.reserve(0, 1), 5000u);  // every cycle before is still booked
}

TEST(BandwidthCalendar, FractionalRatesAreExactOverTime) {
    BandwidthCalendar link(12.8);
    Cycle end = 0;
    for (int i = 0; i < 10; ++i) end = link.transfer(0, 64).second;
    EXPECT_EQ(end, 50u);  // 640 bytes / 12.8 bytes per cycle
}

TEST(BandwidthCalendar, TransfersShareCyclesAsAFluid) {
    BandwidthCalendar link(48.0);
    EXPECT_EQ(link.transfer(0, 64), std::make_pair(Cycle(0), Cycle(2)));  // 48 + 16 bytes
    EXPECT_EQ(link.transfer(0, 64), std::make_pair(Cycle(1), Cycle(3)));  // 32 left in cycle 1
}

TEST(BandwidthCalendar, EarlyTransfersSlipIntoGaps) {
    BandwidthCalendar link(64.0);
    EXPECT_EQ(link.transfer(100, 128), std::make_pair(Cycle(100), Cycle(102)));
    EXPECT_EQ(link.transfer(0, 64), std::make_pair(Cycle(0), Cycle(1)));
    EXPECT_EQ(link.transfer(99, 128), std::make_pair(Cycle(99), Cycle(103)));  // around 100-101
}

// The same check for the fluid link against a map of bytes moved per cycle.
TEST(BandwidthCalendar, MatchesASimpleModelOnRandomRequests) {
    for (double rate : {12.8, 64.0})
        for (Cycle spread : {200, 4}) {
            std::mt19937 rng(uint32_t(11 + spread));
            BandwidthCalendar link(rate);
            TimeFloor floor_seen;
            link.follow(&floor_seen);
            const uint64_t capacity = uint64_t(rate * 1000 + 0.5);  // thousandths of a byte
            std::map<Cycle, uint64_t> used;
            Cycle floor = 0;
            for (int i = 0; i < 20000; ++i) {
                floor += rng() % 16;  // 72 bytes per 7.5 cycles: 75% of 12.8 bytes per cycle
                floor_seen.cycle = floor;
                const Cycle ready = floor + rng() % spread;
                const uint64_t bytes = 16 * (1 + rng() % 8);
                Cycle c = ready;
                while (used[c] == capacity) ++c;
                const Cycle first = c;
                for (uint64_t left = bytes * 1000; left > 0; ++c) {
                    const uint64_t take = std::min(left, capacity - used[c]);
                    used[c] += take;
                    left -= take;
                }
                ASSERT_EQ(link.transfer(ready, bytes), std::make_pair(first, c)) << "request " << i;
            }
        }
}

// A port keeps its latest cycle only: a request ready before an earlier one's is counted.
TEST(PortCalendar, RequestsOutOfTimeOrderAreCounted) {
    PortCalendar port;
    port.per_cycle = 2;
    EXPECT_EQ(port.take(10), 10u);
    EXPECT_EQ(port.take(10), 10u);
    EXPECT_EQ(port.take(10), 11u);  // two per cycle
    EXPECT_EQ(port.out_of_order, 0u);
    port.take(5);
    EXPECT_EQ(port.out_of_order, 1u);
    port.take(12);
    EXPECT_EQ(port.out_of_order, 1u);
}

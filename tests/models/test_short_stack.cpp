#include <gtest/gtest.h>

#include <vector>

#include "models/short_stack.h"

using namespace rtsim;

namespace {
Step at(unsigned depth, bool popped) {
    Step s{};
    s.stack = stack_byte(depth, popped);
    return s;
}
}  // namespace

// A two-entry short stack against a ray's recorded depths, each step worked out by hand.
TEST(ShortStack, SpillsAndRefillsAsWorkedOutByHand) {
    ShortStack st(2);
    // The root: nothing on the stack.
    EXPECT_FALSE(st.before(at(0, false)).any());
    // The root pushed 3 (its nearest hit child is fetched directly): one does not fit and the
    // oldest, memory entry 0, spills.
    StackTraffic t = st.before(at(3, false));
    EXPECT_EQ(t.spill_entries, 1u);
    EXPECT_EQ(t.spill_from, 0u);
    EXPECT_EQ(t.refill_entries, 0u);
    // 2 more pushed: on chip 4, 2 spill as memory entries 1 and 2.
    t = st.before(at(5, false));
    EXPECT_EQ(t.spill_entries, 2u);
    EXPECT_EQ(t.spill_from, 1u);
    EXPECT_EQ(st.on_chip(), 2u);
    EXPECT_EQ(st.spilled(), 3u);
    // Two pops from the short stack: no traffic.
    EXPECT_FALSE(st.before(at(4, true)).any());
    EXPECT_FALSE(st.before(at(3, true)).any());
    EXPECT_EQ(st.on_chip(), 0u);
    // A pop with the short stack empty: the top two memory entries (1 and 2) come back in one
    // read, one of which is popped.
    t = st.before(at(2, true));
    EXPECT_EQ(t.spill_entries, 0u);
    EXPECT_EQ(t.refill_entries, 2u);
    EXPECT_EQ(t.refill_from, 1u);
    EXPECT_EQ(st.on_chip(), 1u);
    EXPECT_EQ(st.spilled(), 1u);
    // Two pops (one culled, one taken): the one on chip, then memory entry 0 read back.
    t = st.before(at(0, true));
    EXPECT_EQ(t.refill_entries, 1u);
    EXPECT_EQ(t.refill_from, 0u);
    EXPECT_EQ(st.on_chip(), 0u);
    EXPECT_EQ(st.spilled(), 0u);
}

// With room for the deepest stack there is never any traffic; a fresh ray starts empty.
TEST(ShortStack, NoTrafficWhenTheStackFitsAndResetEmptiesIt) {
    ShortStack st(8);
    const unsigned depths[] = {0, 3, 7, 8, 6, 5, 2, 0};
    for (unsigned d : depths) EXPECT_FALSE(st.before(at(d, d < 8 && d > 0)).any()) << d;
    ShortStack small(1);
    small.before(at(0, false));
    EXPECT_TRUE(small.before(at(4, false)).any());
    small.reset();
    EXPECT_EQ(small.on_chip() + small.spilled(), 0u);
}

// Pops past the bottom (a depth saturated at 127, or a trace without depths) change nothing.
TEST(ShortStack, PopsPastTheBottomAreIgnored) {
    ShortStack st(2);
    st.before(at(0, false));
    const StackTraffic t = st.before(at(0, true));
    EXPECT_FALSE(t.any());
    EXPECT_EQ(st.on_chip(), 0u);
}

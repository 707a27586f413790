// Progress lines: the time left from the share done and the time it took.
#include <gtest/gtest.h>

#include "sim/progress.h"

using namespace rtsim;

TEST(Progress, TimeLeftFromTheShareDone) {
    // A quarter done in 10 s: 30 s left. A tenth in 20 s: 180 s = 3 min.
    EXPECT_EQ(time_left(10, 0.25), "about 30 s left");
    EXPECT_EQ(time_left(20, 0.1), "about 3 min 0 s left");
    EXPECT_EQ(time_left(100, 0.05), "about 31 min 40 s left");
    EXPECT_EQ(time_left(3600, 0.5), "about 1 h 0 min left");
    EXPECT_EQ(time_left(0.2, 0.5), "under 1 s left");
    // Too early (below 1%), finished, or no time measured yet: nothing said.
    EXPECT_EQ(time_left(5, 0.005), "");
    EXPECT_EQ(time_left(5, 1.0), "");
    EXPECT_EQ(time_left(0, 0.5), "");
}

TEST(Progress, SweepLineCountsPointsAndEstimates) {
    EXPECT_EQ(sweep_progress_line(0, 2, 0, 8, 1.0),
              "[rtsim] sweep: 0 of 8 points done, 2 running, 0 failed");
    // 2 of 8 in 30 s: 90 s left at that pace.
    EXPECT_EQ(sweep_progress_line(2, 2, 1, 8, 30.0),
              "[rtsim] sweep: 2 of 8 points done, 2 running, 1 failed, about 1 min 30 s left");
}

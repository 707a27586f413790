// Progress lines on a terminal: how far a run or a sweep is and an estimate of the
// time left, from the share done so far and the time it took.
#pragma once

#include <cmath>
#include <string>

#include <fmt/format.h>

namespace rtsim {

// "under 1 s left", "about 12 s left", "about 3 min 5 s left", "about 1 h 20 min left"; empty until
// `fraction` (of the work done after `elapsed_seconds`) is large enough to say anything (1%) or
// when it is complete.
inline std::string time_left(double elapsed_seconds, double fraction) {
    if (!(fraction >= 0.01) || fraction >= 1.0 || !(elapsed_seconds > 0)) return {};
    const double left = elapsed_seconds * (1.0 - fraction) / fraction;
    const long s = std::lround(left);
    if (s < 1) return "under 1 s left";
    if (s < 60) return fmt::format("about {} s left", s);
    if (s < 3600) return fmt::format("about {} min {} s left", s / 60, s % 60);
    return fmt::format("about {} h {} min left", s / 3600, (s % 3600) / 60);
}

// A sweep's line: points done, running and failed, and the time left at the pace so far.
inline std::string sweep_progress_line(size_t done, size_t running, size_t failed, size_t total,
                                       double elapsed_seconds) {
    std::string line = fmt::format("[rtsim] sweep: {} of {} points done, {} running, {} failed",
                                   done, total, running, failed);
    const std::string left = time_left(elapsed_seconds, total ? double(done) / double(total) : 0.0);
    return left.empty() ? line : line + ", " + left;
}

}  // namespace rtsim

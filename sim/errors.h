// How rtsim reports a failure: one line on stderr and the exit status (2: bad input or usage,
// 1: a runtime failure).
#pragma once

#include <string>

namespace rtsim {

constexpr int kExitRuntimeFailure = 1;
constexpr int kExitBadInput = 2;

// Prints "rtsim: error: MESSAGE" (bad input) or "rtsim: failed: MESSAGE" and returns the status.
int report_failure(const std::string& message, bool bad_input);

}  // namespace rtsim

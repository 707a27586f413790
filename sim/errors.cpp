#include "sim/errors.h"

#include <fmt/format.h>

namespace rtsim {

int report_failure(const std::string& message, bool bad_input) {
    fmt::print(stderr, "rtsim: {}: {}\n", bad_input ? "error" : "failed", message);
    return bad_input ? kExitBadInput : kExitRuntimeFailure;
}

}  // namespace rtsim

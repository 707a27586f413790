// Error kinds that map to exit codes: bad input (2) vs. runtime failure (1).
#pragma once

#include <stdexcept>
#include <string>

namespace rtsim {

// Bad user input: a config, scene, trace or command-line value. Message is one line that names
// the file (or option) and what was expected.
class InputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

}  // namespace rtsim

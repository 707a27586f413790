// Error kinds that map to exit codes: bad input (2) vs. runtime failure (1).
#pragma once

#include <cstdio>
#include <stdexcept>
#include <string>

namespace rtsim {

// Bad user input: a config, scene, trace or command-line value. Message is one line that names
// the file (or option) and what was expected.
class InputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// A one-line warning on stderr: the input is usable but outside what the results are checked
// for (the run goes on).
inline void warn(const std::string& message) {
    std::fprintf(stderr, "rtsim: warning: %s\n", message.c_str());
}

// The SIGINT or SIGTERM received so far, or 0; set by the command line (sim/interrupt.cpp), whose
// handlers only record the signal. Code that cannot poll for it (a third-party reader) is
// watched from another thread with it.
using InterruptProbe = int (*)();
inline InterruptProbe& interrupt_probe() {
    static InterruptProbe probe = nullptr;
    return probe;
}

}  // namespace rtsim

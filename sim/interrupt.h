// SIGINT and SIGTERM: a long command (run, trace, sweep) stops at its next unit of work (a ray,
// a batch of rays, a finished sweep point), removes what it had not finished (output goes through
// AtomicOutputFile, whose temporary files are removed as the stack unwinds), and exits with
// 128 + the signal's number after one line on stderr. A sweep's finished points stay: `--resume`
// runs the rest.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>

namespace rtsim {

// Installs the handlers (they only record the signal; the commands poll for it).
void install_interrupt_handlers();
// The signal received (SIGINT, SIGTERM), or 0.
int interrupt_signal();
// "SIGINT" or "SIGTERM".
std::string interrupt_name(int signal);

// Thrown where a command notices the signal outside the SystemC kernel.
class Interrupted : public std::runtime_error {
  public:
    // `what`: what was kept and what was not, for the one-line report.
    explicit Interrupted(int signal, std::string what = "no unfinished output written")
        : std::runtime_error(std::move(what)), signal_(signal) {}
    int signal() const { return signal_; }

  private:
    int signal_;
};

// Throws Interrupted if a signal came.
inline void check_interrupt() {
    if (const int s = interrupt_signal()) throw Interrupted(s);
}

// Prints "rtsim: interrupted by SIGINT: WHAT" and returns 128 + the signal.
int report_interrupt(int signal, const std::string& what);

}  // namespace rtsim

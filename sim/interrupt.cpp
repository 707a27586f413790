#include "sim/interrupt.h"

#include <fmt/format.h>
#include <signal.h>

#include <csignal>

#include "workloads/error.h"

namespace rtsim {
namespace {
volatile std::sig_atomic_t g_signal = 0;

extern "C" void on_signal(int s) {
    g_signal = s;
}
}  // namespace

void install_interrupt_handlers() {
    struct sigaction sa {};
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;  // no SA_RESTART: a sweep's waitpid returns to look at the signal
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
    interrupt_probe() = interrupt_signal;
}

int interrupt_signal() {
    return int(g_signal);
}

std::string interrupt_name(int signal) {
    return signal == SIGINT    ? "SIGINT"
           : signal == SIGTERM ? "SIGTERM"
                               : fmt::format("signal {}", signal);
}

int report_interrupt(int signal, const std::string& what) {
    fmt::print(stderr, "rtsim: interrupted by {}: {}\n", interrupt_name(signal), what);
    return 128 + signal;
}

}  // namespace rtsim

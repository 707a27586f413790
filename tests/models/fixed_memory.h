// Test doubles for the blocks below a cache or a core: memories a block's socket binds to, and
// the kernel steps a test takes before it calls the blocks.
#pragma once

#include <systemc>
#include <vector>

#include "models/timing.h"
#include "models/transaction.h"

namespace rtsim::test {

// A memory the blocks reach through `up` (b_transport, as the fast engine's requests do): its
// MemoryPort calls are what a test writes.
class TargetMemory : public sc_core::sc_module, public MemoryPort {
  public:
    // (The name lives as long as the expression that builds the memory: SystemC's rule for a
    // module's sockets.)
    explicit TargetMemory(const sc_core::sc_module_name& name =
                              sc_core::sc_module_name(sc_core::sc_gen_unique_name("memory")))
        : sc_core::sc_module(name), up("up") {
        up.register_b_transport<&TargetMemory::b_transport>(this);
    }
    TargetSocket<TargetMemory> up;

  private:
    void b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
        serve_loosely_timed(*this, gp, delay);
    }
};

// A memory level with a fixed latency and no contention.
class FixedLatencyMemory : public TargetMemory {
  public:
    explicit FixedLatencyMemory(Cycle latency) : latency_(latency) {}
    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* bd = nullptr) override {
        addrs.push_back(addr);
        times.push_back(now);
        bytes += size_bytes;
        if (bd) bd->cycles[level] += latency_;
        return now + latency_;
    }
    // Posted writes: recorded apart from reads, accepted `write_latency` after they come.
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        write_addrs.push_back(addr);
        write_times.push_back(now);
        write_bytes += size_bytes;
        return now + write_latency;
    }
    Cycle write_latency = 0;
    std::vector<uint64_t> write_addrs;
    std::vector<Cycle> write_times;
    uint64_t write_bytes = 0;
    std::vector<uint64_t> addrs;
    std::vector<Cycle> times;  // cycle of each request, in arrival order
    uint64_t bytes = 0;
    int level = kLevelDram;  // where its latency is attributed

  private:
    Cycle latency_;
};

// SystemC binds sockets at elaboration: a test that calls blocks directly (not from a process
// under sc_start) elaborates once it has built them.
inline void elaborate() {
    sc_core::sc_report_handler::set_actions(sc_core::SC_ID_NO_SC_START_ACTIVITY_,
                                            sc_core::SC_DO_NOTHING);
    sc_core::sc_start(sc_core::SC_ZERO_TIME);
}

// A test that builds blocks again after elaborate() (one hierarchy per case of a loop) starts a
// new kernel first. The elaborated one is kept as it is, never freed: its blocks still refer to
// it until they are destroyed.
inline void fresh_kernel() {
    // (Never destroyed, so that they stay reachable to the end: no leak to report.)
    static auto* const kept = new std::vector<sc_core::sc_simcontext*>;
    if (sc_core::sc_curr_simcontext) kept->push_back(sc_core::sc_curr_simcontext);
    sc_core::sc_curr_simcontext = nullptr;
    sc_core::sc_default_global_context = nullptr;
}

}  // namespace rtsim::test

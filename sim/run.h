// `rtsim run`: scene -> BVH -> rays -> functional tracer -> SystemC timing model -> stats.json.
// The work sources are in sim/work_sources.h, the workload's pieces in sim/workload.h, the
// report and summary in sim/run_report.h, the --bound run in sim/bound.h.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sim/config.h"
#include "sim/workload.h"

namespace rtsim {

struct RunOptions {
    std::string config_path;  // empty: schema defaults
    std::vector<std::string> sets;
    WorkloadOptions workload;
    std::string trace_path;       // replay this trace instead of generating rays
    std::string out_dir;          // empty: a fresh folder under out/
    std::string bvh_cache;        // --bvh-cache: "off", a folder, or empty for the default
    double target_error_pct = 0;  // --target-error (sim.sampled = true)
    // --pilot-units (a --target-error pilot's child run): the skip design's period is raised so
    // that about this many of the units it draws from are measured (0: as configured).
    uint64_t pilot_units = 0;
    std::string reference_dir;     // --reference: matched-pair sampling (sim/sampling/reference.h)
    std::string sample_order_dir;  // --sample-order: strata cut from units ordered by its cycles
    bool quiet = false;
    int tracer_threads = 1;      // --tracer-threads: threads generating and tracing rays
    std::string mem_trace_path;  // --mem-trace: write the requests that reach DRAM here
    // Also run the same rays with ideal memory and unlimited units (a child rtsim process) and
    // report achieved / bound. `argv` is this process's command line, to repeat it.
    bool bound = false;
    std::vector<std::string> argv;
};

// Returns the process exit status. Throws InputError for bad input.
int run_command(const RunOptions& options);

}  // namespace rtsim

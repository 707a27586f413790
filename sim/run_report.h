// A run's stats.json, assembled from the chip's blocks, the workload and the host's timings,
// and the summary `rtsim run` prints from it.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "sim/chip.h"
#include "sim/config.h"
#include "sim/stats_report.h"
#include "sim/work_sources.h"

namespace rtsim {

// Host wall-clock times of a run (stats.json's "host"; never part of the simulated figures).
struct HostTimes {
    double run_time_s = 0, prepare_s = 0, simulation_s = 0;
    // The process's CPU seconds (all its threads) over run_time_s; a child process's (the
    // --target-error pilot, a paired run's matched sample) are not in it.
    double run_cpu_s = 0;
    double bvh_build_s = -1;   // < 0: the BVH came with a trace
    std::string trace;         // the trace replayed, if any
    std::string bvh_cache;     // what the BVH cache did: off, hit, built, rebuilt (empty: trace)
    double scene_load_s = -1;  // < 0: no scene (a trace)
    std::string mesh_cache;    // what the mesh cache did (workloads/mesh_cache.h)
};

// What the blocks' reports need of the run.
ReportContext report_context(const Params& params, const Chip& chip, uint64_t rays);
// stats.json without "bound": config echo, scene, BVH and workload (`meta`), rays, cycles, the
// blocks' sections, time series, host times.
nlohmann::json run_report(const Config& cfg, const Chip& chip, const nlohmann::json& meta,
                          const CountingSource& source, const HostTimes& host);
// The console summary of a run's stats.json.
void print_run_summary(const nlohmann::json& out, const std::string& stats_path);
// Peak resident memory of this process so far.
double peak_rss_mib();

}  // namespace rtsim

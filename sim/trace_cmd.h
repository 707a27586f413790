// `rtsim trace`: the functional tracer alone, on generated rays or on an external ray file,
// writing hits as CSV and/or binary (see workloads/ray_file.h for the formats).
#pragma once

#include <string>
#include <vector>

#include "sim/run.h"

namespace rtsim {

struct TraceOptions {
    std::string config_path;
    std::vector<std::string> sets;
    WorkloadOptions workload;
    std::string rays_file;   // external rays; empty: rays from the generator
    std::string hits_csv;    // CSV hits output
    std::string hits_bin;    // binary hits output
    std::string write_rays;  // write the rays traced, in the ray-file format
    std::string trace_out;   // record a trace file (.rtt)
    std::string bvh_cache;   // --bvh-cache: "off", a folder, or empty for the default
    uint32_t trace_chunk_rays = 4096;
    bool any_hit = false;     // external rays: occlusion (any hit) instead of closest hit
    int threads = 0;          // 0: all hardware threads
    int packet = 0;           // rays per packet (consecutive rays of one kind); 0: single rays
    float packet_switch = 0;  // packets go single-ray below this active-lane fraction
    bool quiet = false;
};

int trace_command(const TraceOptions& options);
void add_trace_options(CLI::App* cmd, TraceOptions& t);

}  // namespace rtsim

// `rtsim run`: scene -> BVH -> rays -> functional tracer -> SystemC timing model -> stats.json.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sim/config.h"
#include "workloads/bvh.h"
#include "workloads/raygen.h"

namespace CLI {
class App;
}

namespace rtsim {

class TraceReader;

// Scene and ray options shared by every command that produces rays (run, trace).
struct WorkloadOptions {
    std::string scene = "builtin:cornell";
    std::string rays = "primary";  // parsed into gen.kinds
    std::string res = "128x128";   // parsed into gen.width, gen.height
    std::string light = "point";   // parsed into gen.light
    RayGenOptions gen;

    // Parses the text options into `gen` and validates it. Throws InputError.
    void resolve();
};

struct RunOptions {
    std::string config_path;  // empty: schema defaults
    std::vector<std::string> sets;
    WorkloadOptions workload;
    std::string trace_path;  // replay this trace instead of generating rays
    std::string out_dir;     // empty: a fresh folder under out/
    bool quiet = false;
    // Also run the same rays with ideal memory and unlimited units (a child rtsim process) and
    // report achieved / bound. `argv` is this process's command line, to repeat it.
    bool bound = false;
    std::vector<std::string> argv;
};

// Returns the process exit status. Throws InputError for bad input.
int run_command(const RunOptions& options);

// Sections of stats.json and of a trace's header metadata.
nlohmann::json scene_summary(const Scene& scene);
nlohmann::json bvh_summary(const Bvh& bvh, bool treelet_tables = false);
nlohmann::json workload_summary(const RayGenOptions& rg, float ao_length);
// The layout a bvh_summary describes; throws InputError naming `where` if it is incomplete.
BvhLayout layout_from_summary(const nlohmann::json& bvh, const std::string& where);
// A trace's header metadata, checked, with the reader's layout set from it. Throws InputError.
nlohmann::json open_trace_metadata(TraceReader& reader, const std::string& path);
// Config fields that are valid one by one but not together (a treelet mode without treelets, a
// treelet cache with a split L1, packets replayed from a trace). Throws InputError.
void check_config_combination(const Config& cfg, const std::string& trace_path);
// A trace's BVH summary against the config's BVH fields; `where` names the trace in the error.
void check_trace_matches_config(const nlohmann::json& bvh, const Config& cfg,
                                const std::string& where);
// Peak resident memory of this process so far.
double peak_rss_mib();

// The BVH the config's "bvh" section asks for.
Bvh build_bvh_from_config(const Config& cfg, const Scene& scene);

// "WxH" -> width, height. Throws InputError naming `what`.
void parse_resolution(const std::string& text, const std::string& what, int& width, int& height);

// Adds the scene and ray options (--scene, --rays, --res, ...) to a command.
void add_workload_options(CLI::App* cmd, WorkloadOptions& w);

}  // namespace rtsim

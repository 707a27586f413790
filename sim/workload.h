// What a run or a trace works on: the scene and ray options, the BVH the config asks for, the
// summaries stats.json and trace headers carry, and the checks that a trace and a config fit.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "sim/config.h"
#include "workloads/bvh.h"
#include "workloads/bvh_cache.h"
#include "workloads/bvh_summary.h"
#include "workloads/instances.h"
#include "workloads/raygen.h"
#include "workloads/scene.h"

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
    bool flatten = false;          // a mesh file whose nodes share meshes: one flattened mesh
    RayGenOptions gen;

    // Parses the text options into `gen` and validates it. Throws InputError.
    void resolve();
};

// Ends a refusal of what scenes of instances cannot do yet, when the scene is a mesh file read
// as instances (a scene file has no flattened form).
constexpr const char* kOrFlatten = " (or add --flatten to read it as one mesh)";

// Adds the scene and ray options (--scene, --rays, --res, ...) to a command.
void add_workload_options(CLI::App* cmd, WorkloadOptions& w);
// "WxH" -> width, height. Throws InputError naming `what`.
void parse_resolution(const std::string& text, const std::string& what, int& width, int& height);

// The record sizes the config gives a BVH's layout (bvh.node_size_bytes, triangle_size_bytes).
BvhLayout layout_sizes_from_config(const Config& cfg);
// A scene of instances' two levels as the config's "bvh" section asks for, each BLAS through
// the BVH cache in `cache_dir` (empty: none; the TLAS is always built).
TwoLevelBvh build_two_level_from_config(const Config& cfg, const InstancedScene& scene,
                                        const std::string& cache_dir = "",
                                        size_t* blas_cache_hits = nullptr);
// The BVH the config's "bvh" section asks for, through the BVH cache in `cache_dir` (empty:
// none; workloads/bvh_cache.h). `scene_hash`: the scene's content hash if known.
Bvh build_bvh_from_config(const Config& cfg, const Scene& scene, const std::string& cache_dir,
                          BvhCacheStatus* status = nullptr,
                          std::optional<uint64_t> scene_hash = std::nullopt);
// The --bvh-cache option: "off" -> none, empty -> default_bvh_cache_dir(), else the folder.
std::string resolve_bvh_cache_dir(const std::string& option);
// Adds --bvh-cache to a command that builds BVHs.
void add_bvh_cache_option(CLI::App* cmd, std::string& dir);

// Sections of stats.json and of a trace's header metadata.
nlohmann::json scene_summary(const Scene& scene);
// The same with the scene's content hash already known (BvhCacheStatus::scene_hash).
nlohmann::json scene_summary(const Scene& scene, uint64_t content_hash);
// A scene file's: "triangles" are its meshes' (unique), "instanced_triangles" every instance's.
nlohmann::json scene_summary(const InstancedScene& scene);
nlohmann::json workload_summary(const RayGenOptions& rg, float ao_length);
// A trace's header metadata, checked to be an RTSim trace's (the reader has set its layout
// from it). Throws InputError.
nlohmann::json open_trace_metadata(TraceReader& reader, const std::string& path);
// A run's inputs that are valid one by one but not together (a traversal mode that cannot
// replay traces given one). Config-only combinations are checked when the config loads.
void check_config_combination(const Config& cfg, const std::string& trace_path);
// A trace's BVH summary against the config's BVH fields; `where` names the trace in the error.
void check_trace_matches_config(const nlohmann::json& bvh, const Config& cfg,
                                const std::string& where);

}  // namespace rtsim

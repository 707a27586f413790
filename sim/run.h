// `rtsim run`: scene -> BVH -> rays -> functional tracer -> SystemC timing model -> stats.json.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace rtsim {

// Scene and ray options shared by every command that produces rays (run, and later trace).
struct WorkloadOptions {
    std::string scene = "builtin:cornell";
    std::string rays = "primary";
    int width = 128, height = 128;
    uint64_t seed = 1;
    int ao_samples = 2;
    float ao_length_fraction = 0.1f;
};

struct RunOptions {
    std::string config_path;  // empty: schema defaults
    std::vector<std::string> sets;
    WorkloadOptions workload;
    std::string out_dir;  // empty: a fresh folder under out/
    bool quiet = false;
};

// Returns the process exit status. Throws InputError for bad input.
int run_command(const RunOptions& options);

// "WxH" -> width, height. Throws InputError naming `what`.
void parse_resolution(const std::string& text, const std::string& what, int& width, int& height);

}  // namespace rtsim

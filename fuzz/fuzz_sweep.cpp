// Sweep files: the plan (schema of the sweep file, its base config and overrides, every point's
// config checked against the config schema) is built before anything runs; nothing runs here.
#include "fuzz/fuzz_input.h"
#include "sim/sweep.h"
#include "workloads/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = rtsim::fuzz::write_input(data, size, ".json");
    try {
        const rtsim::SweepPlan plan = rtsim::plan_sweep(path);
        (void)plan.points.size();
    } catch (const rtsim::InputError&) {
    }
    return 0;
}

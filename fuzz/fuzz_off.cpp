// The OFF reader (and the scene loader's checks on what it reads).
#include "fuzz/fuzz_input.h"
#include "workloads/error.h"
#include "workloads/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = rtsim::fuzz::write_input(data, size, ".off");
    try {
        const rtsim::Scene s = rtsim::load_scene(path);
        (void)s.bounds();
    } catch (const rtsim::InputError&) {
    }
    return 0;
}

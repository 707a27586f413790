// Ray files (rtsim trace --rays-file): read to the end in small blocks.
#include <vector>

#include "fuzz/fuzz_input.h"
#include "workloads/error.h"
#include "workloads/ray_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = rtsim::fuzz::write_input(data, size, ".rays");
    try {
        rtsim::RayFileReader reader(path);
        std::vector<rtsim::Ray> rays;
        while (reader.read(rays, 7)) {
        }
    } catch (const rtsim::InputError&) {
    }
    return 0;
}

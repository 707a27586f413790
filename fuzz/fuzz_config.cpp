// Config JSON against the schema (and the typed binding and cross-field checks after it).
#include "fuzz/fuzz_input.h"
#include "sim/config.h"
#include "workloads/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = rtsim::fuzz::write_input(data, size, ".json");
    try {
        const rtsim::Config c = rtsim::load_config(path, {});
        (void)c.hash();
    } catch (const rtsim::InputError&) {
    }
    return 0;
}

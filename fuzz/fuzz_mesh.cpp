// The scene loader's other formats, read through assimp: the first byte picks the file name's
// extension (OBJ, STL, glTF), which is what chooses the importer; the rest is the file.
// Not PLY: assimp 5.2.5's PLY reader loops forever on damaged headers (this target found one in
// seconds, tests/data/assimp_hang.ply). That is assimp's bug; rtsim's answer is the watchdog in
// workloads/scene.cpp (a one-line error past a deadline), which a fuzzer would report as a
// crash on every such input, hiding anything else.
#include "fuzz/fuzz_input.h"
#include "workloads/error.h"
#include "workloads/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size == 0) return 0;
    static const char* const kSuffixes[] = {".obj", ".stl", ".gltf"};
    const char* suffix = kSuffixes[data[0] % 3];
    const std::string path = rtsim::fuzz::write_input(data + 1, size - 1, suffix);
    try {
        const rtsim::Scene s = rtsim::load_scene(path);
        (void)s.bounds();
    } catch (const rtsim::InputError&) {
    }
    return 0;
}

// Shared by the fuzz targets: the readers take paths, so each input goes to a scratch file
// (one per process and suffix, rewritten per input, in $TMPDIR or /tmp, removed at exit). Bad input
// must end in InputError (a clear one-line error), never a crash, a hang or unbounded memory; the
// sanitizers and libFuzzer's limits catch the rest.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <string>

// The libraries link SystemC, whose shared library wants an sc_main; a fuzz target's entry is
// libFuzzer's own main.
extern "C" int sc_main(int, char**) {
    return 0;
}

namespace rtsim::fuzz {

// The scratch files this process wrote; libFuzzer ends a run with exit(), which destroys this.
struct ScratchFiles {
    std::set<std::string> paths;
    ~ScratchFiles() {
        for (const std::string& p : paths) std::remove(p.c_str());
    }
};

inline std::string scratch_path(const char* suffix) {
    static ScratchFiles files;
    const char* tmp = std::getenv("TMPDIR");
    const std::string path = std::string(tmp && *tmp ? tmp : "/tmp") + "/rtsim_fuzz_" +
                             std::to_string(getpid()) + std::string(suffix);
    files.paths.insert(path);
    return path;
}

// The readers pick a format by the file name's extension: `suffix`.
inline std::string write_input(const uint8_t* data, size_t size, const char* suffix) {
    const std::string path = scratch_path(suffix);
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f) {
        if (size) std::fwrite(data, 1, size, f);
        std::fclose(f);
    }
    return path;
}

}  // namespace rtsim::fuzz

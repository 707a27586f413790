// One scratch directory per test process, under the system's temp directory, removed when the
// process ends, so test runs leave no files behind (CI machines and laptops alike).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

namespace rtsim::test {

class ScratchDir {
  public:
    ScratchDir()
        : path_(std::filesystem::temp_directory_path() /
                ("rtsim_test_" + std::to_string(::getpid()))) {
        std::filesystem::remove_all(path_);
        std::filesystem::create_directories(path_);
    }
    ~ScratchDir() {
        std::error_code ec;  // best effort: never throw from a static destructor
        std::filesystem::remove_all(path_, ec);
    }
    ScratchDir(const ScratchDir&) = delete;
    ScratchDir& operator=(const ScratchDir&) = delete;

    const std::filesystem::path& path() const { return path_; }

  private:
    std::filesystem::path path_;
};

// The process's scratch directory, made on first use.
inline const std::filesystem::path& scratch_dir() {
    static const ScratchDir dir;
    return dir.path();
}

}  // namespace rtsim::test

// Output files that appear whole or not at all: data goes to PATH.tmp, and commit() renames it
// into place. A file never committed (an error part-way) is removed, so bad input never leaves
// partial or corrupted output behind, and an existing file at PATH survives a failed run.
// A symlink stays a symlink (the file behind it is replaced); a pipe or a device (/dev/stdout)
// is written in place, never replaced.
#pragma once

#include <cstdio>
#include <optional>
#include <string>

namespace rtsim {

class AtomicOutputFile {
  public:
    explicit AtomicOutputFile(std::string path);  // throws InputError if it cannot be created
    ~AtomicOutputFile();
    AtomicOutputFile(const AtomicOutputFile&) = delete;
    AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

    void write(const std::string& data);  // throws std::runtime_error on a write failure
    void commit();
    const std::string& path() const { return path_; }

  private:
    std::string path_;
    std::string target_, tmp_;  // the file behind any link, and the temporary file beside it
    std::FILE* f_ = nullptr;
    bool direct_ = false;  // a pipe or device: written in place
};

// Writes text to path atomically.
void write_file_atomically(const std::string& path, const std::string& text);

// The whole file's bytes; nullopt if it cannot be opened.
std::optional<std::string> read_file_text(const std::string& path);

}  // namespace rtsim

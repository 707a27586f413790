// A file's bytes, read and written whole: the cache tests damage, truncate and swap entries.
#pragma once

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace rtsim::test {

inline std::string read_file_bytes(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

inline void write_file_bytes(const std::filesystem::path& p, const std::string& bytes) {
    std::ofstream(p, std::ios::binary | std::ios::trunc)
        .write(bytes.data(), std::streamsize(bytes.size()));
}

}  // namespace rtsim::test

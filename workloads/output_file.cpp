#include "workloads/output_file.h"

#include <fmt/format.h>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>

#include "workloads/error.h"

namespace rtsim {

AtomicOutputFile::AtomicOutputFile(std::string path)
    : path_(std::move(path)), tmp_(path_ + ".tmp") {
    f_ = std::fopen(tmp_.c_str(), "wb");
    if (!f_)
        throw InputError(
            fmt::format("{}: cannot create output file: {}", path_, std::strerror(errno)));
}

AtomicOutputFile::~AtomicOutputFile() {
    if (f_) {
        std::fclose(f_);
        std::remove(tmp_.c_str());
    }
}

void AtomicOutputFile::write(const std::string& data) {
    if (std::fwrite(data.data(), 1, data.size(), f_) != data.size())
        throw std::runtime_error(fmt::format("{}: write failed: {}", tmp_, std::strerror(errno)));
}

void AtomicOutputFile::commit() {
    const bool ok = std::fflush(f_) == 0;
    std::fclose(f_);
    f_ = nullptr;
    std::error_code ec;
    if (ok) std::filesystem::rename(tmp_, path_, ec);
    if (!ok || ec) {
        std::remove(tmp_.c_str());
        throw std::runtime_error(fmt::format("{}: cannot write output file", path_));
    }
}

void write_file_atomically(const std::string& path, const std::string& text) {
    AtomicOutputFile f(path);
    f.write(text);
    f.commit();
}

}  // namespace rtsim

#include "workloads/output_file.h"

#include <fmt/format.h>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "workloads/error.h"

namespace rtsim {

namespace {

namespace fs = std::filesystem;

// Where a regular file at `path` really lives: a symlink's target (followed through chains, a
// dangling one included), so that the rename replaces the target and the link stays.
fs::path file_behind(const fs::path& path) {
    fs::path p = path;
    std::error_code ec;
    for (int hops = 0; hops < 40 && fs::is_symlink(fs::symlink_status(p, ec)); ++hops) {
        const fs::path t = fs::read_symlink(p, ec);
        if (ec) break;
        p = t.is_absolute() ? t : p.parent_path() / t;
    }
    return p;
}

}  // namespace

AtomicOutputFile::AtomicOutputFile(std::string path) : path_(std::move(path)) {
    std::error_code ec;
    const fs::file_status st = fs::status(path_, ec);  // follows links
    // A pipe, a device (/dev/stdout) or a socket is written in place: it cannot be replaced,
    // and must not be (a rename would put a regular file where the device or its link was).
    direct_ = !ec && fs::exists(st) && !fs::is_regular_file(st);
    if (!direct_) {
        target_ = file_behind(path_).string();
        tmp_ = target_ + ".tmp";
    }
    f_ = std::fopen(direct_ ? path_.c_str() : tmp_.c_str(), "wb");
    if (!f_)
        throw InputError(
            fmt::format("{}: cannot create output file: {}", path_, std::strerror(errno)));
}

AtomicOutputFile::~AtomicOutputFile() {
    if (f_) {
        std::fclose(f_);
        if (!direct_) std::remove(tmp_.c_str());
    }
}

void AtomicOutputFile::write(const std::string& data) {
    if (std::fwrite(data.data(), 1, data.size(), f_) != data.size())
        throw std::runtime_error(
            fmt::format("{}: write failed: {}", direct_ ? path_ : tmp_, std::strerror(errno)));
}

void AtomicOutputFile::commit() {
    const bool ok = std::fflush(f_) == 0;
    std::fclose(f_);
    f_ = nullptr;
    if (direct_) {
        if (!ok) throw std::runtime_error(fmt::format("{}: cannot write output", path_));
        return;
    }
    std::error_code ec;
    // Renaming over the file behind any link keeps the link.
    if (ok) std::filesystem::rename(tmp_, target_, ec);
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

std::optional<std::string> read_file_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return std::nullopt;
    // A file of known size is sized once and read in one call; a pipe (tellg fails) or a file
    // that reports no size (/proc) is copied through a stream.
    const std::streamoff size = in.tellg();
    if (size > 0 && in.seekg(0)) {
        std::string bytes(size_t(size), '\0');
        in.read(bytes.data(), size);
        if (in.gcount() == size) return bytes;
        return std::nullopt;
    }
    in.clear();
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

}  // namespace rtsim

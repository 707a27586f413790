// OFF reader. assimp's OFF importer rejects '#' comments after values, which real files use
// (libcgal-demo's mesh_with_colors.off), so OFF gets this small line-based reader with
// precise errors. Other formats go through assimp.
#include <fmt/format.h>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "workloads/error.h"
#include "workloads/scene.h"

namespace rtsim {
namespace {

class LineReader {
  public:
    LineReader(std::istream& in, const std::string& path) : in_(in), path_(path) {}
    // Next line with content, comments stripped; false at end of file.
    bool next(std::string& line) {
        while (std::getline(in_, line)) {
            ++number_;
            const auto hash = line.find('#');
            if (hash != std::string::npos) line.erase(hash);
            if (line.find_first_not_of(" \t\r") != std::string::npos) return true;
        }
        return false;
    }
    [[noreturn]] void fail(const std::string& what) const {
        throw InputError(fmt::format("{}: line {}: {}", path_, number_, what));
    }

  private:
    std::istream& in_;
    const std::string& path_;
    int number_ = 0;
};

}  // namespace

Scene read_off(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(fmt::format("{}: cannot open", path));
    LineReader lines(in, path);
    std::string line;
    if (!lines.next(line)) lines.fail("empty file, expected an OFF header");
    std::istringstream head(line);
    std::string keyword;
    head >> keyword;
    const auto off = keyword.find("OFF");
    if (off != std::string::npos && off + 3 == keyword.size()) {
        const std::string prefix = keyword.substr(0, off);
        if (prefix.find_first_not_of("STCN") != std::string::npos)
            lines.fail(
                fmt::format("unsupported OFF variant '{}' (expected [ST][C][N]OFF)", keyword));
        std::string rest;
        std::getline(head, rest);
        if (rest.find_first_not_of(" \t\r") == std::string::npos) {
            if (!lines.next(line)) lines.fail("expected vertex, face and edge counts");
        } else {
            line = rest;
        }
    } else if (!std::isdigit(static_cast<unsigned char>(keyword[0]))) {
        lines.fail(fmt::format("expected an OFF header, got '{}'", keyword));
    }
    long nv = -1, nf = -1;
    {
        std::istringstream counts(line);
        if (!(counts >> nv >> nf) || nv < 0 || nf < 0)
            lines.fail("expected vertex and face counts");
    }
    if (nv > (1l << 30) || nf > (1l << 30)) lines.fail("vertex or face count too large");

    Scene s;
    // A count is only a claim: reserve no more than the file can hold (a vertex line has at
    // least 6 bytes), so a 20-byte file claiming 2^30 vertices allocates nothing much.
    std::error_code size_error;
    const auto file_bytes = std::filesystem::file_size(path, size_error);
    const size_t most_vertices = size_error ? 0 : size_t(file_bytes / 6);
    s.vertices.reserve(std::min(static_cast<size_t>(nv), most_vertices));
    for (long i = 0; i < nv; ++i) {
        if (!lines.next(line)) lines.fail(fmt::format("file ends after {} of {} vertices", i, nv));
        const char* p = line.c_str();
        float xyz[3];
        for (float& c : xyz) {
            char* end;
            errno = 0;
            c = std::strtof(p, &end);
            if (end == p || !std::isfinite(c)) lines.fail("expected 3 finite vertex coordinates");
            p = end;
        }
        s.vertices.emplace_back(xyz[0], xyz[1], xyz[2]);
    }
    for (long f = 0; f < nf; ++f) {
        if (!lines.next(line)) lines.fail(fmt::format("file ends after {} of {} faces", f, nf));
        std::istringstream face(line);
        long n;
        if (!(face >> n) || n < 1) lines.fail("expected a face's vertex count");
        // Each index takes at least two characters of the line (found by fuzzing: a face of
        // 1.2e17 vertices asked for an allocation of 480 PB).
        if (n > long(line.size()) / 2 + 1)
            lines.fail(fmt::format("a face of {} vertices does not fit its line", n));
        std::vector<uint32_t> idx(static_cast<size_t>(n));
        for (auto& i : idx) {
            long v;
            if (!(face >> v)) lines.fail(fmt::format("expected {} vertex indices", n));
            if (v < 0 || v >= nv)
                lines.fail(fmt::format("vertex index {} out of range 0..{}", v, nv - 1));
            i = static_cast<uint32_t>(v);
        }
        // Polygons become fans in file order, like assimp's triangulation of convex faces.
        for (long k = 1; k + 1 < n; ++k) s.triangles.push_back({idx[0], idx[k], idx[k + 1]});
    }
    return s;
}

}  // namespace rtsim

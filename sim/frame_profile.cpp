#include "sim/frame_profile.h"

#include <unistd.h>

#include <fmt/format.h>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "workloads/tile_queue.h"
#include "workloads/trace_file.h"
#include "workloads/tracer.h"

namespace rtsim {

LineTracker::LineTracker(uint64_t base, uint64_t end, uint32_t line_bytes) {
    line_shift_ = uint64_t(__builtin_ctz(line_bytes));
    first_line_ = base >> line_shift_;
    const uint64_t lines = end > base ? ((end - 1) >> line_shift_) - first_line_ + 1 : 0;
    touched_.assign((lines + 63) / 64, 0);
}

FrameProfile profile_frame(const RayGenerator& gen, const Bvh& bvh, uint64_t unit_tiles,
                           uint64_t base, uint64_t end, uint32_t line_bytes, int threads) {
    const auto start = std::chrono::steady_clock::now();
    FrameProfile p;
    p.unit_tiles = unit_tiles;
    p.line_bytes = line_bytes;
    LineTracker lines(base, end, line_bytes);
    p.line_base = lines.address(0);
    const uint64_t tiles = uint64_t(gen.tile_count());
    p.units.assign((tiles + unit_tiles - 1) / unit_tiles, AuxFigures{});
    p.first_touch_start.assign(tiles + 1, 0);
    // The tiles in frame order, traced on the tile threads as a run's work source does.
    TileQueue queue(gen, threads, [&bvh](std::vector<GeneratedRay>& rays) {
        for (GeneratedRay& g : rays)
            if (!g.traced) {
                g.prim = trace_ray(bvh, g.ray, g.query, &g.steps).prim;
                g.traced = true;
            }
    });
    std::vector<GeneratedRay> rays;
    RayWork work;
    auto new_line = [&p](uint64_t k) { p.first_touches.push_back(uint32_t(k)); };
    while (queue.next(rays)) {
        const uint64_t tile = uint64_t(queue.last_tile()), u = tile / unit_tiles;
        for (GeneratedRay& g : rays) {
            work.rays = 1;
            work.steps.swap(g.steps);
            const AuxFigures a = ray_auxiliaries(work, lines, new_line);
            for (size_t k = 0; k < kAuxiliaries; ++k) p.units[u][k] += a[k];
        }
        rays.clear();
        p.first_touch_start[tile + 1] = uint32_t(p.first_touches.size());
    }
    p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    p.cache = "off";
    return p;
}

namespace {

namespace fs = std::filesystem;

constexpr char kMagic[8] = {'R', 'T', 'S', 'P', 'R', 'O', 'F', '1'};

// Bytes appended and read back in one order; a read past the end or a bad count is an unusable
// entry.
struct Unusable {
    std::string why;
};

template <class T>
void put(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof v);
}
template <class T>
void put_vec(std::string& out, const std::vector<T>& v) {
    put(out, uint64_t(v.size()));
    out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

class Reader {
  public:
    explicit Reader(const std::string& s) : p_(s.data()), end_(s.data() + s.size()) {}
    template <class T>
    T get() {
        T v;
        take(&v, sizeof v);
        return v;
    }
    template <class T>
    void get_vec(std::vector<T>& v) {
        const uint64_t n = get<uint64_t>();
        if (n > uint64_t(end_ - p_) / sizeof(T)) throw Unusable{"truncated"};
        v.resize(size_t(n));
        take(v.data(), size_t(n) * sizeof(T));
    }
    bool done() const { return p_ == end_; }

  private:
    void take(void* dst, size_t n) {
        if (n > size_t(end_ - p_)) throw Unusable{"truncated"};
        if (n) std::memcpy(dst, p_, n);
        p_ += n;
    }
    const char* p_;
    const char* end_;
};

uint64_t fnv(const std::string& s) {
    uint64_t h = 1469598103934665603ull;
    for (unsigned char c : s) {
        h ^= c;
        h *= 1099511628211ull;
    }
    return h;
}

std::string serialize(const FrameProfile& p, const std::string& key) {
    std::string out(kMagic, sizeof kMagic);
    put_vec(out, std::vector<char>(key.begin(), key.end()));
    put(out, p.unit_tiles);
    put(out, p.line_bytes);
    put(out, p.line_base);
    put_vec(out, p.units);
    put_vec(out, p.first_touch_start);
    put_vec(out, p.first_touches);
    put(out, crc32(out.data(), out.size()));
    return out;
}

FrameProfile deserialize(const std::string& bytes, const std::string& key, uint64_t tiles) {
    if (bytes.size() < sizeof kMagic + 4 || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
        throw Unusable{"not a frame profile"};
    uint32_t crc;
    std::memcpy(&crc, bytes.data() + bytes.size() - 4, 4);
    if (crc32(bytes.data(), bytes.size() - 4) != crc) throw Unusable{"checksum mismatch"};
    const std::string body = bytes.substr(sizeof kMagic, bytes.size() - sizeof kMagic - 4);
    Reader r(body);
    std::vector<char> stored;
    r.get_vec(stored);
    if (std::string(stored.begin(), stored.end()) != key) throw Unusable{"key mismatch"};
    FrameProfile p;
    p.unit_tiles = r.get<uint64_t>();
    p.line_bytes = r.get<uint32_t>();
    p.line_base = r.get<uint64_t>();
    r.get_vec(p.units);
    r.get_vec(p.first_touch_start);
    r.get_vec(p.first_touches);
    if (!r.done()) throw Unusable{"trailing bytes"};
    // Structure: a start per tile and one more, non-decreasing, ending at the lines' count.
    if (p.unit_tiles == 0 || p.first_touch_start.size() != tiles + 1 ||
        p.units.size() != (tiles + p.unit_tiles - 1) / p.unit_tiles ||
        p.first_touch_start.front() != 0 || p.first_touch_start.back() != p.first_touches.size() ||
        !std::is_sorted(p.first_touch_start.begin(), p.first_touch_start.end()))
        throw Unusable{"inconsistent contents"};
    return p;
}

}  // namespace

FrameProfile profile_frame_cached(const RayGenerator& gen, const Bvh& bvh, uint64_t unit_tiles,
                                  uint64_t base, uint64_t end, uint32_t line_bytes, int threads,
                                  const std::string& key, const std::string& dir) {
    if (dir.empty()) return profile_frame(gen, bvh, unit_tiles, base, end, line_bytes, threads);
    const auto start = std::chrono::steady_clock::now();
    const std::string full_key = fmt::format("{} unit_tiles={} line_bytes={} range={:x}-{:x}", key,
                                             unit_tiles, line_bytes, base, end);
    const std::string path =
        (fs::path(dir) / fmt::format("profile-{:016x}.bin", fnv(full_key))).string();
    std::string outcome = "built";
    {
        std::ifstream in(path, std::ios::binary);
        if (in) {
            std::ostringstream ss;
            ss << in.rdbuf();
            try {
                FrameProfile p = deserialize(ss.str(), full_key, uint64_t(gen.tile_count()));
                p.cache = "hit";
                p.seconds =
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                return p;
            } catch (const Unusable& u) {
                outcome = "rebuilt: " + u.why;
            }
        }
    }
    FrameProfile p = profile_frame(gen, bvh, unit_tiles, base, end, line_bytes, threads);
    // Written to a temporary file and renamed: concurrent runs never read half an entry. A
    // folder that cannot be written costs only the store.
    std::error_code ec;
    fs::create_directories(dir, ec);
    const std::string tmp = fmt::format("{}.tmp.{}", path, getpid());
    const std::string bytes = serialize(p, full_key);
    bool stored = false;
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        out.write(bytes.data(), std::streamsize(bytes.size()));
        stored = bool(out);
    }
    if (stored) fs::rename(tmp, path, ec);
    if (!stored || ec) {
        fs::remove(tmp, ec);
        std::fprintf(stderr,
                     "rtsim: warning: %s: cannot write the frame profile (the run goes on)\n",
                     path.c_str());
    }
    p.cache = outcome;
    p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return p;
}

}  // namespace rtsim

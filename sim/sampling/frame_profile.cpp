#include "sim/sampling/frame_profile.h"

#include <fmt/format.h>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <stdexcept>

#include "workloads/cache_entry.h"
#include "workloads/tile_queue.h"

namespace rtsim {

LineTracker::LineTracker(uint64_t base, uint64_t end, uint32_t line_bytes) {
    line_shift_ = uint64_t(__builtin_ctz(line_bytes));
    first_line_ = base >> line_shift_;
    lines_ = end > base ? ((end - 1) >> line_shift_) - first_line_ + 1 : 0;
    touched_.assign((lines_ + 63) / 64, 0);
}

FrameProfile profile_frame(const RayGenerator& gen, const TraceRays& trace, uint64_t unit_tiles,
                           uint64_t base, uint64_t end, uint32_t line_bytes, int threads) {
    const auto start = std::chrono::steady_clock::now();
    FrameProfile p;
    p.unit_tiles = unit_tiles;
    p.line_bytes = line_bytes;
    LineTracker lines(base, end, line_bytes);
    p.line_base = lines.address(0);
    const uint64_t tiles = uint64_t(gen.tile_count());
    p.units.assign((tiles + unit_tiles - 1) / unit_tiles, AuxFigures{});
    p.unit_new_line_rays.assign(p.units.size(), 0);
    // The per-tile arrays, built here and handed to the profile at the end.
    std::vector<uint32_t> tile_line_start(tiles + 1, 0), tile_rays(tiles, 0), tile_lines;
    std::vector<uint8_t> tile_line_info;
    // Per line of the range: the last tile that fetched it, plus one (0: none yet); the last of
    // that tile's rays that did, plus one; and its entry in tile_lines.
    std::vector<uint32_t> fetched_by(lines.lines(), 0), last_ray(lines.lines(), 0);
    std::vector<size_t> entry(lines.lines(), 0);
    // The tiles in frame order, traced on the tile threads as a run's work source does.
    TileQueue queue(gen, threads, trace);
    std::vector<GeneratedRay> rays;
    std::vector<size_t> new_entries;  // the tile's entries of lines new to the frame
    while (queue.next(rays)) {
        new_entries.clear();
        const uint64_t tile = uint64_t(queue.last_tile()), u = tile / unit_tiles;
        tile_rays[tile] = uint32_t(rays.size());
        const uint32_t stamp = uint32_t(tile + 1);
        AuxFigures& aux = p.units[u];
        uint32_t ray = 0;
        // One pass over each ray's steps for every figure (ray_auxiliaries' counts: a line no
        // tile fetched before is a first touch in the frame).
        for (const GeneratedRay& g : rays) {
            ++ray;
            aux[kAuxWork] += g.steps.size() + 1;
            aux[kAuxRays] += 1;
            for (const Step& s : g.steps) {
                aux[kAuxNodeSteps] += s.kind == StepKind::Node;
                p.fetch_lines += lines.lines_spanned(s);
                p.fetch_bytes += s.size_bytes;
                lines.for_each_line(s, [&](uint64_t k) {
                    if (fetched_by[k] != stamp) {
                        if (fetched_by[k] == 0) {
                            new_entries.push_back(tile_lines.size());
                            ++aux[kAuxNewLines];
                        }
                        fetched_by[k] = stamp;
                        last_ray[k] = ray;
                        entry[k] = tile_lines.size();
                        tile_lines.push_back(uint32_t(k));
                        tile_line_info.push_back(
                            uint8_t(1 | (s.kind == StepKind::Triangle ? kTileLineTriangle : 0)));
                    } else if (last_ray[k] != ray) {
                        last_ray[k] = ray;
                        uint8_t& info = tile_line_info[entry[k]];
                        if ((info & kTileLineRays) != kTileLineRays) ++info;
                    }
                });
            }
        }
        for (size_t e : new_entries) p.unit_new_line_rays[u] += tile_line_info[e] & kTileLineRays;
        rays.clear();
        if (tile_lines.size() > UINT32_MAX)
            throw std::runtime_error("frame profile: more than 2^32 tile lines (a smaller frame)");
        tile_line_start[tile + 1] = uint32_t(tile_lines.size());
    }
    p.tile_line_start = std::move(tile_line_start);
    p.tile_rays = std::move(tile_rays);
    p.tile_lines = std::move(tile_lines);
    p.tile_line_info = std::move(tile_line_info);
    p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    p.cache = "off";
    return p;
}

uint64_t unit_tiles_for_slot_fills(const MappableArray<uint32_t>& tile_rays, uint64_t rays) {
    uint64_t sum = 0, tiles = 0;
    for (uint32_t r : tile_rays) {
        sum += r;
        tiles += r > 0;
    }
    if (sum == 0 || rays == 0) return 1;
    // ceil(rays / (sum / tiles)), in integers.
    return std::max<uint64_t>(1, (rays * tiles + sum - 1) / sum);
}

void merge_profile_units(FrameProfile& p, uint64_t merge) {
    if (merge == 0) throw std::invalid_argument("merge_profile_units: merge >= 1");
    if (merge == 1) return;
    const size_t units = (p.units.size() + merge - 1) / merge;
    std::vector<AuxFigures> merged(units, AuxFigures{});
    std::vector<uint64_t> new_line_rays(units, 0);
    for (size_t u = 0; u < p.units.size(); ++u) {
        for (size_t k = 0; k < kAuxiliaries; ++k) merged[u / merge][k] += p.units[u][k];
        new_line_rays[u / merge] += p.unit_new_line_rays[u];
    }
    p.units = std::move(merged);
    p.unit_new_line_rays = std::move(new_line_rays);
    p.unit_tiles *= merge;
    if (!p.key.empty()) p.key += fmt::format(" merged to {} tiles", p.unit_tiles);
}

namespace {

namespace fs = std::filesystem;

// 8: per-tile arrays on 64-byte boundaries, mapped on a hit.
constexpr char kMagic[8] = {'R', 'T', 'S', 'P', 'R', 'O', 'F', '8'};

using Unusable = CacheEntryUnusable;

std::string serialize(const FrameProfile& p, const std::string& key) {
    CacheEntryWriter w(kMagic);
    w.key(key);
    w.pod(p.unit_tiles);
    w.pod(p.line_bytes);
    w.pod(p.line_base);
    w.vec(p.units);
    w.vec(p.unit_new_line_rays);
    w.aligned_vec(p.tile_line_start);
    w.aligned_vec(p.tile_lines);
    w.aligned_vec(p.tile_line_info);
    w.aligned_vec(p.tile_rays);
    w.pod(p.fetch_lines);
    w.pod(p.fetch_bytes);
    return w.finish();
}

FrameProfile deserialize(std::string_view bytes, const std::string& key, uint64_t tiles,
                         const std::shared_ptr<const void>& keep) {
    CacheEntryReader r =
        open_cache_entry(bytes, kMagic, "not a frame profile", "checksum mismatch");
    r.expect_key(key);
    FrameProfile p;
    p.unit_tiles = r.pod<uint64_t>();
    p.line_bytes = r.pod<uint32_t>();
    p.line_base = r.pod<uint64_t>();
    r.vec(p.units);
    r.vec(p.unit_new_line_rays);
    r.view(p.tile_line_start, keep);
    r.view(p.tile_lines, keep);
    r.view(p.tile_line_info, keep);
    r.view(p.tile_rays, keep);
    p.fetch_lines = r.pod<uint64_t>();
    p.fetch_bytes = r.pod<uint64_t>();
    if (!r.done()) throw Unusable{"trailing bytes"};
    // Structure: a start per tile and one more, non-decreasing, ending at the lines' count.
    if (p.unit_tiles == 0 || p.tile_line_start.size() != tiles + 1 ||
        p.units.size() != (tiles + p.unit_tiles - 1) / p.unit_tiles ||
        p.unit_new_line_rays.size() != p.units.size() || p.tile_line_start.front() != 0 ||
        p.tile_line_start.back() != p.tile_lines.size() ||
        p.tile_line_info.size() != p.tile_lines.size() || p.tile_rays.size() != tiles ||
        !std::is_sorted(p.tile_line_start.begin(), p.tile_line_start.end()))
        throw Unusable{"inconsistent contents"};
    return p;
}

}  // namespace

FrameProfile profile_frame_cached(const RayGenerator& gen, const TraceRays& trace,
                                  uint64_t unit_tiles, uint64_t base, uint64_t end,
                                  uint32_t line_bytes, int threads, const std::string& key,
                                  const std::string& dir) {
    if (dir.empty()) return profile_frame(gen, trace, unit_tiles, base, end, line_bytes, threads);
    const auto start = std::chrono::steady_clock::now();
    // The format's magic in the key: an entry of an older format is never read (nor warned of).
    const std::string full_key =
        fmt::format("{} unit_tiles={} line_bytes={} range={:x}-{:x} {}", key, unit_tiles,
                    line_bytes, base, end, std::string(kMagic, sizeof kMagic));
    const std::string path =
        (fs::path(dir) /
         fmt::format("profile-{:016x}.bin", fnv1a(kFnvOffset, full_key.data(), full_key.size())))
            .string();
    std::string outcome;
    FrameProfile p = through_cache_entry(
        path,
        [&](std::string_view bytes, const std::shared_ptr<const void>& keep) {
            return deserialize(bytes, full_key, uint64_t(gen.tile_count()), keep);
        },
        [&] { return profile_frame(gen, trace, unit_tiles, base, end, line_bytes, threads); },
        [&](const FrameProfile& built) { return serialize(built, full_key); }, "frame profile",
        outcome);
    p.cache = outcome;
    p.key = full_key;
    p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return p;
}

}  // namespace rtsim

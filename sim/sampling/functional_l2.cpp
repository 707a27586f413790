#include "sim/sampling/functional_l2.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <stdexcept>

#include "workloads/cache_entry.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace rtsim {

namespace {

// An LRU cache of line indices: per set, `stride` tags (the ways, padded to a multiple of 4 with
// a tag no line has) and their last use. Exact LRU by use stamps, as models/replacement/lru.cpp.
class LruTags {
  public:
    LruTags(uint64_t sets, uint32_t ways)
        : ways_(ways),
          stride_((ways + 3) / 4 * 4),
          tags_(sets * stride_, kNone),
          stamps_(sets * stride_, 0) {}

    // True on a hit; a miss installs the line over the least recently used way.
    bool access(uint64_t set, uint32_t line) {
        uint32_t* tags = &tags_[set * stride_];
        uint32_t* stamps = &stamps_[set * stride_];
        const int way = find(tags, line);
        if (way >= 0) {
            stamps[way] = ++now_;
            return true;
        }
        uint32_t victim = 0;  // an empty way has stamp 0: filled before any eviction
        for (uint32_t w = 1; w < ways_; ++w) victim = stamps[w] < stamps[victim] ? w : victim;
        tags[victim] = line;
        stamps[victim] = ++now_;
        return false;
    }

  private:
    static constexpr uint32_t kNone = UINT32_MAX;
    int find(const uint32_t* tags, uint32_t line) const {
#ifdef __SSE2__
        if (stride_ > 64) return scan(tags, line);  // more ways than the mask has bits
        // Every group compared, no early exit (which group holds the line is a coin toss for
        // the branch predictor); a line is in at most one way.
        const __m128i key = _mm_set1_epi32(int(line));
        uint64_t hits = 0;
        for (uint32_t g = 0; g < stride_; g += 4) {
            const __m128i four = _mm_loadu_si128(reinterpret_cast<const __m128i*>(tags + g));
            hits |= uint64_t(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(four, key)))) << g;
        }
        return hits ? int(__builtin_ctzll(hits)) : -1;
#else
        return scan(tags, line);
#endif
    }
    int scan(const uint32_t* tags, uint32_t line) const {
        for (uint32_t w = 0; w < ways_; ++w)
            if (tags[w] == line) return int(w);
        return -1;
    }
    uint32_t ways_, stride_;
    std::vector<uint32_t> tags_, stamps_;
    uint32_t now_ = 0;
};

}  // namespace

FunctionalL2 functional_l2_misses(const FrameProfile& p, uint64_t sets, uint32_t ways) {
    const auto start = std::chrono::steady_clock::now();
    if (sets == 0 || (sets & (sets - 1)) != 0 || ways == 0 || p.line_bytes == 0)
        throw std::invalid_argument("functional_l2_misses: sets a power of two, ways >= 1");
    FunctionalL2 out;
    out.cache = "off";
    out.unit_capacity_misses.assign(p.units.size(), 0);
    if (p.tile_lines.empty()) return out;
    // Use stamps count accesses: more than 2^32 - 1 would wrap them.
    if (p.tile_lines.size() >= UINT32_MAX)
        throw std::invalid_argument("functional_l2_misses: too many tile lines");
    // The cache model's set is the line address's low bits; the profile's lines are numbered
    // from its base, which adds the same to every line: which lines share a set is the same.
    const uint64_t set_mask = sets - 1;
    const uint32_t distinct = *std::max_element(p.tile_lines.begin(), p.tile_lines.end()) + 1;
    std::vector<uint8_t> fetched(distinct, 0);
    LruTags cache(sets, ways);
    const size_t tiles = p.tile_line_start.size() - 1;
    if (p.unit_tiles == 0 || (tiles + p.unit_tiles - 1) / p.unit_tiles > p.units.size())
        throw std::invalid_argument(
            "functional_l2_misses: the profile's units do not cover its tiles");
    for (size_t t = 0; t < tiles; ++t) {
        uint32_t& unit = out.unit_capacity_misses[t / p.unit_tiles];
        for (uint32_t i = p.tile_line_start[t]; i < p.tile_line_start[t + 1]; ++i) {
            const uint32_t line = p.tile_lines[i];
            if (cache.access(line & set_mask, line)) continue;
            ++out.misses;
            if (fetched[line]) {
                ++unit;
                ++out.capacity_misses;
            }
            fetched[line] = 1;
        }
    }
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return out;
}

FunctionalL1 functional_l1_misses(const FrameProfile& p, uint64_t cores, uint64_t sets,
                                  uint32_t ways, bool split) {
    const auto start = std::chrono::steady_clock::now();
    if (cores == 0 || sets == 0 || (sets & (sets - 1)) != 0 || ways == 0)
        throw std::invalid_argument("functional_l1_misses: cores >= 1, sets a power of two");
    FunctionalL1 out;
    out.unit_misses.assign(p.units.size(), 0);
    const size_t tiles = p.tile_line_start.empty() ? 0 : p.tile_line_start.size() - 1;
    if (tiles == 0) return out;
    if (p.unit_tiles == 0 || (tiles + p.unit_tiles - 1) / p.unit_tiles > p.units.size())
        throw std::invalid_argument(
            "functional_l1_misses: the profile's units do not cover its tiles");
    // One tag array for every core's cache (and a split L1's two): core c's set s of cache
    // kind k is set (c * kinds + k) * sets + s.
    const uint64_t kinds = split ? 2 : 1, set_mask = sets - 1;
    LruTags tags(cores * kinds * sets, ways);
    // Expected distinct cores among r rays, for r up to the profile's cap.
    std::vector<double> spread(kTileLineRays + 1, 0.0);
    for (uint32_t r = 1; r <= kTileLineRays; ++r)
        spread[r] = double(cores) * (1.0 - std::pow(1.0 - 1.0 / double(cores), double(r)));
    uint64_t state = 0x9e3779b97f4a7c15ULL;  // a fixed stream: the count is deterministic
    auto draw = [&state] {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        return state * 0x2545f4914f6cdd1dULL;
    };
    uint64_t accesses = 0;
    for (size_t t = 0; t < tiles; ++t) {
        uint32_t& unit = out.unit_misses[t / p.unit_tiles];
        for (uint32_t i = p.tile_line_start[t]; i < p.tile_line_start[t + 1]; ++i) {
            const uint32_t line = p.tile_lines[i];
            const uint8_t info = p.tile_line_info[i];
            const double expected = spread[info & kTileLineRays];
            const uint64_t r = draw();
            // Rounded up with the probability of its fraction: the right count on average.
            uint64_t fetching = uint64_t(expected);
            if (double(r >> 11) * 0x1.0p-53 < expected - double(fetching)) ++fetching;
            const uint64_t kind = split && (info & kTileLineTriangle) ? 1 : 0;
            uint64_t core = (r >> 32) % cores;
            for (uint64_t c = 0; c < fetching; ++c) {
                const uint64_t set = (core * kinds + kind) * sets + (line & set_mask);
                if (!tags.access(set, line)) ++unit;
                core = core + 1 == cores ? 0 : core + 1;
            }
            accesses += fetching;
            // The tags' use stamps count accesses: a frame with more gets no count.
            if (accesses >= UINT32_MAX) {
                out.unit_misses.clear();
                return out;
            }
        }
    }
    for (uint32_t m : out.unit_misses) out.misses += m;
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return out;
}

namespace {

constexpr char kMagic[8] = {'R', 'T', 'S', 'L', '2', 'M', 'S', '1'};

std::string serialize(const FunctionalL2& f, const std::string& key) {
    CacheEntryWriter w(kMagic);
    w.key(key);
    w.pod(f.misses);
    w.pod(f.capacity_misses);
    w.vec(f.unit_capacity_misses);
    return w.finish();
}

FunctionalL2 deserialize(std::string_view bytes, const std::string& key, size_t units) {
    CacheEntryReader r =
        open_cache_entry(bytes, kMagic, "not an L2 miss count", "checksum mismatch");
    r.expect_key(key);
    FunctionalL2 f;
    f.misses = r.pod<uint64_t>();
    f.capacity_misses = r.pod<uint64_t>();
    r.vec(f.unit_capacity_misses);
    if (!r.done()) throw CacheEntryUnusable{"trailing bytes"};
    if (f.unit_capacity_misses.size() != units || f.capacity_misses > f.misses ||
        std::accumulate(f.unit_capacity_misses.begin(), f.unit_capacity_misses.end(),
                        uint64_t(0)) != f.capacity_misses)
        throw CacheEntryUnusable{"inconsistent contents"};
    return f;
}

}  // namespace

FunctionalL2 functional_l2_misses_cached(const FrameProfile& p, uint64_t sets, uint32_t ways,
                                         const std::string& dir) {
    if (dir.empty() || p.key.empty()) return functional_l2_misses(p, sets, ways);
    const auto start = std::chrono::steady_clock::now();
    const std::string key = fmt::format("{} l2 sets={} ways={} {}", p.key, sets, ways,
                                        std::string(kMagic, sizeof kMagic));
    const std::string path =
        (std::filesystem::path(dir) /
         fmt::format("l2misses-{:016x}.bin", fnv1a(kFnvOffset, key.data(), key.size())))
            .string();
    std::string outcome;
    FunctionalL2 f = through_cache_entry(
        path,
        [&](std::string_view bytes, const std::shared_ptr<const void>&) {
            return deserialize(bytes, key, p.units.size());
        },
        [&] { return functional_l2_misses(p, sets, ways); },
        [&](const FunctionalL2& built) { return serialize(built, key); }, "L2 miss count", outcome);
    f.cache = outcome;
    f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return f;
}

}  // namespace rtsim

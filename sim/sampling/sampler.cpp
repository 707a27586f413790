#include "sim/sampling/sampler.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <random>

#include "models/cache.h"
#include "sim/sampling/estimators.h"
#include "sim/sampling/reference.h"
#include "workloads/error.h"

namespace rtsim {

using nlohmann::json;

SampleDesign::SampleDesign(const SamplingParams& params) : params_(params) {
    std::mt19937_64 rng(params_.seed ^ 0x5a3b1e5d);
    first_unit_ = params_.first_unit >= 0
                      ? uint64_t(params_.first_unit) % params_.period_units
                      : std::uniform_int_distribution<uint64_t>(0, params_.period_units - 1)(rng);
    if (!params_.skip || params_.tiles == 0) return;
    if (params_.by_work) draw_by_work();
    if (!params_.unit_order.empty()) {
        if (params_.unit_order.size() != units())
            throw std::invalid_argument("SampleDesign: unit_order does not list the frame's units");
        rank_.assign(units(), ~uint32_t(0));
        for (size_t k = 0; k < params_.unit_order.size(); ++k) {
            const uint32_t u = params_.unit_order[k];
            if (u >= rank_.size() || rank_[u] != ~uint32_t(0))
                throw std::invalid_argument("SampleDesign: unit_order is not a permutation");
            rank_[u] = uint32_t(k);
        }
    }
    // Every tile's role, strongest first: a measured unit's tiles, the tile whose first ray
    // closes it, then going back from each measured unit its detailed warm-up (warmup_tiles,
    // and on until it holds warmup_tile_rays rays when tile_rays is known) and before that the
    // functionally warmed tiles. A measured unit without rays (tile_rays known) takes no cycles
    // whatever came before, has nothing to close and needs no warm-up, and a warm-up reaches back
    // through it as through any tile without rays: in the full run the rays before and after it
    // follow each other through the slots (1080p camel diffuse, 1 in 20, seed 2: a warm-up that
    // stopped at such a unit left the next measured unit 20% short of its L2 misses).
    const uint64_t per = params_.unit_tiles, tiles = params_.tiles;
    const bool by_rays = params_.tile_rays.size() == tiles;
    const bool by_work = params_.tile_work.size() == tiles;
    auto unit_end = [&](uint64_t u) { return std::min(tiles, (u + 1) * per); };
    auto has_rays = [&](uint64_t u) {
        return !by_rays || std::any_of(params_.tile_rays.begin() + long(u * per),
                                       params_.tile_rays.begin() + long(unit_end(u)),
                                       [](uint32_t r) { return r > 0; });
    };
    roles_.assign(tiles, TileRole::Skipped);
    std::vector<uint8_t> measured_with_rays(units(), 0);
    for (uint64_t u = 0; u < units(); ++u) {
        if (!measured_unit(u)) continue;
        measured_with_rays[u] = has_rays(u);
        std::fill(roles_.begin() + long(u * per), roles_.begin() + long(unit_end(u)),
                  TileRole::Measured);
        if (measured_with_rays[u] && (u + 1) * per < tiles && !measured_unit(u + 1))
            roles_[(u + 1) * per] = TileRole::After;
    }
    for (uint64_t u = 0; u < units(); ++u) {
        if (!measured_with_rays[u]) continue;
        uint64_t t = u * per, back = 0, rays = 0, work = 0, warming = 0;
        while (t > 0) {
            const bool warmup = back < params_.warmup_tiles ||
                                (by_rays && rays < params_.warmup_tile_rays) ||
                                (by_work && work < params_.warmup_work);
            if (!warmup && warming >= params_.warm_tiles) break;
            TileRole& r = roles_[--t];
            // No further back than an earlier unit with rays, measured or closed. A warm-up that
            // reaches the tile closing one runs all of it: the two windows are one, the chip never
            // runs short of rays between them, and nothing waits for a drain (which, after the
            // closing tile's other rays were skipped, started a warm-up of less than a slot fill
            // on an empty chip: on 64 x 32 cores the next measured unit's rays then went out at
            // once, and one such unit took 2,241 cycles against 6,024 in the full run).
            if (r == TileRole::After) {
                r = TileRole::Warmup;
                break;
            }
            if (r == TileRole::Measured && measured_with_rays[t / per]) break;
            ++back;
            if (by_rays) rays += params_.tile_rays[t];
            if (by_work) work += params_.tile_work[t];
            if (r == TileRole::Measured) continue;  // a unit without rays: traced anyway
            if (warmup) {
                r = TileRole::Warmup;
            } else {
                if (r == TileRole::Skipped) r = TileRole::Warming;
                ++warming;
            }
        }
    }
}

uint64_t SampleDesign::pick(uint64_t stratum) const {
    uint64_t size = params_.period_units;
    // The skip design knows the frame's units: a last, shorter stratum draws among the units it
    // has (the expansion needs a measured unit in every stratum).
    if (params_.skip) size = std::min(size, units() - stratum * params_.period_units);
    return draw(stratum, size);
}

void SampleDesign::draw_by_work() {
    const std::vector<uint64_t>& work = params_.unit_work;
    if (work.size() != units())
        throw std::invalid_argument("SampleDesign: unit_work does not list the frame's units");
    measured_.assign(units(), 0);
    certainty_.assign(units(), 0);
    design_weight_.assign(units(), 0.0);
    auto take = [&](uint32_t u) {
        certainty_[u] = measured_[u] = 1;
        design_weight_[u] = 1.0;
        ++certainty_count_;
    };
    // The start-up units: the frame's first units with work, until their rays have filled the
    // chip's slots params_.startup_rays / slots times. The full run starts them on an empty chip
    // with cold caches, and their cycles hold the pipeline's fill and the compulsory misses
    // before the rays' flow settles, which no auxiliary predicts: on 4 of 7 tuning frames (camel
    // diffuse, homer 2-bounce, elephant and hand AO, 1024x768) the first one or two units with
    // work held 15-69% of the squared residuals of a fit on work among 270-487 units, and a
    // sample that drew none of them read low inside a narrow interval. A sampled run starts them
    // exactly as the full run does, with nothing before them to warm, so they are measured
    // outright, besides the units the period asks for.
    uint64_t active_units = 0;
    for (uint32_t u = 0; u < units(); ++u) active_units += work[u] > 0;
    if (params_.startup_rays > 0 && params_.unit_ray_counts.size() == units()) {
        uint64_t rays = 0;
        for (uint32_t u = 0; u < units() && rays < params_.startup_rays; ++u)
            if (work[u] > 0) {
                take(u);
                rays += params_.unit_ray_counts[u];
            }
    }
    // The units with work left to draw, heaviest first (ties by unit).
    std::vector<uint32_t> active;
    uint64_t remaining_work = 0;
    for (uint32_t u = 0; u < units(); ++u)
        if (work[u] > 0 && !certainty_[u]) {
            active.push_back(u);
            remaining_work += work[u];
        }
    if (active.empty()) return;
    std::sort(active.begin(), active.end(), [&](uint32_t a, uint32_t b) {
        return work[a] != work[b] ? work[a] > work[b] : a < b;
    });
    // The sample's size: one unit in period_units of those with work, at least 2.
    const uint64_t budget = std::min<uint64_t>(
        active.size(),
        std::max<uint64_t>(2, (active_units + params_.period_units - 1) / params_.period_units));
    // Certainty units: a unit whose work is at least the mean work per unit left to draw
    // (what a draw in proportion to work would take for sure) is measured outright, heaviest
    // first, the threshold recomputed as they leave; at most half the sample, so that the rest
    // is drawn. A frame whose cycles sit in a few units (1024x768 fandisk diffuse: 144 of 3,072
    // units hold 86%) then measures them instead of extrapolating to them.
    size_t c = 0;
    while (c < active.size() && c < budget / 2 &&
           double(work[active[c]]) * double(budget - c) >= double(remaining_work)) {
        take(active[c]);
        remaining_work -= work[active[c]];
        ++c;
    }
    // The rest, lightest first, cut into strata of equal work, one unit drawn in each: the
    // sample spans the frame's range of work, and draws fall where the work (and so the
    // spread of cycles) is rather than among the many light units. A unit stands for its
    // stratum (its design weight is the stratum's size). Equal-count strata on the recorded
    // fandisk frame, 1 in 10, gave 9.2% mean error offline against 5.1% for equal work.
    std::vector<uint32_t> rest(active.begin() + long(c), active.end());
    std::reverse(rest.begin(), rest.end());
    drawn_population_ = rest.size();
    if (rest.empty()) return;
    const uint64_t draws = std::max<uint64_t>(1, budget - c);
    uint64_t begin = 0, done_work = 0;
    for (uint64_t s = 0; begin < rest.size(); ++s) {
        // Up to the unit where the work so far reaches the next share of the rest's, leaving a
        // unit for each draw after this one: many light units share a stratum, and cut at equal
        // work alone the strata could number fewer than the draws, a smaller sample than asked
        // (1 in 1 of a 1080p bunny frame left 95 of its 1,188 units with work unmeasured).
        uint64_t end = begin;
        const double target = double(remaining_work) * double(s + 1) / double(draws);
        const uint64_t keep = draws - (s + 1);  // s + 1 == draws takes the rest
        while (end < rest.size() &&
               (end == begin || s + 1 == draws ||
                (double(done_work + work[rest[end]]) <= target && rest.size() - end > keep))) {
            done_work += work[rest[end]];
            ++end;
        }
        const uint64_t size = end - begin;
        for (uint64_t k = begin; k < end; ++k) design_weight_[rest[k]] = double(size);
        measured_[rest[begin + draw(s, size)]] = 1;
        ++drawn_strata_;
        begin = end;
    }
}

uint64_t SampleDesign::draw(uint64_t stratum, uint64_t size) const {
    // splitmix64 of (seed, stratum): independent, uniform picks, the same for a seed.
    uint64_t z = (params_.seed ^ 0x9e3779b97f4a7c15ull) + stratum * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return z % std::max<uint64_t>(1, size);
}

bool SampleDesign::measured_unit(uint64_t unit) const {
    if (params_.by_work) return unit < measured_.size() && measured_[unit];
    const uint64_t k = rank_.empty() || unit >= rank_.size() ? unit : rank_[unit];
    return k % params_.period_units ==
           (params_.stratified ? pick(k / params_.period_units) : first_unit_);
}

uint64_t SampleDesign::first_unit() const {
    if (params_.by_work) {
        const auto it = std::find(measured_.begin(), measured_.end(), 1);
        return it == measured_.end() ? 0 : uint64_t(it - measured_.begin());
    }
    const uint64_t k = params_.stratified ? pick(0) : first_unit_;
    return rank_.empty() || k >= params_.unit_order.size() ? k : params_.unit_order[k];
}

SampleDesign::TileRole SampleDesign::tile_role(uint64_t tile) const {
    return tile < roles_.size() ? roles_[tile] : TileRole::Skipped;  // past the frame
}

Sampler::Sampler(const SamplingParams& params,
                 std::vector<std::array<MemoryPort*, kStepKinds>> ports,
                 const StatsRegistry& counters, std::shared_ptr<const SampleDesign> design)
    : design_(design ? std::move(design) : std::make_shared<const SampleDesign>(params)),
      params_(design_->params()),
      ports_(std::move(ports)),
      counters_(counters) {
    deltas_.resize(counters_.entries().size());
}

bool Sampler::detailed_ray(uint64_t i) const {
    const uint64_t unit = i / params_.unit_rays;
    if (measured_unit(unit)) return true;
    // The ray right after a measured unit: its hand-out closes the unit.
    if (i % params_.unit_rays == 0 && unit > 0 && measured_unit(unit - 1)) return true;
    // The warm-up before the next measured unit.
    const uint64_t next_start = (i / params_.unit_rays + 1) * params_.unit_rays;
    return measured_unit(unit + 1) && next_start - i <= params_.warmup_rays;
}

void Sampler::set_caches(const Cache& l1, const Cache& l2, uint64_t dram_bytes_per_fill) {
    const CacheParams &p1 = l1.params(), &p2 = l2.params();
    l2_line_bytes_ = p2.line_bytes;
    dram_bytes_per_fill_ = dram_bytes_per_fill;
    l1_lines_ = p1.size_bytes / p1.line_bytes;
    // A prefetcher brings lines no demand touched: the replay's LRU shortcuts (a line's state
    // depends only on its last touch) and its direct tag checks then do not hold, and the
    // replay goes through each cache's warm(), which prefetches as a miss does.
    prefetching_ = l1.prefetching() || l2.prefetching();
    l1_lru_ = p1.replacement == "lru" && !prefetching_;
    l2_lru_ = p2.replacement == "lru" && !prefetching_;
    l1_fetch_lines_ = LineTracker(0, 0, p1.line_bytes);
    l2_sets_ = p2.sets();
    l2_ways_ = uint32_t(p2.ways);
    l1_sets_ = p1.sets();
    l1_ways_ = uint32_t(p1.ways);
}

std::unique_ptr<Sampler> make_sampler(const std::string& fast_forward, const SamplingParams& params,
                                      const SampledChip& chip, const SampledFrame& frame) {
    return FastForwardRegistry::at(fast_forward).make(params, chip, frame);
}

void Sampler::set_line_range(uint64_t base, uint64_t end, uint32_t line_bytes) {
    lines_ = LineTracker(base, end, line_bytes);
}

void Sampler::set_profile(const FrameProfile* profile, Cache* l2, const std::string& cache_dir) {
    profile_ = profile;
    l2_ = l2;
    // The direct route: each line is one tag check per level, not a chain of warm() calls
    // through the sockets (the replay is a quarter of a 1-in-50 primary frame's main thread).
    const uint32_t line_bytes = profile->line_bytes;
    bool direct = !prefetching_ && l2 && l2->params().line_bytes == line_bytes && line_bytes > 0 &&
                  profile->line_base % line_bytes == 0 && !ports_.empty() &&
                  l1s_over_l2_.size() == ports_.size();
    for (size_t c = 0; direct && c < ports_.size(); ++c)
        for (size_t k = 0; direct && k < kStepKinds; ++k)
            direct = l1s_over_l2_[c][k] && l1s_over_l2_[c][k]->params().line_bytes == line_bytes;
    if (direct) {
        direct_l1_ = l1s_over_l2_;
        direct_l2_ = l2;
        direct_first_line_ = profile->line_base / line_bytes;
    }
    const auto& lines = profile->tile_lines;
    const size_t distinct = lines.empty() ? 0 : *std::max_element(lines.begin(), lines.end()) + 1;
    line_pass_.resize(distinct);
    // Started small, the table grows to what the windows meet. Sized for the most a window can
    // meet (what the L1s hold together: the default chip's, 4,352 lines in 16,384 slots, 256 KB),
    // its slots missed the host's caches, and half of the window's search was that one load
    // (1080p camel primary at 1 in 50, 15 runs: its median 2.32 ms, 1.57 ms grown from 512
    // slots; a window there walks about a thousand line entries).
    if (l1_lru_ && ports_.size() <= CoreLinePass::kMaxCores) core_line_pass_.reserve(256);
    // A reference design's matched sample already carries its capacity misses (section 10 of
    // docs/sampling.md); other replacement policies would need their own
    // functional model.
    if (!reference_ && l2_lru_ && l2_sets_ > 0 && l2_ways_ > 0 &&
        profile->line_bytes == l2_line_bytes_)
        functional_l2_pending_ =
            std::async(std::launch::async, [profile, sets = l2_sets_, ways = l2_ways_, cache_dir] {
                return functional_l2_misses_cached(*profile, sets, ways, cache_dir);
            });
    if (!reference_ && l1_sets_ > 0 && l1_ways_ > 0 &&
        profile->line_bytes == l1_fetch_lines_.line_bytes() && !ports_.empty()) {
        const bool split =
            ports_[0][size_t(StepKind::Node)] != ports_[0][size_t(StepKind::Triangle)];
        functional_l1_pending_ =
            std::async(std::launch::async,
                       [profile, cores = ports_.size(), sets = l1_sets_, ways = l1_ways_, split] {
                           return functional_l1_misses(*profile, cores, sets, ways, split);
                       });
    }
}

double Sampler::wait_functional_l2() {
    if (functional_l2_pending_.valid()) functional_l2_ = functional_l2_pending_.get();
    if (functional_l1_pending_.valid()) functional_l1_ = functional_l1_pending_.get();
    return functional_l2_.seconds;
}

void Sampler::replay_skipped_tiles(uint64_t tile) {
    if (profile_ && l2_ && tile > replayed_tiles_) {
        const auto start = std::chrono::steady_clock::now();
        const FrameProfile& p = *profile_;
        const uint64_t last = std::min<uint64_t>(tile, p.tile_line_start.size() - 1);
        const uint32_t end = p.tile_line_start[last];
        const size_t cores = ports_.size();
        // Only the tiles just before this one can still have lines in an L1: going back, the
        // L1s together take in what they hold, then earlier tiles' lines go straight into
        // the L2 (as they would through the L1s, which miss them by then; a line an L1 would
        // still have held refreshes the L2 too, which measured the same on bunny and Cornell
        // frames), at a warm per line instead of one per core that fetched it. A line counts
        // once: tile after tile touches the top of the tree again, which evicts nothing (counted
        // at every touch, the window ended too soon where tiles between are background: 1080p
        // elephant primary's measured units missed their L1s 23-41% more often than the same
        // units in the full run, and took 0.5-1.2% more cycles; counted once, within -2% to +2%
        // and -0.1% to +0.8%). A window of twice what the L1s hold measured the same (1080p bunny
        // primary and armadillo AO, 1 in 10, 5 seeds: the measured units' cycles against the
        // full run's +0.51% and -0.50%, against +0.42% and -0.42% with this one; 8 times: +0.50%
        // and -0.52%; 24 frames at 1 in 20, 100 seeds: cycles' mean error 1.80% and 1.79%,
        // coverage 92.3% and 92.6%, DRAM bytes' 0.93% both) and made a 1-in-20 run 1.12x slower.
        // The cores share a tile's rays: a line that n of them fetched is in n cores' L1s (all
        // of them for the top of the tree), a line one ray fetched in one, in turn.
        // An LRU L2 direct behind the L1s ends in the state of its lines' last touches, wherever
        // they come from: the L1s' misses are gathered and loaded after the window, each line
        // once, behind the lines before the window that they do not touch again. (The cores
        // share the window's lines: 1080p bunny primary at 1 in 50 made 293k L1 misses in its
        // windows, 42k of them distinct per window.) The L1s hold no dirty line that could
        // write into the L2 in between: writes go to the level below them.
        const bool defer_l2 = direct_l2_ && l2_lru_;
        l1_misses_.clear();
        if (first_demands_)
            for (uint32_t i = p.tile_line_start[replayed_tiles_]; i < end; ++i)
                first_demands_->touch(p.line_base + uint64_t(p.tile_lines[i]) * p.line_bytes,
                                      false);
        auto rays_of = [&](uint32_t i) {
            return std::min<size_t>(p.tile_line_info[i] & kTileLineRays, cores);
        };
        auto warm = [&](uint32_t i, size_t core) {
            const auto kind = size_t((p.tile_line_info[i] & kTileLineTriangle) ? StepKind::Triangle
                                                                               : StepKind::Node);
            if (direct_l2_) {
                if (!direct_l1_[core][kind]->warm_line(direct_first_line_ + p.tile_lines[i])) {
                    if (defer_l2)
                        l1_misses_.push_back(i);
                    else
                        warm_l2_line(i);
                }
                return;
            }
            ports_[core][kind]->warm(p.line_base + uint64_t(p.tile_lines[i]) * p.line_bytes,
                                     p.line_bytes);
        };
        const uint64_t budget_limit = l1_lines_ * cores;  // l1_lines_ 0: no limit
        uint64_t through_l1 = last;
        if (!core_line_pass_.enabled() || cores == 0) {
            line_pass_.next();
            for (uint64_t budget = 0;
                 through_l1 > replayed_tiles_ && (l1_lines_ == 0 || budget < budget_limit);) {
                --through_l1;
                for (uint32_t i = p.tile_line_start[through_l1];
                     i < p.tile_line_start[through_l1 + 1]; ++i)
                    if (line_pass_.first(p.tile_lines[i])) budget += rays_of(i);
            }
            const uint32_t l1_from = cores == 0 ? end : p.tile_line_start[through_l1];
            if (!defer_l2) warm_l2_lines(p.tile_line_start[replayed_tiles_], l1_from);
            for (uint32_t i = l1_from; i < end; ++i) {
                const size_t n = rays_of(i);
                for (size_t j = 0; j < n; ++j) warm(i, (replay_core_ + j) % cores);
                replay_core_ = (replay_core_ + n) % cores;
            }
            if (defer_l2) warm_l2_lines(p.tile_line_start[replayed_tiles_], l1_from, l1_misses_);
        } else {
            // An LRU L1 ends in the state its lines' last touches leave, as the L2 does
            // (warm_l2_lines), and the lines it held before leave it as the window's distinct
            // lines push them out: each (core, line) is warmed once, at its last touch, found
            // going back from the window's end (the cores taken in the same turn). The top of the
            // tree comes back tile after tile: 1080p bunny primary at 1 in 50 made 925k L1 warms,
            // 368k of them last touches. The L2 sees the L1s' misses at their last touches.
            // One pass back finds the window and its last touches together: cores are counted
            // from the window's end (0 the core after its last warm, unknown until the window is
            // found; turning every core by the same amount changes no set of cores met).
            core_line_pass_.next();
            l1_last_touches_.clear();
            auto ones = [](size_t k) { return k >= 64 ? ~uint64_t(0) : (uint64_t(1) << k) - 1; };
            size_t from = 0;  // the first core of the entry in turn, counted from the end
            for (uint64_t budget = 0;
                 through_l1 > replayed_tiles_ && (l1_lines_ == 0 || budget < budget_limit);) {
                --through_l1;
                const uint32_t tile_start = p.tile_line_start[through_l1];
                for (uint32_t i = p.tile_line_start[through_l1 + 1]; i-- > tile_start;) {
                    const size_t n = rays_of(i);  // at most `cores`
                    // from - n, modulo cores, without a division (two per line took a fifth of
                    // this loop's time).
                    from += (n == cores ? 0 : cores - n);
                    if (from >= cores) from -= cores;
                    // The cores from, from + 1, ... n of them, wrapping past the last.
                    const size_t below_end = std::min(n, cores - from);
                    const uint64_t wrapped = ones(n - below_end);
                    const uint64_t turn = ones(below_end) << from | wrapped;
                    bool new_line = false;
                    const uint64_t fresh = core_line_pass_.first(p.tile_lines[i], turn, new_line);
                    if (new_line) budget += n;
                    // Most entries (the top of the tree, tile after tile) meet no core anew.
                    if (fresh == 0) continue;
                    // Later cores of the turn first (they come after in the warm order): the
                    // wrapped ones, then the others.
                    auto last_touches = [&](uint64_t bits) {
                        while (bits != 0) {
                            const int core = 63 - __builtin_clzll(bits);
                            bits &= ~(uint64_t(1) << core);
                            l1_last_touches_.emplace_back(i, uint32_t(core));
                        }
                    };
                    last_touches(fresh & wrapped);
                    last_touches(fresh & ~wrapped);
                }
            }
            const uint32_t l1_from = p.tile_line_start[through_l1];
            if (!defer_l2) warm_l2_lines(p.tile_line_start[replayed_tiles_], l1_from);
            // The core after the window's last warm: replay_core_ plus the window's rays.
            const size_t next_core = (replay_core_ + (cores - from) % cores) % cores;
            for (auto w = l1_last_touches_.rbegin(); w != l1_last_touches_.rend(); ++w) {
                const size_t core = w->second + next_core;
                warm(w->first, core >= cores ? core - cores : core);
            }
            replay_core_ = next_core;
            if (defer_l2) warm_l2_lines(p.tile_line_start[replayed_tiles_], l1_from, l1_misses_);
        }
        replay_seconds_ +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    replayed_tiles_ = tile + 1;
}

// Tile line entry i into the L2, as l2_->warm() would put it there.
void Sampler::warm_l2_line(uint32_t i) {
    const FrameProfile& p = *profile_;
    const uint64_t addr = p.line_base + uint64_t(p.tile_lines[i]) * p.line_bytes;
    if (!direct_l2_) {
        l2_->warm(addr, p.line_bytes);
    } else if (!direct_l2_->warm_line(direct_first_line_ + p.tile_lines[i])) {
        direct_l2_->warm_below(addr);
    }
}

void Sampler::warm_l2_lines(uint32_t from, uint32_t to, const std::vector<uint32_t>& then) {
    auto warm = [&](uint32_t i) { warm_l2_line(i); };
    if (!l2_lru_) {
        for (uint32_t i = from; i < to; ++i) warm(i);
        for (const uint32_t i : then) warm(i);
        return;
    }
    // An LRU cache ends in the same state whatever came before each line's last touch (a set
    // holds its most recently touched lines, in that order), so only last touches are loaded, in
    // their order: a Cornell 2-bounce path frame at 1 in 100 replays about 5 million tile lines,
    // a few tens of thousands of them distinct.
    line_pass_.next();
    last_touches_.clear();
    for (auto i = then.rbegin(); i != then.rend(); ++i)
        if (line_pass_.first(profile_->tile_lines[*i])) last_touches_.push_back(*i);
    for (uint32_t i = to; i-- > from;)
        if (line_pass_.first(profile_->tile_lines[i])) last_touches_.push_back(i);
    for (auto i = last_touches_.rbegin(); i != last_touches_.rend(); ++i) warm(*i);
}

bool Sampler::fast_forward(const RayWork& work, int64_t tile) {
    current_ = index_;
    index_ += work.rays;
    bool detailed;
    if (params_.skip) {
        const uint64_t t = uint64_t(std::max<int64_t>(tile, 0));
        const uint64_t unit = t / params_.unit_tiles;
        const bool new_tile = tile != last_tile_;
        tiles_traced_ += new_tile;
        // Tiles of a unit come together; a warming unit may start part-way.
        current_first_ = last_tile_ < 0 || unit != current_unit_;
        current_unit_ = unit;
        // Tiles not traced between the last one and this, with rays (known ray counts), were
        // skipped: the window before is over.
        if (new_tile && !gap_) {
            const uint64_t from = uint64_t(last_tile_ + 1);
            if (params_.tile_rays.size() != params_.tiles) {
                gap_ = t > from;
            } else {
                for (uint64_t k = from; k < t && !gap_; ++k) gap_ = params_.tile_rays[k] > 0;
            }
        }
        // The tiles skipped since the last traced one, each its unit's share by rays (their work
        // is known only per unit).
        if (new_tile && profile_)
            for (uint64_t k = uint64_t(last_tile_ + 1); k < t; ++k) {
                const uint64_t u = k / params_.unit_tiles;
                if (u >= profile_->units.size()) break;
                const AuxFigures& unit = profile_->units[u];
                const double share = unit[kAuxRays] > 0 && k < profile_->tile_rays.size()
                                         ? double(profile_->tile_rays[k]) / double(unit[kAuxRays])
                                         : 0.0;
                add_skipped(unit, 1.0 / double(params_.unit_tiles), share);
            }
        last_tile_ = tile;
        // The tiles skipped since the last traced one fetched their first lines before it.
        if (new_tile) replay_skipped_tiles(t);
        using Role = SampleDesign::TileRole;
        const Role role = design_->tile_role(t);
        detailed =
            role == Role::Measured || role == Role::Warmup || (role == Role::After && new_tile);
    } else {
        current_unit_ = current_ / params_.unit_rays;
        current_first_ = current_ % params_.unit_rays == 0;
        detailed = detailed_ray(current_);
    }
    Aux& a = current_aux_;
    a = ray_auxiliaries(work, lines_);
    for (size_t k = 0; k < kAuxiliaries; ++k) total_aux_[k] += a[k];
    uint64_t fetch_lines = 0, fetch_bytes = 0;
    // The skip design's frame totals are the profile's: only its detailed rays are counted.
    if (detailed || !params_.skip) {
        for (const Step& s : work.steps) {
            fetch_lines += l1_fetch_lines_.lines_spanned(s);
            fetch_bytes += s.size_bytes;
        }
        total_fetch_lines_ += fetch_lines;
        total_fetch_bytes_ += fetch_bytes;
    }
    window_start_ = detailed && gap_;
    if (detailed) {
        if (window_start_) window_skipped_terms_ = skipped_terms_;
        skipped_terms_.fill(0.0);
        gap_ = false;
        detailed_ += work.rays;
        for (size_t k = 0; k < kAuxiliaries; ++k) detailed_aux_[k] += a[k];
        detailed_fetch_lines_ += fetch_lines;
        detailed_fetch_bytes_ += fetch_bytes;
        return false;
    }
    // A ray of a unit not skipped whole: its share of the unit count (the skip design's units
    // are tiles, counted as skipped above).
    add_skipped(a, params_.skip ? 0.0 : double(work.rays) / double(params_.unit_rays));
    if (!ports_.empty()) {
        const auto& mem = ports_[next_core_];
        for (const Step& s : work.steps) mem[size_t(s.kind)]->warm(s.addr, s.size_bytes);
        if (next_core_ < write_cores_.size()) warm_writes(*write_cores_[next_core_], work);
        next_core_ = (next_core_ + 1) % ports_.size();
    }
    gap_ = true;
    return true;
}

void Sampler::warm_writes(const Core& core, const RayWork& work) const {
    const CoreParams& p = core.params();
    if (!core.has_local_memory()) return;
    if (p.short_stack_entries > 0) {
        ShortStack stack(p.short_stack_entries);
        for (const Step& s : work.steps) {
            const StackTraffic t = stack.before(s);
            if (t.spill_entries)
                core.warm_local(core.stack_address(0, t.spill_from),
                                t.spill_entries * p.stack_entry_bytes, true);
            if (t.refill_entries)
                core.warm_local(core.stack_address(0, t.refill_from),
                                t.refill_entries * p.stack_entry_bytes, false);
        }
    }
    if (p.hit_record_bytes > 0)
        core.warm_local(core.hit_record_address(work.ray_id), p.hit_record_bytes * work.rays, true);
}

void Sampler::handed_out(Cycle now) {
    last_handout_ = std::max(last_handout_, now);
    const uint64_t unit = current_unit_;
    const bool first_of_unit = current_first_;
    // The ray after the measured unit closes it.
    if (open_ && (unit != open_unit_)) close_unit(unit_aux_, now);
    if (first_of_unit && measured_unit(unit)) {
        open_ = true;
        open_unit_ = unit;
        open_cycle_ = now;
        const auto& e = counters_.entries();
        open_counts_.resize(e.size());
        for (size_t c = 0; c < e.size(); ++c) open_counts_[c] = *e[c].value;
        unit_aux_.fill(0);
    }
    if (open_)
        for (size_t k = 0; k < kAuxiliaries; ++k) unit_aux_[k] += current_aux_[k];
}

SkippedCyclesFit::Terms SkippedCyclesFit::terms(const AuxFigures& aux, double units, double share) {
    return {units, share * double(aux[kAuxWork]), share * double(aux[kAuxNewLines]),
            share * double(aux[kAuxRays])};
}

void SkippedCyclesFit::add(const Terms& x, double y) {
    for (size_t i = 0; i < kTerms; ++i) {
        for (size_t j = 0; j < kTerms; ++j) xtx[i][j] += x[i] * x[j];
        xty[i] += x[i] * y;
    }
}

double SkippedCyclesFit::predict(const Terms& x) const {
    // Measured units enter with a count term of 1: the sums of 1, work and cycles over them are
    // in the normal equations' first row.
    const double units = xtx[0][0], work = xtx[0][1], cycles = xty[0];
    if (units == 0) return 0.0;
    if (units < double(2 * kTerms))
        return std::max(0.0, work > 0 ? cycles / work * x[1] : cycles / units * x[0]);
    // Scaled to unit diagonal (a term no unit carries, such as new lines where none are
    // counted, has a zero coefficient), with a small ridge so that collinear terms (rays and
    // the count where every unit has as many rays) share their coefficient instead of failing.
    Terms scale{};
    for (size_t i = 0; i < kTerms; ++i) scale[i] = xtx[i][i] > 0 ? std::sqrt(xtx[i][i]) : 0.0;
    std::vector<double> m(kTerms * kTerms, 0.0), v(kTerms, 0.0), beta;
    for (size_t i = 0; i < kTerms; ++i) {
        for (size_t j = 0; j < kTerms; ++j)
            if (scale[i] > 0 && scale[j] > 0) m[i * kTerms + j] = xtx[i][j] / (scale[i] * scale[j]);
        m[i * kTerms + i] += 1e-6 + (scale[i] > 0 ? 0.0 : 1.0);
        v[i] = scale[i] > 0 ? xty[i] / scale[i] : 0.0;
    }
    if (!solve_small(std::move(m), std::move(v), beta)) return 0.0;
    double y = 0;
    for (size_t i = 0; i < kTerms; ++i)
        if (scale[i] > 0) y += beta[i] / scale[i] * x[i];
    return std::max(0.0, y);
}

double Sampler::window_hold_cycles() const {
    return hold_fit_.predict(window_skipped_terms_);
}

void Sampler::held(Cycle now) {
    if (open_ && current_unit_ != open_unit_) close_unit(unit_aux_, now);
}

void Sampler::finish() {
    if (!open_) return;
    // The frame ended inside a measured unit: it counts up to its last ray's hand-out (the
    // rays before that one; the drain after it is added separately).
    if (unit_aux_[kRays] > current_aux_[kRays]) {
        Aux before_last = unit_aux_;
        for (size_t k = 0; k < kAuxiliaries; ++k) before_last[k] -= current_aux_[k];
        close_unit(before_last, last_handout_);
    }
    open_ = false;
}

void Sampler::close_unit(const Aux& aux, Cycle end) {
    // The hold's fit takes the profile's figures where skipped tiles are known only by them.
    const Aux& known = params_.skip && profile_ && open_unit_ < profile_->units.size()
                           ? profile_->units[open_unit_]
                           : aux;
    hold_fit_.add(SkippedCyclesFit::terms(known, 1.0), double(end) - double(open_cycle_));
    for (size_t k = 0; k < kAuxiliaries; ++k) aux_[k].push_back(double(aux[k]));
    unit_index_.push_back(open_unit_);
    // Signed: cores take work within a horizon of each other, so hand-out cycles are not
    // strictly in order (differences telescope over the frame).
    cycles_.push_back(double(end) - double(open_cycle_));
    const auto& e = counters_.entries();
    for (size_t c = 0; c < e.size(); ++c)
        deltas_[c].push_back(double(*e[c].value - open_counts_[c]));
    open_ = false;
}

namespace {
bool matches(const std::string& n, const std::string& prefix, const std::string& suffix) {
    return n.size() >= prefix.size() + suffix.size() && n.compare(0, prefix.size(), prefix) == 0 &&
           n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0;
}
}  // namespace

json estimate_json(const Estimate& e, double scale, double offset) {
    const double v = e.value * scale + offset;
    const double hw = e.half_width * scale;
    json out = {{"value", v}};
    if (std::isfinite(hw)) {
        out.update({{"lo", v - hw},
                    {"hi", v + hw},
                    {"half_width_pct", v != 0 ? 100.0 * hw / std::abs(v) : 0.0}});
    } else {
        // No interval the data support: null bounds, and why.
        out.update({{"lo", nullptr}, {"hi", nullptr}, {"half_width_pct", nullptr}});
    }
    if (!e.caveat.empty()) out["caveat"] = e.caveat;
    return out;
}

double half_width_pct_of(const json& estimate) {
    const json& h = estimate.at("half_width_pct");
    return h.is_number() ? h.get<double>() : std::numeric_limits<double>::infinity();
}

json Sampler::counter_estimates(const TotalFn& total, double frame_first_fills,
                                const Auxiliary& capacity, uint64_t units, size_t drawn,
                                JointEstimates& joint) const {
    // Counters that move by a known amount per first fill of a BVH line in the L2 (its
    // compulsory misses, the most of a frame's DRAM traffic). The frame's first fills are its
    // distinct lines, known exactly, so only the rest (capacity misses, writes) is estimated:
    // total = per_fill * frame's first fills + the rest's regression total, from each measured
    // unit's change less per_fill * its first fills (both counted as the L2 met them, in the
    // same span). Regressing on the first fills as an auxiliary instead needed extreme weights
    // where a small object's lines are fetched first by few units, and dropped it.
    size_t fill_counters = 0;
    const std::vector<double> first_fills = unit_sums("l2.first_fills", "", &fill_counters);
    // Each counter's amount per fill, and whether its misses include capacity misses (all but
    // the first fills themselves).
    struct PerFill {
        const char* name;
        double per_fill;
        bool capacity;
    };
    const std::vector<PerFill> per_fill = {{"l2.first_fills", 1.0, false},
                                           {"l2.misses", 1.0, true},
                                           {"l2.fill_bytes", double(l2_line_bytes_), true},
                                           {"dram.bytes", double(dram_bytes_per_fill_), true}};
    // With the frame's capacity misses counted functionally (sim/sampling/functional_l2.h), those
    // too are known, and only the difference of the detailed model's from the functional count is
    // left to estimate: the known part is then per_fill * (first fills + capacity misses), the
    // measured units' functional capacity misses taken off their change with their first fills.
    // The regression on work alone left Cornell diffuse frames' DRAM bytes 5.7% off at 1 in 20
    // (docs/sampling.md).
    const double frame_capacity = capacity.x.empty() ? 0.0 : capacity.total;
    json counters = json::object();
    const auto& e = counters_.entries();
    for (size_t c = 0; c < e.size(); ++c) {
        double sum = 0;
        for (double d : deltas_[c]) sum += d;
        const auto known = std::find_if(per_fill.begin(), per_fill.end(),
                                        [&](const PerFill& p) { return p.name == e[c].name; });
        const bool per_fill_known = fill_counters == 1 && known != per_fill.end() &&
                                    known->per_fill != 0 && frame_first_fills > 0;
        // A counter that never moved in a measured unit is left out, unless the frame's part of
        // it is known: a 1-in-100 sample of a 1080p elephant primary frame whose 81 units fetched
        // no new line reported no DRAM bytes at all (and no DRAM energy) where the frame's first
        // fills alone were 99.9% of them.
        if (sum == 0 && !per_fill_known) continue;
        const std::string column = summed_counter_name(e[c].name);
        if (!per_fill_known) {
            Estimate est = total(deltas_[c], column, 0.0);
            counters[e[c].name] = estimate_json(est, 1.0);
            joint.add(e[c].name, std::move(est));
            continue;
        }
        const double k = known->per_fill;
        const bool with_capacity = known->capacity && frame_capacity > 0;
        std::vector<double> rest(deltas_[c].size());
        for (size_t u = 0; u < rest.size(); ++u)
            rest[u] = deltas_[c][u] - k * (first_fills[u] + (with_capacity ? capacity.x[u] : 0.0));
        Estimate est = total(rest, column, k);
        // Rare events (a capacity miss in a frame that nearly fits the L2) leave a sample that
        // saw none with no spread to show: the half-width is at least the rule of three's
        // bound (none in n units: up to 3 N / n in the frame's N, at 95%), each a line.
        const double rule_of_three = drawn == 0 ? 0.0 : k * 3.0 * double(units) / double(drawn);
        est.half_width = std::max(est.half_width, rule_of_three);
        const double frame_known = k * (frame_first_fills + (with_capacity ? frame_capacity : 0.0));
        est.value += frame_known;
        for (double& r : est.replicates) r += frame_known;
        counters[e[c].name] = estimate_json(est, 1.0);
        joint.add(e[c].name, std::move(est));
    }
    return counters;
}

// Informative units drawn (with work) from which the unit count is an auxiliary of the
// regression: kModelFloorDegrees residual degrees of freedom beyond the 7 auxiliaries a skip
// regression fits at most, where the jackknife alone sets the interval (Sampler::report).
constexpr size_t kUnitCountMinUnits = kModelFloorDegrees + 7;

json Sampler::report(Cycle end_cycle) {
    finish();
    wait_functional_l2();
    const bool skip = params_.skip;
    const uint64_t units =
        skip ? design_->units() : (index_ + params_.unit_rays - 1) / params_.unit_rays;
    if (skip) add_rayless_units(units);
    json out = {{"period_units", params_.period_units},
                {"design", params_.by_work      ? "work"
                           : params_.stratified ? "stratified"
                                                : "systematic"},
                {"first_unit", design_->first_unit()},
                {"units", units},
                {"units_measured", cycles_.size()},
                {"rays_detailed", detailed_},
                {"simulated_cycles", end_cycle},
                {"drain_cycles", end_cycle - last_handout_}};
    if (skip) {
        out.update({{"fast_forward", "skip"},
                    {"unit_tiles", params_.unit_tiles},
                    {"warm_tiles", params_.warm_tiles},
                    {"warmup_tiles", params_.warmup_tiles},
                    {"warmup_tile_rays", params_.warmup_tile_rays},
                    {"tiles", params_.tiles},
                    {"tiles_traced", tiles_traced_},
                    {"rays_traced", index_}});
        out["order"] = params_.unit_order.empty() ? json("frame")
                                                  : json({{"by", "cycles"},
                                                          {"then", "work per cycle"},
                                                          {"strata_per_group", kBalancedStrata},
                                                          {"of", params_.unit_order_of}});
    } else {
        out.update({{"unit_rays", params_.unit_rays},
                    {"warmup_rays", params_.warmup_rays},
                    {"work", total_aux_[kWork]},
                    {"rays", index_},
                    {"detailed_share", index_ ? double(detailed_) / double(index_) : 0.0}});
    }
    if (cycles_.size() < 2) {
        out["note"] = fmt::format(
            "fewer than 2 measured units: no estimates (a frame shorter than two "
            "sampling periods; lower sim.sample_period_units or sample_unit_{})",
            skip ? "tiles" : "rays");
        return out;
    }
    std::vector<Auxiliary> aux(kAuxiliaries);
    // Each auxiliary's column in sampled_units.csv, for the regression's totals in stats.json.
    std::vector<std::string> aux_names = {"work", skip ? "new_line_rays" : "new_lines",
                                          "node_steps", "rays"};
    if (skip) {
        // The units' auxiliaries come from the frame's profile (the skip run's own first
        // fetches are not the frame's), their totals too.
        for (size_t k = 0; k < kAuxiliaries; ++k) {
            aux[k].x.resize(cycles_.size());
            for (size_t i = 0; i < cycles_.size(); ++i)
                aux[k].x[i] = double(profile_->units[unit_index_[i]][k]);
            for (const Aux& u : profile_->units) aux[k].total += double(u[k]);
        }
        const double rays = aux[kRays].total;
        out["total_rays"] = rays;
        if (std::all_of(aux[kWork].x.begin(), aux[kWork].x.end(),
                        [](double x) { return x == 0; })) {
            // Every measured unit's tiles sent no ray (a 1-in-100 sample of a 1080p camel AO
            // frame measured 21 units of background): nothing to scale up.
            out["note"] =
                "no measured unit ran a ray (the sample missed every tile with work): no "
                "estimates; lower sim.sample_period_units";
            return out;
        }
        out["detailed_share"] = rays > 0 ? double(detailed_) / rays : 0.0;
        out["traced_share"] = rays > 0 ? double(index_) / rays : 0.0;
        out["profile"] = {{"seconds", profile_->seconds}, {"cache", profile_->cache}};
    } else {
        // The work the hand-out times span: all but the last ray's (whose hand-out ends the
        // span; the drain after it is measured).
        for (size_t k = 0; k < kAuxiliaries; ++k)
            aux[k] = {aux_[k], double(total_aux_[k] - current_aux_[k])};
    }
    const double frame_new_lines = aux[kNewLines].total;
    out["new_lines"] = frame_new_lines;
    // Skip design, LRU L2: the measured units' capacity misses as counted functionally and the
    // frame's (no unit's otherwise).
    Auxiliary capacity;
    if (skip) {
        // The regression takes the rays that fetched the units' new lines in place of the new
        // lines themselves: the residual over every unit of a 1080p frame fell from 41.5% to
        // 39.1% of the mean unit's cycles (bunny primary), 41.1% to 35.0% (Cornell primary),
        // 26.1% to 19.5% (bunny AO), and a 1-in-20 sample's error by 5-30% on 8 of 9 frames
        // (docs/sampling.md). The frame's new lines still give its first fills.
        Auxiliary& a = aux[kNewLines];
        a.total = 0;
        for (size_t i = 0; i < cycles_.size(); ++i)
            a.x[i] = double(profile_->unit_new_line_rays[unit_index_[i]]);
        for (uint64_t r : profile_->unit_new_line_rays) a.total += double(r);
        // A functional count per unit of the profile as an auxiliary
        // (sim/sampling/functional_l2.h), fitted only where at least 4 measured units have some: a
        // unit alone in having them has a leverage of 1 (a 96x96 bunny frame with 23 capacity
        // misses left the jackknife without replicates).
        auto per_unit_auxiliary = [&](const std::vector<uint32_t>& per_unit, double total,
                                      const char* name) {
            Auxiliary a;
            a.x.resize(cycles_.size());
            for (size_t i = 0; i < cycles_.size(); ++i) a.x[i] = double(per_unit[unit_index_[i]]);
            a.total = total;
            constexpr long kMinUnitsCarrying = 4;
            if (std::count_if(a.x.begin(), a.x.end(), [](double x) { return x > 0; }) >=
                kMinUnitsCarrying) {
                aux.push_back(a);
                aux_names.push_back(name);
            }
            return a;
        };
        // A fifth where the frame outgrows the L2: the units' capacity misses. Cornell 2-bounce
        // path frames, 1080p: the residual over every unit fell from 28.2% to 15.6% of the mean
        // unit's cycles, a 1-in-20 sample's error from 0.88% to 0.54% (docs/sampling.md).
        if (!functional_l2_.unit_capacity_misses.empty()) {
            capacity = per_unit_auxiliary(functional_l2_.unit_capacity_misses,
                                          double(functional_l2_.capacity_misses),
                                          "functional_capacity_misses");
            out["functional_l2"] = {{"misses", functional_l2_.misses},
                                    {"capacity_misses", functional_l2_.capacity_misses}};
        }
        // A sixth where a unit's cycles follow its L1 misses, which its work does not predict.
        if (!functional_l1_.unit_misses.empty()) {
            per_unit_auxiliary(functional_l1_.unit_misses, double(functional_l1_.misses),
                               "functional_l1_misses");
            out["functional_l1"] = {{"misses", functional_l1_.misses}};
        }
    }
    // Skip design: the share of the frame's work in units heavier than any measured one. The
    // regression carries the measured units' cycles per work to them; a sample that missed
    // the frame's heaviest units says little of them.
    double work_beyond_share = 0;
    if (skip) {
        double heaviest = 0, beyond = 0;
        for (size_t i = 0; i < cycles_.size(); ++i) heaviest = std::max(heaviest, aux[kWork].x[i]);
        for (const Aux& u : profile_->units)
            if (double(u[kWork]) > heaviest) beyond += double(u[kWork]);
        work_beyond_share = aux[kWork].total > 0 ? beyond / aux[kWork].total : 0.0;
        out["work_beyond_sample_share"] = work_beyond_share;
    }
    // The frame's totals of the auxiliaries, which calibrate the figures they give exactly
    // (taken before design `work` leaves its certainty units out of the regression's).
    std::array<double, kAuxiliaries> frame{};
    for (size_t k = 0; k < kAuxiliaries; ++k)
        frame[k] = skip ? aux[k].total : double(total_aux_[k]);
    // Design `work`: the certainty units are measured, their figures known; the regression
    // and its spread cover the units drawn, over the units that could be drawn (those with
    // work that are not certainty units; units without work hold none of anything).
    certain_pos_.clear();
    drawn_pos_.clear();
    uint64_t population = units;
    if (params_.by_work) {
        for (size_t i = 0; i < cycles_.size(); ++i)
            (design_->certainty_unit(unit_index_[i]) ? certain_pos_ : drawn_pos_).push_back(i);
        if (certain_pos_.size() != design_->certainty_units())
            throw std::logic_error("Sampler: a certainty unit was not measured");
        population = design_->drawn_population();
        for (Auxiliary& a : aux) {
            std::vector<double> drawn(drawn_pos_.size());
            for (size_t j = 0; j < drawn_pos_.size(); ++j) drawn[j] = a.x[drawn_pos_[j]];
            for (size_t i : certain_pos_) a.total -= a.x[i];
            a.x = std::move(drawn);
        }
        out["certainty_units"] = certain_pos_.size();
        out["drawn_units"] = drawn_pos_.size();
        out["drawn_population"] = population;
        out["drawn_strata"] = design_->drawn_strata();
    } else {
        for (size_t i = 0; i < cycles_.size(); ++i) drawn_pos_.push_back(i);
    }
    // Skip design: a unit's cycles also hold a part that does not scale with its work: they run
    // from the hand-out of its first ray to that of the next unit's, and a unit of a few cheap
    // rays waits for as many slots to free from the heavier rays before it. A regression through
    // the origin on work and the rays' misses reads such a unit's cycles as a high cost per work
    // and carries it to every light unit: on a tuning frame (cow AO, 1024x768, 1 in 10) one
    // drawn unit of 12 rays and 2,162 cycles standing for 57 units put an estimate 50% high.
    // With the units themselves (1 per unit with work) as an auxiliary, fitted second, the
    // error's standard deviation over 60 seeds of that frame fell from 6.6% to 2.1%; on 9 other
    // tuning frames the mean |error| moved by at most 0.17 points. Only where the jackknife
    // alone sets the interval (kUnitCountMinUnits informative units drawn): below that the
    // fit's model's prediction variance floors it (sim/sampling/estimators.h), and the count's
    // coefficient, carried to every unit not measured, read +-224% on a quick pilot of 11 drawn
    // units of a 512x512 bunny frame where the fit without it read +-18% on the same estimate.
    const std::vector<double>& drawn_work = aux[kWork].x;
    if (skip && size_t(std::count_if(drawn_work.begin(), drawn_work.end(),
                                     [](double w) { return w > 0; })) >= kUnitCountMinUnits) {
        Auxiliary units_with_work;
        for (double w : drawn_work) units_with_work.x.push_back(w > 0 ? 1.0 : 0.0);
        // Over the units the regression draws from: those with work, less the certainty units.
        if (params_.by_work) {
            units_with_work.total = double(population);
        } else {
            for (const Aux& u : profile_->units) units_with_work.total += u[kWork] > 0 ? 1.0 : 0.0;
        }
        aux.insert(aux.begin() + 1, std::move(units_with_work));
        aux_names.insert(aux_names.begin() + 1, "unit_with_work");
    }
    // Totals by regression on the auxiliaries (sim/sampling/estimators.h says which it fits), the
    // reference design's figure in the same unit first where there is one.
    std::vector<Auxiliary> with_reference(aux.size() + 1);
    std::copy(aux.begin(), aux.end(), with_reference.begin() + 1);
    // The matched sample's rows and first fills are looked up once, not per counter and unit.
    const std::vector<size_t> ref_rows =
        reference_ ? reference_->rows_of(unit_index_) : std::vector<size_t>();
    const std::vector<double>* ref_fills =
        reference_ ? reference_->column("l2.first_fills") : nullptr;
    // Every counter without a reference column is regressed on the same auxiliaries: one design.
    std::optional<RegressionDesign> plain_design;
    std::vector<double> expansion;  // design `work`: the units each drawn unit stands for
    for (size_t i : drawn_pos_)
        if (params_.by_work) expansion.push_back(design_->design_weight(unit_index_[i]));
    if (!drawn_pos_.empty())
        plain_design.emplace(aux, population, params_.by_work ? &expansion : nullptr);
    const RegressionDesign& plain = *plain_design;
    // Paired: a design per reference column, which like blocks share (core[0] to core[7]'s
    // counters are regressed on the reference's core.* sum).
    std::map<std::pair<std::string, double>, std::optional<RegressionDesign>> paired;
    auto regressed = [&](const std::vector<double>& y, const std::string& column, double per_fill) {
        const auto [entry, first] = paired.try_emplace({column, per_fill});
        std::optional<RegressionDesign>& design = entry->second;
        if (!first) return design ? design->total(y) : plain.total(y);
        if (reference_ && reference_->totals.count(column) &&
            (per_fill == 0 || reference_->totals.count("l2.first_fills"))) {
            const std::vector<double>* ref = reference_->column(column);
            if (!ref || (per_fill != 0 && !ref_fills))
                throw InputError(
                    fmt::format("--reference {}: its matched sample has no column {} (delete its "
                                "matched-*.csv files to run it again)",
                                reference_->dir, ref ? "l2.first_fills" : column));
            Auxiliary& r = with_reference[0];
            r.x.resize(y.size());
            r.total = reference_->totals.at(column);
            if (per_fill != 0) r.total -= per_fill * reference_->totals.at("l2.first_fills");
            for (size_t i = 0; i < y.size(); ++i)
                r.x[i] = (*ref)[ref_rows[i]] -
                         (per_fill != 0 ? per_fill * (*ref_fills)[ref_rows[i]] : 0.0);
            // A figure the reference's sample never moved (DRAM traffic beyond first fills, in a
            // frame whose lines fit its L2) says nothing of this design's.
            if (std::any_of(r.x.begin(), r.x.end(), [](double x) { return x != 0; })) {
                design.emplace(with_reference, units);
                return design->total(y);
            }
        }
        return plain.total(y);
    };
    // The certainty units' sum is known; the drawn units' total is regressed.
    auto total = [&](const std::vector<double>& y, const std::string& column, double per_fill) {
        if (!params_.by_work) return regressed(y, column, per_fill);
        double certain = 0;
        for (size_t i : certain_pos_) certain += y[i];
        Estimate e;
        if (!drawn_pos_.empty()) {
            std::vector<double> drawn(drawn_pos_.size());
            for (size_t j = 0; j < drawn_pos_.size(); ++j) drawn[j] = y[drawn_pos_[j]];
            e = regressed(drawn, column, per_fill);
        }
        e.value += certain;
        for (double& r : e.replicates) r += certain;
        return e;
    };
    if (reference_) out["reference"] = reference_->summary;
    // What the regression ran over, for estimates made later from sampled_units.csv (rtsim
    // compare's matched differences): its population and each auxiliary's total there, named as
    // the table's columns.
    {
        json totals = json::object();
        for (size_t k = 0; k < aux.size(); ++k) totals[aux_names[k]] = aux[k].total;
        out["regression"] = {{"population", population}, {"totals", totals}};
    }
    // The frame's cycles after its last hand-out: the run's own drain, corrected by the
    // reference's (sim/sampling/reference.h).
    const double drain =
        double(end_cycle - last_handout_) +
        (reference_ ? reference_->drain_full_cycles - reference_->drain_matched_cycles : 0.0);
    JointEstimates joint(drawn_pos_.size(), population);
    Estimate cycles = total(cycles_, "cycles", 0.0);
    // Above kMaxExtrapolatedWorkShare the interval is refused: the fit's spread over the units
    // measured says nothing of units unlike them (1024x768 fandisk diffuse, 1 in 50: 53% of the
    // work beyond the sample, -67% +-28%). A paired run regresses on its reference's cycles,
    // known in every unit, first: the work the sample missed is not what it extrapolates in.
    // Design `work` draws a unit in every stratum of like work, the heaviest included, by
    // construction.
    if (!reference_ && !params_.by_work && work_beyond_share > kMaxExtrapolatedWorkShare) {
        cycles.half_width = std::numeric_limits<double>::infinity();
        cycles.replicates.clear();
        cycles.caveat = fmt::format(
            "{:.0f}% of the frame's work is in units heavier than any measured unit: the estimate "
            "extrapolates to them, no interval (sim.sample_design=work measures the heaviest)",
            100 * work_beyond_share);
    }
    out["total_cycles"] = estimate_json(cycles, 1.0, drain);
    cycles.value += drain;
    for (double& r : cycles.replicates) r += drain;
    joint.add("cycles", std::move(cycles));
    out["counters"] =
        counter_estimates(total, skip ? frame_new_lines : double(total_aux_[kNewLines]), capacity,
                          population, drawn_pos_.size(), joint);
    const json known = apply_functional_totals(out["counters"], joint, frame);
    if (!known.empty()) out["functional_totals"] = known;
    joint_ = std::move(joint);
    out["figures"] = figures(units);
    return out;
}

json Sampler::apply_functional_totals(json& counters, JointEstimates& joint,
                                      const std::array<double, kAuxiliaries>& frame) const {
    // Counters that follow the rays' steps alone: a box operation per node step, a triangle
    // operation per triangle step, an L1 access per line a step's fetch spans and its bytes
    // requested. The frame's totals are known from the functional tracer, while a measured
    // unit's window (from the hand-out of its first ray to that of the ray after it) holds the
    // tails of the rays before it, which the warm-up reproduces only on average: 1080p bunny
    // primary frames, 1 in 20, estimated 0.8-1.6% too many box operations and 1.5-2.3% too much
    // L1 energy (together 78% of the frame's energy). Each identity is checked on this run's
    // own rays run in detail (every one finished by now), so a mode where one does not hold
    // (stack traffic through the L1s, say) keeps the regression's estimates.
    struct Known {
        const char* name;                   // in stats.json's sampling.functional_totals
        std::vector<std::string> prefixes;  // the blocks, "l1[" for l1[0], l1[1], ...
        const char* suffix;                 // the counter
        double run, frame;                  // this run's detailed rays', the frame's
    };
    const bool skip = params_.skip;
    // The profile counts fetches at its own line size: its totals serve an L1 of that size.
    const bool l1_known =
        !skip || (profile_ && profile_->line_bytes == l1_fetch_lines_.line_bytes());
    const double kUnknown = -1;
    const std::vector<Known> known = {
        {"box_unit.ops",
         {"box_unit["},
         ".ops",
         double(detailed_aux_[kNodeSteps]),
         frame[kNodeSteps]},
        {"triangle_unit.ops",
         {"triangle_unit["},
         ".ops",
         double(detailed_aux_[kWork] - detailed_aux_[kNodeSteps] - detailed_aux_[kRays]),
         frame[kWork] - frame[kNodeSteps] - frame[kRays]},
        {"l1.accesses",
         {"l1[", "l1_tri["},
         ".accesses",
         double(detailed_fetch_lines_),
         !l1_known ? kUnknown
         : skip    ? double(profile_->fetch_lines)
                   : double(total_fetch_lines_)},
        {"l1.bytes_requested",
         {"l1[", "l1_tri["},
         ".bytes_requested",
         double(detailed_fetch_bytes_),
         !l1_known ? kUnknown
         : skip    ? double(profile_->fetch_bytes)
                   : double(total_fetch_bytes_)},
    };
    json applied = json::object();
    const auto& e = counters_.entries();
    for (const Known& k : known) {
        if (k.frame < 0) continue;
        std::vector<std::string> names;
        double counted = 0;
        for (const auto& entry : e)
            if (std::any_of(k.prefixes.begin(), k.prefixes.end(), [&](const std::string& p) {
                    return matches(entry.name, p, k.suffix);
                })) {
                names.push_back(entry.name);
                counted += double(*entry.value);
            }
        if (names.empty() || counted != k.run || !joint.calibrate(names, k.frame)) continue;
        for (const std::string& name : names)
            if (const Estimate* est = joint.find(name)) counters[name] = estimate_json(*est, 1.0);
        applied[k.name] = k.frame;
    }
    return applied;
}

namespace {

// ",value" as fmt's "{}" writes it, whole numbers (nearly every counter) through std::to_chars:
// fmt's general path was most of a 1-in-50 run's 9 million instructions writing the table.
void append_csv_number(std::string& out, double v) {
    char buf[32];
    buf[0] = ',';
    if (v == std::floor(v) && std::fabs(v) < 1e15 && !(v == 0 && std::signbit(v))) {
        const auto r = std::to_chars(buf + 1, buf + sizeof buf, int64_t(v));
        out.append(buf, size_t(r.ptr - buf));
    } else {
        fmt::format_to(std::back_inserter(out), ",{}", v);
    }
}

}  // namespace

std::string Sampler::units_csv() const {
    // Counters of like blocks summed: "core[3].stall_l1_cycles" goes to "core.stall_l1_cycles".
    std::vector<std::string> names;
    std::vector<std::vector<double>> cols;
    const auto& e = counters_.entries();
    for (size_t c = 0; c < e.size(); ++c) {
        const std::string name = summed_counter_name(e[c].name);
        size_t col = std::find(names.begin(), names.end(), name) - names.begin();
        if (col == names.size()) {
            names.push_back(name);
            cols.emplace_back(cycles_.size(), 0.0);
        }
        for (size_t u = 0; u < cycles_.size(); ++u) cols[col][u] += deltas_[c][u];
    }
    // The skip design's units also carry the rays that fetched their new lines, which its
    // regression fits in place of the new lines.
    const bool new_line_rays = profile_ != nullptr;
    const bool capacity = !functional_l2_.unit_capacity_misses.empty();
    const bool l1 = !functional_l1_.unit_misses.empty();
    std::string out = "unit,work,new_lines,node_steps,rays,cycles";
    if (new_line_rays) out += ",new_line_rays";
    if (capacity) out += ",functional_capacity_misses";
    if (l1) out += ",functional_l1_misses";
    if (new_line_rays) out += ",unit_with_work";
    // Design `work`: which units were measured outright, and the units each stands for.
    if (params_.by_work) out += ",certainty,design_weight";
    for (const auto& n : names) out += "," + n;
    out += "\n";
    for (size_t i = 0; i < cycles_.size(); ++i) {
        // The skip design regresses on the profile's auxiliaries, the other on the run's own.
        Aux a{};
        for (size_t k = 0; k < kAuxiliaries; ++k)
            a[k] = profile_ && unit_index_[i] < profile_->units.size()
                       ? profile_->units[unit_index_[i]][k]
                       : uint64_t(aux_[k][i]);
        auto to = std::back_inserter(out);
        fmt::format_to(to, "{},{},{},{},{},{}", unit_index_[i], a[kWork], a[kNewLines],
                       a[kNodeSteps], a[kRays], cycles_[i]);
        // A per-unit figure of the profile's, 0 past its units.
        auto per_unit_column = [&](const auto& per_unit) {
            fmt::format_to(to, ",{}",
                           unit_index_[i] < per_unit.size() ? uint64_t(per_unit[unit_index_[i]])
                                                            : uint64_t(0));
        };
        if (new_line_rays) per_unit_column(profile_->unit_new_line_rays);
        if (capacity) per_unit_column(functional_l2_.unit_capacity_misses);
        if (l1) per_unit_column(functional_l1_.unit_misses);
        if (new_line_rays) fmt::format_to(to, ",{}", a[kWork] > 0 ? 1 : 0);
        if (params_.by_work)
            fmt::format_to(to, ",{},{}", design_->certainty_unit(unit_index_[i]) ? 1 : 0,
                           design_->design_weight(unit_index_[i]));
        for (const auto& c : cols) append_csv_number(out, c[i]);
        out += "\n";
    }
    return out;
}

void Sampler::add_rayless_units(uint64_t units) {
    if (!profile_ || profile_->units.size() != units)
        throw std::logic_error("Sampler: the skip design needs the frame's profile");
    // A measured unit that handed out no ray (its tiles' pixels missed the scene, so no
    // secondary rays) took no cycles and moved no counter: it enters as zeros, in unit order
    // (unit_index_ is ascending: units close in frame order).
    size_t at = 0;
    for (uint64_t u = 0; u < units; ++u) {
        if (!design_->measured_unit(u)) continue;
        if (at < unit_index_.size() && unit_index_[at] == u) {
            ++at;
            continue;
        }
        unit_index_.insert(unit_index_.begin() + long(at), u);
        for (auto& a : aux_) a.insert(a.begin() + long(at), 0.0);
        cycles_.insert(cycles_.begin() + long(at), 0.0);
        for (auto& d : deltas_) d.insert(d.begin() + long(at), 0.0);
        ++at;
    }
}

// Per measured unit, the change of the counters named `prefix`...`suffix` (l1[*].hits: "l1[",
// ".hits"; an exact name: the name and "").
std::vector<double> Sampler::unit_sums(const std::string& prefix, const std::string& suffix,
                                       size_t* blocks) const {
    std::vector<double> out(cycles_.size(), 0.0);
    const auto& e = counters_.entries();
    if (blocks) *blocks = 0;
    for (size_t c = 0; c < e.size(); ++c) {
        if (!matches(e[c].name, prefix, suffix)) continue;
        if (blocks) ++*blocks;
        for (size_t u = 0; u < out.size(); ++u) out[u] += deltas_[c][u];
    }
    return out;
}

Estimate Sampler::ratio_of(const std::vector<double>& y, const std::vector<double>& x,
                           uint64_t units) const {
    if (!params_.by_work) return ratio_estimate(y, x, units);
    // Design `work`: the certainty units' sums are known; each drawn unit stands for its
    // stratum. R = (Y_c + sum d y) / (X_c + sum d x), its variance by the delete-one
    // jackknife (a unit left out, the others' weights scaled by n / (n - 1)).
    double yc = 0, xc = 0, yd = 0, xd = 0;
    for (size_t i : certain_pos_) {
        yc += y[i];
        xc += x[i];
    }
    const size_t n = drawn_pos_.size();
    std::vector<double> d(n);
    for (size_t j = 0; j < n; ++j) {
        d[j] = design_->design_weight(unit_index_[drawn_pos_[j]]);
        yd += d[j] * y[drawn_pos_[j]];
        xd += d[j] * x[drawn_pos_[j]];
    }
    Estimate e;
    e.confidence = 0.95;
    e.units = n;
    e.population = design_->drawn_population();
    e.value = xc + xd > 0 ? (yc + yd) / (xc + xd) : 0.0;
    if (n < 2) {
        e.half_width = n == 0 ? 0.0 : std::numeric_limits<double>::infinity();
        return e;
    }
    const double scale = double(n) / double(n - 1);
    std::vector<double> r(n);
    double mean = 0;
    for (size_t j = 0; j < n; ++j) {
        const double ys = yc + scale * (yd - d[j] * y[drawn_pos_[j]]),
                     xs = xc + scale * (xd - d[j] * x[drawn_pos_[j]]);
        r[j] = xs > 0 ? ys / xs : e.value;
        mean += r[j];
    }
    mean /= double(n);
    double variance = 0;
    for (double v : r) variance += (v - mean) * (v - mean);
    variance *= double(n - 1) / double(n);
    e.t_quantile = student_t_quantile(0.975, double(n - 1));
    e.half_width = e.t_quantile * std::sqrt(variance);
    return e;
}

json Sampler::figures(uint64_t units) const {
    // Derived figures as ratios of two per-unit changes, each with its interval: a hit rate is
    // hits over accesses in the same units, a utilisation busy cycles over the cycles x blocks.
    json out = json::object();
    // A share (a hit rate, a utilisation, a stall share) lies in [0, 1], and so does its
    // interval; any ratio of counts is at least 0.
    auto ratio = [&](json& to, const std::string& name, const std::vector<double>& y,
                     const std::vector<double>& x, double scale = 1.0, bool share = true) {
        double sx = 0;
        for (double v : x) sx += v;
        if (sx <= 0) return;
        json e = estimate_json(ratio_of(y, x, units), scale);
        for (const char* bound : {"lo", "hi"})
            if (e[bound].is_number())
                e[bound] = std::clamp(e[bound].get<double>(), 0.0,
                                      share ? 1.0 : std::numeric_limits<double>::infinity());
        to[name] = std::move(e);
    };
    ratio(out, "l1_hit_rate", unit_sums("l1[", ".hits"), unit_sums("l1[", ".accesses"));
    ratio(out, "l2_hit_rate", unit_sums("l2.hits", ""), unit_sums("l2.accesses", ""));
    ratio(out, "dram_bytes_per_cycle", unit_sums("dram.bytes", ""), cycles_, 1.0, false);
    for (const char* unit : {"box_unit", "triangle_unit"}) {
        size_t blocks = 0;
        const std::vector<double> busy =
            unit_sums(std::string(unit) + "[", ".busy_cycles", &blocks);
        if (blocks)
            ratio(out, std::string(unit) + "_utilization", busy, cycles_, 1.0 / double(blocks));
    }
    // Stall shares: each cause's slot cycles over all of them (the causes and no work, which
    // is in the denominator only, as it was not a stall).
    std::vector<double> slots(cycles_.size(), 0.0);
    std::vector<std::pair<std::string, std::vector<double>>> by_cause;
    for (const std::string& cause : stall_causes()) {
        const bool no_work = cause == "no_work";
        const std::vector<double> c =
            unit_sums("core[", no_work ? ".no_work_cycles" : ".stall_" + cause + "_cycles");
        for (size_t u = 0; u < slots.size(); ++u) slots[u] += c[u];
        if (!no_work) by_cause.emplace_back(cause, c);
    }
    json shares = json::object();
    for (const auto& [cause, c] : by_cause)
        if (std::any_of(c.begin(), c.end(), [](double v) { return v != 0; }))
            ratio(shares, cause, c, slots);
    out["stall_shares"] = shares;
    return out;
}

}  // namespace rtsim

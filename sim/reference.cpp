#include "sim/reference.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>

#include "sim/bound.h"
#include "workloads/cache_entry.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Field [a, b) of `text`, line `line` of `path`, as a number; InputError if it is none (empty,
// trailing characters, not finite). Digits alone are read as an integer (exactly, and several
// times faster than as a double: rtsim writes counters and cycles so).
double csv_number(std::string_view text, size_t a, size_t b, const std::string& path, size_t line) {
    const char *first = text.data() + a, *last = text.data() + b;
    uint64_t n = 0;
    auto r = std::from_chars(first, last, n);
    if (a != b && r.ec == std::errc() && r.ptr == last) return double(n);
    double v = 0;
    r = std::from_chars(first, last, v);
    if (a == b || r.ec != std::errc() || r.ptr != last || !std::isfinite(v))
        throw InputError(
            fmt::format("{}: line {}: '{}' is not a number", path, line, text.substr(a, b - a)));
    return v;
}

}  // namespace

UnitTable parse_units_csv(const std::string& text, const std::string& path) {
    UnitTable t;
    const size_t header_end = std::min(text.find('\n'), text.size());
    if (text.compare(0, 5, "unit,") != 0)
        throw InputError(fmt::format("{}: not a sampled_units.csv (no 'unit,...' header)", path));
    for (size_t a = 0; a <= header_end;) {
        const size_t b = std::min(text.find(',', a), header_end);
        t.names.push_back(text.substr(a, b - a));
        a = b + 1;
    }
    std::vector<std::vector<double>*> cols;
    for (const auto& n : t.names) cols.push_back(&t.cols[n]);
    if (t.cols.size() != t.names.size())
        throw InputError(fmt::format("{}: a column name appears twice", path));
    // By hand with from_chars: a paired run reads a table of every measured unit's counters.
    size_t row = 1;
    for (size_t pos = header_end + 1; pos < text.size();) {
        ++row;
        const size_t end = std::min(text.find('\n', pos), text.size());
        if (end == pos) {
            pos = end + 1;
            continue;
        }
        size_t c = 0;
        for (size_t a = pos; a <= end; ++c) {
            const size_t b = std::min(text.find(',', a), end);
            if (c < t.names.size()) cols[c]->push_back(csv_number(text, a, b, path, row));
            a = b + 1;
        }
        if (c != t.names.size())
            throw InputError(fmt::format("{}: line {}: {} fields, the header has {}", path, row, c,
                                         t.names.size()));
        ++t.rows;
        pos = end + 1;
    }
    return t;
}

namespace {

const char* const kReferenceRunHow =
    "the output folder of a run of the frame with --set sim.fidelity=sampled --set "
    "sim.sample_fast_forward=skip --set sim.sample_period_units=1, which measures every unit";

// The checks on an every-unit run's stats.json (`ref`, or its digest's fields): a skip run that
// measured every unit.
void check_every_unit_run(const json& ref, const std::string& where) {
    if (ref.is_discarded() || !ref.is_object())
        throw InputError(fmt::format("{}: no readable stats.json ({})", where, kReferenceRunHow));
    const json& sm = ref.value("sampling", json::object());
    if (sm.value("fast_forward", "") != "skip" || sm.value("period_units", 0) != 1)
        throw InputError(fmt::format("{}: not a run that measured every unit of the frame ({})",
                                     where, kReferenceRunHow));
}

// How many of an every-unit run's units (its stats.json `stats`) make one of this run's units of
// `unit_tiles` tiles: this run's units are whole runs of its units (a paired run's larger units
// are its reference's merged, in frame order).
uint64_t units_merged(const json& stats, uint64_t unit_tiles, const std::string& where) {
    const uint64_t theirs = stats["sampling"].value("unit_tiles", uint64_t(0));
    if (theirs == 0 || unit_tiles % theirs != 0)
        throw InputError(
            fmt::format("{}: its units are {} tiles, this run's {} (a multiple of them is needed: "
                        "sim.sample_unit_tiles, or sim.sample_paired_unit_tiles in a paired run)",
                        where, theirs, unit_tiles));
    return unit_tiles / theirs;
}

// Every unit's cycles in an every-unit run (its stats.json `stats`), from its sampled_units.csv
// at `path` (`text`: its bytes, none if it could not be read).
std::vector<double> cycles_by_unit(const json& stats, std::optional<std::string_view> text,
                                   const std::string& path) {
    const uint64_t units = stats["sampling"].value("units", uint64_t(0));
    if (!text)
        throw InputError(
            fmt::format("{}: cannot be read (a run that measured every unit writes it)", path));
    const std::string_view t = *text;
    // Two columns of a table of every unit's counters (1.5 MB for a 1080p frame): a line is
    // scanned to its cycles field, not parsed whole.
    const size_t header_end = std::min(t.find('\n'), t.size());
    size_t cycles_col = 0, col = 0;
    bool found = false;
    for (size_t a = 0; a <= header_end && !found; ++col) {
        const size_t b = std::min(t.find(',', a), header_end);
        found = t.compare(a, b - a, "cycles") == 0;
        cycles_col = col;
        a = b + 1;
    }
    if (t.compare(0, 5, "unit,") != 0 || !found)
        throw InputError(fmt::format("{}: not a sampled_units.csv with a cycles column", path));
    std::vector<double> cycles(units, 0.0);
    std::vector<uint8_t> seen(units, 0);
    size_t listed = 0, row = 1;
    for (size_t pos = header_end + 1; pos < t.size(); ++row) {
        const size_t end = std::min(t.find('\n', pos), t.size());
        if (end == pos) {
            pos = end + 1;
            continue;
        }
        double unit = -1, c = -1;
        size_t a = pos;
        for (size_t k = 0; k <= cycles_col && a <= end; ++k) {
            const size_t b = std::min(t.find(',', a), end);
            if (k == 0) unit = csv_number(t, a, b, path, row + 1);
            if (k == cycles_col) c = csv_number(t, a, b, path, row + 1);
            a = b + 1;
        }
        if (c < 0) throw InputError(fmt::format("{}: line {}: no cycles field", path, row + 1));
        if (!(unit >= 0 && unit < double(units)) || unit != std::floor(unit) || seen[size_t(unit)])
            throw InputError(fmt::format(
                "{}: line {}: unit {} is not one of the frame's {} units, or comes twice", path,
                row + 1, unit, units));
        seen[size_t(unit)] = 1;
        cycles[size_t(unit)] = c;
        ++listed;
        pos = end + 1;
    }
    if (listed != units)
        throw InputError(
            fmt::format("{}: {} units listed, its stats.json counts {}", path, listed, units));
    return cycles;
}

// The cycles of units of `merge` consecutive units each (the last may have fewer).
std::vector<double> merged_cycles(const std::vector<double>& cycles, uint64_t merge) {
    std::vector<double> merged((cycles.size() + merge - 1) / merge, 0.0);
    for (size_t k = 0; k < cycles.size(); ++k) merged[k / merge] += cycles[k];
    return merged;
}

// The units by their cycles (`merged`: merged_cycles'), ties by unit.
std::vector<uint32_t> order_by_cycles(const std::vector<double>& merged) {
    const size_t units = merged.size();
    // Sorted as one integer key per unit (cycles, then unit) while the cycles are whole numbers
    // below 2^32, as rtsim writes them: 1080p tables' 8,100 units as (double, unit) pairs took
    // half of the order's 10 million instructions to parse and sort.
    std::vector<uint64_t> keys;
    std::vector<std::pair<double, uint32_t>> by_cycles;  // any other cycles
    keys.reserve(units);
    for (size_t u = 0; u < units; ++u) {
        const double c = merged[u];
        if (c == std::floor(c) && c < 4294967296.0)
            keys.push_back(uint64_t(c) << 32 | uint64_t(u));
        else
            by_cycles.emplace_back(c, uint32_t(u));
    }
    std::vector<uint32_t> order(units);
    if (by_cycles.empty()) {
        std::sort(keys.begin(), keys.end());
        for (size_t k = 0; k < units; ++k) order[k] = uint32_t(keys[k]);
    } else {
        for (uint64_t key : keys) by_cycles.emplace_back(double(key >> 32), uint32_t(key));
        std::sort(by_cycles.begin(), by_cycles.end());
        for (size_t k = 0; k < units; ++k) order[k] = by_cycles[k].second;
    }
    return order;
}

// What a paired run (or --sample-order) reads of an every-unit run: its stats.json's fields
// that load_reference uses, and its units' cycles. Parsing the whole 55 KB
// stats.json and scanning the 1.5 MB sampled_units.csv of a 1080p frame took 16 million
// instructions, a tenth of a 1-in-50 paired run of a small frame; the first run keeps both in a
// digest beside them, keyed by the two files' XXH3 (a rerun into the folder changes them, and
// its digest is then made again). A folder that cannot take it only costs the next run a parse.
struct EveryUnitRun {
    json stats;
    std::vector<double> cycles;  // per unit
    uint64_t merge = 1;          // its units per unit of the run reading it
    // Its units, merged to the reading run's, in order of their cycles (for
    // SamplingParams::unit_order).
    std::vector<uint32_t> order() const { return order_by_cycles(merged_cycles(cycles, merge)); }
    // That order balanced on the frame's work per cycle (balance_unit_order): the strata's.
    std::vector<uint32_t> strata_order(const std::vector<AuxFigures>& units,
                                       uint64_t period_units) const {
        const std::vector<double> merged = merged_cycles(cycles, merge);
        std::vector<uint32_t> o = order_by_cycles(merged);
        balance_unit_order(o, merged, units, period_units);
        return o;
    }
};

// 2: every unit's cycles, not their order (a paired run's units may merge several).
constexpr char kDigestMagic[8] = {'R', 'T', 'S', 'I', 'M', 'R', 'E', '2'};
constexpr const char* kDigestName = "every_unit_digest.bin";

EveryUnitRun read_every_unit_run(const fs::path& dir, const std::string& where,
                                 uint64_t unit_tiles) {
    const std::string stats_path = (dir / "stats.json").string();
    const std::string csv_path = (dir / "sampled_units.csv").string();
    // Mapped once: hashed for the digest's key, and parsed only when there is no digest.
    CacheEntryBytes stats_bytes, csv_bytes;
    stats_bytes.map(stats_path);
    const bool csv_readable = csv_bytes.map(csv_path);
    auto hash = [](const CacheEntryBytes& b) {
        return uint64_t(XXH3_64bits(b.view().data(), b.view().size()));
    };
    const std::string key =
        fmt::format("stats={:016x} units={:016x}", hash(stats_bytes), hash(csv_bytes));
    const std::string digest_path = (dir / kDigestName).string();
    EveryUnitRun run;
    {
        CacheEntryBytes digest;
        if (digest.map(digest_path)) {
            try {
                CacheEntryReader r =
                    open_cache_entry(digest.view(), kDigestMagic, "not a digest", "damaged");
                r.expect_key(key);
                std::vector<char> text;
                r.vec(text);
                r.vec(run.cycles);
                if (!r.done()) throw CacheEntryUnusable{"trailing bytes"};
                run.stats = json::parse(text.begin(), text.end(), nullptr, false);
                if (run.stats.is_object()) {
                    check_every_unit_run(run.stats, where);
                    run.merge = units_merged(run.stats, unit_tiles, where);
                    return run;
                }
            } catch (const CacheEntryUnusable&) {
            }
        }
    }
    const std::string_view text = stats_bytes.view();
    const json ref = json::parse(text.begin(), text.end(), nullptr, false);
    check_every_unit_run(ref, where);
    run.merge = units_merged(ref, unit_tiles, where);
    run.cycles = cycles_by_unit(ref, csv_readable ? std::optional(csv_bytes.view()) : std::nullopt,
                                csv_path);
    // The fields load_reference and read_unit_order read.
    const json& sm = ref["sampling"];
    json& kept = run.stats;
    for (const char* k : {"fast_forward", "period_units", "unit_tiles", "units", "total_rays",
                          "new_lines", "drain_cycles", "simulated_cycles"})
        if (sm.contains(k)) kept["sampling"][k] = sm[k];
    for (const char* k : {"workload", "bvh", "config", "config_hash", "total_cycles", "counters"})
        if (ref.contains(k)) kept[k] = ref[k];
    if (ref.contains("scene") && ref["scene"].is_object() && ref["scene"].contains("hash"))
        kept["scene"]["hash"] = ref["scene"]["hash"];
    CacheEntryWriter w(kDigestMagic);
    w.key(key);
    const std::string dumped = kept.dump();
    w.vec(std::vector<char>(dumped.begin(), dumped.end()));
    w.vec(run.cycles);
    try {
        write_file_atomically(digest_path, w.finish());
    } catch (const std::exception&) {
    }
    return run;
}

}  // namespace

std::vector<uint32_t> read_unit_order(const std::string& dir, const std::string& what,
                                      uint64_t unit_tiles) {
    const std::string where = fmt::format("{} {}", what, dir);
    return read_every_unit_run(dir, where, unit_tiles).order();
}

std::vector<uint32_t> read_strata_order(const std::string& dir, const std::string& what,
                                        uint64_t unit_tiles, const std::vector<AuxFigures>& units,
                                        uint64_t period_units) {
    const std::string where = fmt::format("{} {}", what, dir);
    const EveryUnitRun run = read_every_unit_run(dir, where, unit_tiles);
    const size_t theirs = (run.cycles.size() + run.merge - 1) / run.merge;
    if (theirs != units.size())
        throw InputError(fmt::format(
            "{}: its run has {} units, this frame {} (a run of a frame of the same size)", where,
            theirs, units.size()));
    return run.strata_order(units, period_units);
}

void balance_unit_order(std::vector<uint32_t>& order, const std::vector<double>& unit_cycles,
                        const std::vector<AuxFigures>& units, uint64_t period_units) {
    if (unit_cycles.size() != order.size() || units.size() != order.size())
        throw std::invalid_argument(
            "balance_unit_order: the order, cycles and units differ in size");
    const uint64_t group = kBalancedStrata * std::max<uint64_t>(1, period_units);
    std::vector<double> key(order.size(), 0.0);
    for (size_t u = 0; u < order.size(); ++u)
        if (unit_cycles[u] > 0) key[u] = double(units[u][kAuxWork]) / unit_cycles[u];
    for (size_t start = 0; start < order.size(); start += group) {
        const auto first = order.begin() + long(start);
        const auto last = order.begin() + long(std::min<size_t>(order.size(), start + group));
        std::sort(first, last, [&](uint32_t a, uint32_t b) {
            return key[a] < key[b] || (key[a] == key[b] && a < b);
        });
    }
}

std::string summed_counter_name(std::string name) {
    const size_t open = name.find('['), close = name.find(']');
    if (open != std::string::npos && close != std::string::npos && close > open)
        name.erase(open, close - open + 1);
    return name;
}

const std::vector<double>* Reference::column(const std::string& name) const {
    const auto col = matched.cols.find(name);
    return col == matched.cols.end() ? nullptr : &col->second;
}

std::vector<size_t> Reference::rows_of(const std::vector<uint64_t>& units) const {
    std::vector<size_t> rows(units.size());
    for (size_t i = 0; i < units.size(); ++i) {
        const auto row = row_of_unit.find(units[i]);
        if (row == row_of_unit.end())
            throw InputError(
                fmt::format("--reference {}: its matched sample has no unit {} "
                            "(delete its matched-*.csv files to run it again)",
                            dir, units[i]));
        rows[i] = row->second;
    }
    return rows;
}

namespace {

// An exclusive advisory lock on a file, held for the object's life.
class PlanLock {
  public:
    explicit PlanLock(const std::string& path) {
        fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (fd_ >= 0)
            while (::flock(fd_, LOCK_EX) != 0 && errno == EINTR) {
            }
    }
    ~PlanLock() {
        if (fd_ >= 0) ::close(fd_);  // releases the lock
    }
    PlanLock(const PlanLock&) = delete;
    PlanLock& operator=(const PlanLock&) = delete;

  private:
    int fd_ = -1;
};

}  // namespace

Reference load_reference(const RunOptions& opt, const Config& cfg, const json& meta,
                         const FrameProfile& profile, SamplingParams& sp) {
    const fs::path dir = opt.reference_dir;
    const std::string where = "--reference " + opt.reference_dir;
    EveryUnitRun run = read_every_unit_run(dir, where, sp.unit_tiles);
    const json& ref = run.stats;
    const json& sm = ref["sampling"];
    for (const char* section : {"workload", "scene"}) {
        const json mine = section == std::string("scene") ? meta["scene"]["hash"] : meta[section];
        const json theirs = section == std::string("scene")
                                ? ref.value("scene", json::object()).value("hash", json())
                                : ref.value(section, json());
        if (mine != theirs)
            throw InputError(
                fmt::format("{}: made on another frame (its {} differs: {} against {})", where,
                            section, theirs.dump(), mine.dump()));
    }
    // The same frame's units: the same BVH, and the profile's count of rays and first-touched
    // lines.
    if (ref.value("bvh", json()) != meta["bvh"])
        throw InputError(fmt::format("{}: made with another BVH (bvh differs)", where));
    uint64_t rays = 0, new_lines = 0;
    for (const AuxFigures& u : profile.units) {
        rays += u[kAuxRays];
        new_lines += u[kAuxNewLines];
    }
    // Its units, merged to this run's (the last may have fewer).
    const uint64_t merged_units = (sm.value("units", uint64_t(0)) + run.merge - 1) / run.merge;
    if (merged_units != profile.units.size() || sm.value("total_rays", 0.0) != double(rays) ||
        sm.value("new_lines", 0.0) != double(new_lines))
        throw InputError(fmt::format(
            "{}: its units are not this frame's ({} units, {} rays, {} new lines against {}, {}, "
            "{})",
            where, merged_units, sm.value("total_rays", 0.0), sm.value("new_lines", 0.0),
            profile.units.size(), rays, new_lines));
    // This frame's units: their order by the reference's cycles cuts the strata, unless the run
    // was given another.
    if (sp.unit_order.empty()) {
        sp.unit_order = run.strata_order(profile.units, sp.period_units);
        sp.unit_order_of = opt.reference_dir;
    }
    Reference r;
    r.dir = opt.reference_dir;
    // Every unit measured: the frame's counters are the units' sums, like blocks summed as in
    // sampled_units.csv, and its cycles those of the units and the drain after the last
    // hand-out.
    if (!ref.contains("counters") || !ref["counters"].is_object())
        throw InputError(fmt::format("{}: stats.json has no counters", where));
    for (const auto& [name, v] : ref["counters"].items())
        if (v.is_number()) r.totals[summed_counter_name(name)] += v.get<double>();
    r.drain_full_cycles = sm.value("drain_cycles", 0.0);
    r.totals["cycles"] = sm.value("simulated_cycles", 0.0) - r.drain_full_cycles;

    // The reference design with this run's sampling plan.
    json ref_cfg = ref["config"];
    const json& mine = cfg.values["sim"];
    for (const auto& [k, v] : mine.items())
        if (k.rfind("sample_", 0) == 0 || k == "fidelity") ref_cfg["sim"][k] = v;
    ref_cfg["sim"]["sample_period_units"] = sp.period_units;
    ref_cfg["sim"]["sample_seed"] = sp.seed;
    // The child is not paired: it is given this run's (paired) units and warm-up as its own.
    ref_cfg["sim"]["sample_unit_tiles"] = sp.unit_tiles;
    ref_cfg["sim"]["sample_warmup_tiles"] = sp.warmup_tiles;
    ref_cfg["sim"]["sample_warmup_tile_rays"] = sp.warmup_tile_rays;  // fills included
    ref_cfg["sim"]["sample_warmup_slot_fills"] = 0;
    // The order the strata were cut from is the plan's too.
    const uint64_t order_hash =
        sp.unit_order.empty()
            ? 0
            : uint64_t(XXH3_64bits(sp.unit_order.data(), sp.unit_order.size() * sizeof(uint32_t)));
    const std::string plan =
        fmt::format("{} {} {} {} order={:016x}", RTSIM_VERSION, ref.value("config_hash", ""),
                    ref_cfg["sim"].dump(), meta["workload"].dump(), order_hash);
    const std::string stem =
        fmt::format("matched-{:016x}", uint64_t(XXH3_64bits(plan.data(), plan.size())));
    const fs::path cached = dir / (stem + ".csv"), cached_drain = dir / (stem + ".json");
    // One run at a time looks for this plan's sample and runs it if missing: a sweep's points
    // that start together then run it once, the others waiting and reading it (a folder that
    // cannot hold the lock only loses that).
    const PlanLock lock((dir / (stem + ".lock")).string());
    // The drain is written before the table, so a table is read only beside its drain (an
    // interrupted write is run again).
    const json drain =
        json::parse(read_file_text(cached_drain.string()).value_or(""), nullptr, false);
    std::string matched = drain.is_object() && drain.contains("drain_cycles")
                              ? read_file_text(cached.string()).value_or("")
                              : std::string();
    const bool hit = !matched.empty();
    double child_s = 0;  // the whole child: a sweep's later points with this plan do not pay it
    if (!hit) {
        const auto child_start = std::chrono::steady_clock::now();
        char tmpl[] = "/tmp/rtsim-reference-XXXXXX.json";
        const int fd = mkstemps(tmpl, 5);
        if (fd < 0) throw std::runtime_error(where + ": cannot write a temporary config");
        close(fd);
        std::ofstream(tmpl) << ref_cfg.dump() << "\n";
        try {  // here, so that a reference from an older schema is named in one line
            load_config(tmpl, {});
        } catch (const InputError& e) {
            fs::remove(tmpl);
            const std::string why = e.what();
            throw InputError(fmt::format("{}: its config does not load in this rtsim ({})", where,
                                         why.substr(std::min(why.find(": ") + 2, why.size()))));
        }
        // The run's command line without what names its own design or output: the workload,
        // the scene and BVH caches and the tracer threads stay.
        std::vector<std::string> args = child_arguments(
            opt.argv, {"--bound", "--quiet", "-q"},
            {"--out", "-o", "--target-error", "--config", "--reference", "--mem-trace", "--set"});
        args.insert(args.begin() + (args.empty() ? 0 : 1), {"--config", tmpl});
        // Its units ordered as this run's were: by this reference's cycles unless said otherwise.
        if (opt.sample_order_dir.empty() && !sp.unit_order.empty())
            args.insert(args.end(), {"--sample-order", r.dir});
        json child;
        try {
            const std::string what = fmt::format(
                "--reference {}: the reference design's sample of this run's units", r.dir);
            child = run_rtsim_child(args, what.c_str(), &matched);
        } catch (...) {
            fs::remove(tmpl);
            throw;
        }
        fs::remove(tmpl);
        r.drain_matched_cycles = child["sampling"].value("drain_cycles", 0.0);
        // Kept for the next run with this plan (a sweep's other points); written whole or not
        // at all, and a folder that cannot take it (read-only) only costs the next run a child.
        try {
            write_file_atomically(cached_drain.string(),
                                  json({{"drain_cycles", r.drain_matched_cycles}}).dump() + "\n");
            write_file_atomically(cached.string(), matched);
        } catch (const std::exception&) {
        }
        // Process start, its run, its report and outputs, and keeping the table: the child's
        // own run_time_s left out about a sixth of it (1080p bunny primary at 1 in 50: 97 ms of
        // 114).
        child_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - child_start).count();
    } else {
        r.drain_matched_cycles = drain["drain_cycles"].get<double>();
    }
    r.matched = parse_units_csv(matched, cached.string());
    const auto& units = r.matched.cols.at("unit");
    for (size_t i = 0; i < units.size(); ++i) r.row_of_unit[uint64_t(units[i])] = i;
    r.summary = {{"dir", r.dir},
                 {"config_name", ref["config"].value("name", "")},
                 {"config_hash", ref.value("config_hash", "")},
                 {"total_cycles", ref.value("total_cycles", uint64_t(0))},
                 {"matched_sample", hit ? "cached" : "ran"},
                 {"drain_correction_cycles", r.drain_full_cycles - r.drain_matched_cycles},
                 {"matched_host_s", child_s}};
    return r;
}

}  // namespace rtsim

#include "sim/sampling/reference.h"

#include <fmt/format.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <optional>

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
    "the output folder of a run of the frame with --set sim.sampled=true --set "
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

// 2: every unit's cycles, not their order (a paired run's units may merge several).
constexpr char kDigestMagic[8] = {'R', 'T', 'S', 'I', 'M', 'R', 'E', '2'};
constexpr const char* kDigestName = "every_unit_digest.bin";

}  // namespace

EveryUnitRun read_every_unit_run(const std::string& dir_name, const std::string& where,
                                 uint64_t unit_tiles) {
    const fs::path dir = dir_name;
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

std::vector<uint32_t> EveryUnitRun::order() const {
    return order_by_cycles(merged_cycles(cycles, merge));
}

std::vector<uint32_t> EveryUnitRun::strata_order(const std::vector<AuxFigures>& units,
                                                 uint64_t period_units) const {
    const std::vector<double> merged = merged_cycles(cycles, merge);
    std::vector<uint32_t> o = order_by_cycles(merged);
    balance_unit_order(o, merged, units, period_units);
    return o;
}

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

}  // namespace rtsim

#include "sim/reference.h"

#include <fmt/format.h>
#include <unistd.h>
#include <xxhash.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sim/bound.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

namespace fs = std::filesystem;
using nlohmann::json;

UnitTable parse_units_csv(const std::string& text, const std::string& path) {
    UnitTable t;
    std::istringstream in(text);
    std::string line;
    if (!std::getline(in, line) || line.rfind("unit,", 0) != 0)
        throw InputError(fmt::format("{}: not a sampled_units.csv (no 'unit,...' header)", path));
    std::istringstream header(line);
    for (std::string name; std::getline(header, name, ',');) t.names.push_back(name);
    for (const auto& n : t.names) t.cols[n];
    if (t.cols.size() != t.names.size())
        throw InputError(fmt::format("{}: a column name appears twice", path));
    size_t row = 1;
    while (std::getline(in, line)) {
        ++row;
        if (line.empty()) continue;
        std::istringstream fields(line);
        size_t c = 0;
        for (std::string f; std::getline(fields, f, ','); ++c) {
            if (c >= t.names.size()) break;
            char* end = nullptr;
            const double v = std::strtod(f.c_str(), &end);
            if (f.empty() || *end != '\0' || !std::isfinite(v))
                throw InputError(fmt::format("{}: line {}: '{}' is not a number", path, row, f));
            t.cols[t.names[c]].push_back(v);
        }
        if (c != t.names.size())
            throw InputError(fmt::format("{}: line {}: {} fields, the header has {}", path, row, c,
                                         t.names.size()));
        ++t.rows;
    }
    return t;
}

std::string summed_counter_name(std::string name) {
    const size_t open = name.find('['), close = name.find(']');
    if (open != std::string::npos && close != std::string::npos && close > open)
        name.erase(open, close - open + 1);
    return name;
}

std::optional<double> Reference::value(const std::string& column, uint64_t unit) const {
    const auto col = matched.cols.find(column);
    const auto row = row_of_unit.find(unit);
    if (col == matched.cols.end() || row == row_of_unit.end()) return std::nullopt;
    return col->second[row->second];
}

namespace {

std::string read_text(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    if (!in) return {};
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// The run's command line without what names its own design or output: the workload, the
// scene and BVH caches and the tracer threads stay.
std::vector<std::string> workload_arguments(const std::vector<std::string>& argv) {
    std::vector<std::string> out;
    for (size_t i = 1; i < argv.size(); ++i) {
        const std::string& a = argv[i];
        if (a == "--bound" || a == "--quiet" || a == "-q") continue;
        const bool one_value = a == "--out" || a == "-o" || a == "--target-error" ||
                               a == "--config" || a == "--reference" || a == "--mem-trace";
        if (one_value) {
            ++i;
            continue;
        }
        if (a == "--set") {  // --set takes one or more values
            while (i + 1 < argv.size() && argv[i + 1].rfind("-", 0) != 0) ++i;
            continue;
        }
        bool joined = false;
        for (const char* o :
             {"--out=", "--target-error=", "--config=", "--reference=", "--mem-trace=", "--set="})
            joined = joined || a.rfind(o, 0) == 0;
        if (!joined) out.push_back(a);
    }
    return out;
}

}  // namespace

Reference load_reference(const RunOptions& opt, const Config& cfg, const json& meta,
                         const FrameProfile& profile, const SamplingParams& sp) {
    const fs::path dir = opt.reference_dir;
    const std::string where = "--reference " + opt.reference_dir;
    const std::string how =
        "a reference is the output folder of a run of the reference design on the same frame "
        "with --set sim.fidelity=sampled --set sim.sample_fast_forward=skip --set "
        "sim.sample_period_units=1";
    const json ref = json::parse(read_text(dir / "stats.json"), nullptr, false);
    if (ref.is_discarded() || !ref.is_object())
        throw InputError(fmt::format("{}: no readable stats.json ({})", where, how));
    const json& sm = ref.value("sampling", json::object());
    if (sm.value("fast_forward", "") != "skip" || sm.value("period_units", 0) != 1)
        throw InputError(
            fmt::format("{}: not a run that measured every unit of the frame ({})", where, how));
    if (sm.value("unit_tiles", uint64_t(0)) != sp.unit_tiles)
        throw InputError(fmt::format(
            "{}: its units are {} tiles, this run's {} (sim.sample_unit_tiles must match)", where,
            sm.value("unit_tiles", uint64_t(0)), sp.unit_tiles));
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
    Reference r;
    r.dir = opt.reference_dir;
    const std::string truth_path = (dir / "sampled_units.csv").string();
    const UnitTable truth = parse_units_csv(read_text(truth_path), truth_path);
    // The same frame's units: every unit's functional figures equal this run's profile's (a
    // different BVH or tile order would show here).
    if (truth.rows != profile.units.size())
        throw InputError(fmt::format("{}: {} units, this frame has {}", truth_path, truth.rows,
                                     profile.units.size()));
    const char* aux_names[kAuxiliaries] = {"work", "new_lines", "node_steps", "rays"};
    for (size_t u = 0; u < truth.rows; ++u) {
        if (truth.cols.at("unit")[u] != double(u))
            throw InputError(fmt::format("{}: row {} is not unit {}", truth_path, u + 2, u));
        for (size_t k = 0; k < kAuxiliaries; ++k)
            if (!truth.has(aux_names[k]) ||
                truth.cols.at(aux_names[k])[u] != double(profile.units[u][k]))
                throw InputError(fmt::format(
                    "{}: unit {}'s {} differs from this frame's (another BVH or workload)",
                    truth_path, u, aux_names[k]));
    }
    for (const auto& [name, v] : truth.cols) {
        double sum = 0;
        for (double x : v) sum += x;
        r.totals[name] = sum;
    }

    // The reference design with this run's sampling plan.
    json ref_cfg = ref["config"];
    const json& mine = cfg.values["sim"];
    for (const auto& [k, v] : mine.items())
        if (k.rfind("sample_", 0) == 0 || k == "fidelity") ref_cfg["sim"][k] = v;
    ref_cfg["sim"]["sample_period_units"] = sp.period_units;
    ref_cfg["sim"]["sample_seed"] = sp.seed;
    const std::string plan = fmt::format("{} {} {} {}", RTSIM_VERSION, ref.value("config_hash", ""),
                                         ref_cfg["sim"].dump(), meta["workload"].dump());
    const std::string stem =
        fmt::format("matched-{:016x}", uint64_t(XXH3_64bits(plan.data(), plan.size())));
    const fs::path cached = dir / (stem + ".csv"), cached_drain = dir / (stem + ".json");
    // The drain is written first: a table without it is an interrupted write, run again.
    const json drain = json::parse(read_text(cached_drain), nullptr, false);
    std::string matched =
        drain.is_object() && drain.contains("drain_cycles") ? read_text(cached) : std::string();
    const bool hit = !matched.empty();
    r.drain_full_cycles = sm.value("drain_cycles", 0.0);
    double child_s = 0;
    if (!hit) {
        char tmpl[] = "/tmp/rtsim-reference-XXXXXX.json";
        const int fd = mkstemps(tmpl, 5);
        if (fd < 0) throw std::runtime_error(where + ": cannot write a temporary config");
        close(fd);
        std::ofstream(tmpl) << ref_cfg.dump() << "\n";
        std::vector<std::string> args = workload_arguments(opt.argv);
        args.insert(args.begin() + (args.empty() ? 0 : 1), {"--config", tmpl});
        json child;
        try {
            child = run_rtsim_child(args, "--reference", &matched);
        } catch (...) {
            fs::remove(tmpl);
            throw;
        }
        fs::remove(tmpl);
        child_s = child["host"].value("run_time_s", 0.0);
        r.drain_matched_cycles = child["sampling"].value("drain_cycles", 0.0);
        // Kept for the next run with this plan (a sweep's other points); written whole or not
        // at all.
        write_file_atomically(cached_drain.string(),
                              json({{"drain_cycles", r.drain_matched_cycles}}).dump() + "\n");
        write_file_atomically(cached.string(), matched);
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

#include "sim/paired_run.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <unistd.h>
#include <xxhash.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "sim/bound.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

namespace fs = std::filesystem;
using nlohmann::json;

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
        if (k.rfind("sample_", 0) == 0 || k == "fidelity" || k == "sampled") ref_cfg["sim"][k] = v;
    ref_cfg["sim"]["sample_period_units"] = sp.period_units;
    ref_cfg["sim"]["sample_seed"] = sp.seed;
    // The child is not paired: it is given this run's (paired) units and warm-up as its own.
    ref_cfg["sim"]["sample_unit_tiles"] = sp.unit_tiles;
    ref_cfg["sim"]["sample_warmup_tiles"] = sp.warmup_tiles;
    ref_cfg["sim"]["sample_warmup_tile_rays"] = sp.warmup_tile_rays;  // fills included
    ref_cfg["sim"]["sample_warmup_slot_fills"] = 0;
    ref_cfg["sim"]["sample_unit_slot_fills"] = 0;  // the units as given
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

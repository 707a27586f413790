#include "sim/sweep.h"

#include "sim/sampling/registry.h"

#include <cerrno>
#include <csignal>

#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "sim/bound.h"
#include "sim/compare.h"
#include "sim/config.h"
#include "sim/interrupt.h"
#include "sim/progress.h"
#include "sim/run.h"
#include "sim/shell.h"
#include "sim/sweep_plot.h"
#include "workloads/error.h"
#include "workloads/output_file.h"
#include "workloads/trace_file.h"

namespace rtsim {

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

std::string value_text(const json& v) {
    return v.is_string() ? v.get<std::string>() : v.dump();
}

// A folder-name-safe rendering of a point's values.
std::string point_name(size_t index, const std::vector<std::pair<std::string, std::string>>& vals) {
    std::string name = fmt::format("{:03}", index);
    for (const auto& [k, v] : vals) {
        std::string part = k + "=" + v;
        for (char& ch : part)
            if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.' && ch != '=' &&
                ch != '-' && ch != '_')
                ch = '_';
        name += "_" + part;
    }
    return name;
}

std::string fresh_sweep_dir(const std::string& stem) {
    for (int i = 0;; ++i) {
        const std::string d = fmt::format("out/sweep-{}{}", stem, i ? fmt::format("-{}", i) : "");
        if (!fs::exists(d)) return d;
    }
}

std::string first_line_of(const fs::path& file) {
    std::ifstream in(file);
    std::string line;
    std::getline(in, line);
    return line.empty() ? "(no message)" : line;
}

}  // namespace

void check_pareto(const std::vector<std::string>& names, const std::string& where) {
    std::string known;
    for (const FigureDef& f : figure_list()) known += (known.empty() ? "" : ", ") + f.name;
    if (names.size() != 2)
        throw InputError(fmt::format("{}: expected two figure names, got {}", where, names.size()));
    for (const std::string& n : names) {
        bool found = false;
        for (const FigureDef& f : figure_list()) found = found || f.name == n;
        if (!found)
            throw InputError(
                fmt::format("{}: '{}' is not a figure (figures: {})", where, n, known));
    }
}

SweepPlan plan_sweep(const std::string& path) {
    const json s = read_json_file(path, "sweep file");
    auto fail = [&](const std::string& what) {
        throw InputError(fmt::format("{}: {}", path, what));
    };
    if (!s.is_object()) fail("expected an object");
    for (const auto& [k, v] : s.items())
        if (k != "config" && k != "set" && k != "workload" && k != "trace" && k != "vary" &&
            k != "pareto" && k != "reference")
            fail(fmt::format(
                "{}: unknown key (expected config, set, workload, trace, vary, pareto, reference)",
                k));
    const fs::path dir = fs::path(path).parent_path();
    auto relative = [&](const std::string& p) {
        return fs::path(p).is_absolute() ? p : (dir / p).lexically_normal().string();
    };

    std::vector<std::string> common;  // arguments every point shares
    std::string base_config;
    if (s.contains("config")) {
        if (!s["config"].is_string()) fail("config: expected a file name string");
        base_config = relative(s["config"].get<std::string>());
        common.insert(common.end(), {"--config", base_config});
    }
    std::vector<std::string> fixed_sets;
    if (s.contains("set")) {
        if (!s["set"].is_object()) fail("set: expected an object of KEY: value");
        for (const auto& [k, v] : s["set"].items()) fixed_sets.push_back(k + "=" + v.dump());
    }
    if (s.contains("trace") && s.contains("workload"))
        fail("trace and workload: give one (a trace fixes the scene and rays)");
    std::string trace;
    json trace_meta;
    if (s.contains("trace")) {
        if (!s["trace"].is_string()) fail("trace: expected a file name string");
        trace = relative(s["trace"].get<std::string>());
        if (!fs::is_regular_file(trace)) fail(fmt::format("trace: {}: no such file", trace));
        TraceReader reader(trace);  // its header, checked as `run` checks it
        trace_meta = open_trace_metadata(reader, trace);
        common.insert(common.end(), {"--trace", trace});
    } else if (s.contains("workload")) {
        if (!s["workload"].is_object()) fail("workload: expected an object");
        // Parsed and checked by the parser `run` uses, before any point starts.
        CLI::App parser;
        WorkloadOptions w;
        add_workload_options(&parser, w);
        std::vector<std::string> args;
        for (const auto& [k, v] : s["workload"].items()) {
            std::string flag = "--" + k;
            std::replace(flag.begin(), flag.end(), '_', '-');
            if (k.find('-') != std::string::npos || !parser.get_option_no_throw(flag))
                fail(fmt::format("workload.{}: unknown key", k));
            if (!v.is_string() && !v.is_number())
                fail(fmt::format("workload.{}: expected a string or a number", k));
            args.insert(args.end(), {flag, value_text(v)});
        }
        common.insert(common.end(), args.begin(), args.end());
        try {
            std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11's order
            parser.parse(reversed);
            w.resolve();
        } catch (const CLI::ParseError& e) {
            fail(fmt::format("workload: {}", e.what()));
        } catch (const InputError& e) {
            fail(fmt::format("workload: {}", e.what()));
        }
        if (w.scene.rfind("builtin:", 0) != 0 && !fs::is_regular_file(w.scene))
            fail(fmt::format("workload.scene: {}: no such file", w.scene));
    }

    std::vector<std::string> pareto;
    if (s.contains("pareto")) {
        if (!s["pareto"].is_array() || s["pareto"].size() != 2 || !s["pareto"][0].is_string() ||
            !s["pareto"][1].is_string())
            fail("pareto: expected two figure names, e.g. [\"cycles\", \"energy per ray (nJ)\"]");
        for (const auto& n : s["pareto"]) pareto.push_back(n.get<std::string>());
        check_pareto(pareto, path + ": pareto");
    }
    if (!s.contains("vary") || !s["vary"].is_object() || s["vary"].empty())
        fail("vary: expected an object of KEY: [values], e.g. {\"l1.size_kib\": [16, 32, 64]}");
    SweepPlan plan;
    std::vector<std::vector<json>> axes;
    for (const auto& [k, v] : s["vary"].items()) {
        if (!v.is_array() || v.empty())
            fail(fmt::format("vary.{}: expected a non-empty array of values", k));
        plan.keys.push_back(k);
        axes.emplace_back(v.begin(), v.end());
    }
    // Every combination, the last key varying fastest.
    size_t count = 1;
    for (const auto& a : axes) count *= a.size();
    if (count > 10000) fail(fmt::format("vary: {} points; at most 10000", count));
    for (size_t i = 0; i < count; ++i) {
        SweepPoint p;
        std::vector<std::string> sets = fixed_sets;
        size_t rest = i;
        std::vector<size_t> pick(axes.size());
        for (size_t a = axes.size(); a-- > 0;) {
            pick[a] = rest % axes[a].size();
            rest /= axes[a].size();
        }
        for (size_t a = 0; a < axes.size(); ++a) {
            const json& v = axes[a][pick[a]];
            p.values.emplace_back(plan.keys[a], value_text(v));
            sets.push_back(plan.keys[a] + "=" + v.dump());
        }
        p.name = point_name(i, p.values);
        try {  // a bad key, value or combination fails here, not in a child
            const Config cfg = load_config(base_config, sets);
            check_config_combination(cfg, trace);
            if (!trace.empty()) check_trace_matches_config(trace_meta["bvh"], cfg, trace);
        } catch (const InputError& e) {
            fail(fmt::format("point {}: {}", p.name, e.what()));
        }
        p.run_args = common;
        for (const auto& set : sets) p.run_args.insert(p.run_args.end(), {"--set", set});
        plan.points.push_back(std::move(p));
    }
    plan.pareto = pareto;
    if (s.contains("reference")) {
        if (!s["reference"].is_boolean()) fail("reference: expected true or false");
        if (s["reference"].get<bool>()) {
            if (!trace.empty())
                fail(
                    "reference: needs a workload (a reference's units are tiles of a generated "
                    "frame)");
            const Config base = load_config(base_config, fixed_sets);
            if (!base.typed.sim.sampled ||
                !FastForwardRegistry::at(base.typed.sim.sample_fast_forward).needs_profile)
                fail(
                    "reference: the base design must set sim.sampled=true and "
                    "sim.sample_fast_forward=skip");
            SweepPoint r;
            r.name = "reference";
            r.run_args = common;
            for (const auto& set : fixed_sets) r.run_args.insert(r.run_args.end(), {"--set", set});
            r.run_args.insert(r.run_args.end(), {"--set", "sim.sample_period_units=1"});
            plan.reference = std::move(r);
        }
    }
    return plan;
}

void pair_with_reference(SweepPlan& plan, const std::string& out_dir) {
    if (!plan.reference) return;
    const std::string dir = (fs::absolute(out_dir) / plan.reference->name).string();
    for (SweepPoint& p : plan.points) p.run_args.insert(p.run_args.end(), {"--reference", dir});
}

namespace {
// Whether the point's folder holds a finished run of these arguments (a run writes stats.json
// last, atomically; run.json says what it ran).
bool finished_before(const fs::path& dir, const std::vector<std::string>& run_args) {
    if (!fs::is_regular_file(dir / "stats.json")) return false;
    std::ifstream in(dir / "run.json");
    const json j = json::parse(in, nullptr, false);
    return !j.is_discarded() && j.is_object() && j.value("args", json()) == json(run_args);
}
}  // namespace

namespace {

// Starts point `p`'s run (this binary's `run`, its stderr kept in the point's folder); returns
// its pid, or -1 if it could not be started.
pid_t spawn_point(const std::string& out_dir, const SweepPoint& p) {
    const fs::path dir = fs::path(out_dir) / p.name;
    std::error_code ec;
    fs::create_directories(dir, ec);
    // What this folder's run is, for --resume; a stale stats.json would pass for it.
    fs::remove(dir / "stats.json", ec);
    write_file_atomically((dir / "run.json").string(), json({{"args", p.run_args}}).dump(1) + "\n");
    std::vector<std::string> args = {"run", "--quiet"};
    args.insert(args.end(), p.run_args.begin(), p.run_args.end());
    args.insert(args.end(), {"--out", dir.string()});
    return spawn_rtsim(args, (dir / "stderr.txt").string(), true);
}

// Runs the points `jobs` at a time (points finished before, with --resume, are skipped) and
// throws naming the first that failed. Returns how many were skipped.
size_t run_points(const SweepPlan& plan, const std::string& out_dir, int jobs, bool resume,
                  bool quiet) {
    const bool progress = !quiet && isatty(STDERR_FILENO);
    const auto started = std::chrono::steady_clock::now();
    size_t failed_points = 0;
    auto show = [&](size_t done_now, size_t running_now) {
        if (!progress) return;
        const double elapsed =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        std::fprintf(
            stderr, "\r%s   ",
            sweep_progress_line(done_now, running_now, failed_points, plan.points.size(), elapsed)
                .c_str());
        std::fflush(stderr);
    };
    std::map<pid_t, size_t> running;
    std::vector<int> status(plan.points.size(), -1);
    size_t skipped = 0;
    if (resume)
        for (size_t i = 0; i < plan.points.size(); ++i)
            if (finished_before(fs::path(out_dir) / plan.points[i].name, plan.points[i].run_args)) {
                status[i] = 0;
                ++skipped;
            }
    size_t next = 0, done = skipped;
    bool failed = false;
    std::string spawn_error;
    while (done < plan.points.size() && !(failed && running.empty())) {
        while (!failed && next < plan.points.size() && running.size() < size_t(jobs)) {
            if (status[next] == 0) {  // finished before (--resume)
                ++next;
                continue;
            }
            const pid_t pid = spawn_point(out_dir, plan.points[next]);
            if (pid < 0) {  // stop starting runs; the ones running finish first
                spawn_error = fmt::format("sweep: cannot start the run of {}",
                                          (fs::path(out_dir) / plan.points[next].name).string());
                failed = true;
                break;
            }
            running[pid] = next++;
        }
        show(done, running.size());
        if (running.empty()) break;
        int st = 0;
        const pid_t pid = waitpid(-1, &st, 0);
        if (const int sig = interrupt_signal()) {
            // SIGINT/SIGTERM: start nothing more; the running points get the signal too (a
            // terminal's Ctrl-C reaches them already; a `kill` of this process only it) and
            // leave no stats; what finished stays for --resume.
            for (const auto& [child, point] : running) kill(child, sig);
            while (!running.empty()) {
                const pid_t c = waitpid(-1, &st, 0);
                if (c < 0 && errno != EINTR) break;
                if (c > 0 && running.erase(c) && WIFEXITED(st) && WEXITSTATUS(st) == 0)
                    ++done;  // it finished before the signal reached it
            }
            throw Interrupted(
                sig, fmt::format("{} of {} points finished under {}, no table written; run the "
                                 "same command with --resume to finish",
                                 done, plan.points.size(), out_dir));
        }
        if (pid < 0) {
            if (errno == EINTR) continue;
            break;
        }
        const auto it = running.find(pid);
        if (it == running.end()) continue;
        status[it->second] = WIFEXITED(st) ? WEXITSTATUS(st) : 128;
        failed = failed || status[it->second] != 0;
        failed_points += status[it->second] != 0;
        running.erase(it);
        ++done;
        show(done, running.size());
    }
    if (progress) std::fprintf(stderr, "\r%100s\r", "");
    if (!spawn_error.empty()) throw std::runtime_error(spawn_error);
    for (size_t i = 0; i < plan.points.size(); ++i)
        if (status[i] > 0) {
            const fs::path dir = fs::path(out_dir) / plan.points[i].name;
            throw std::runtime_error(fmt::format("sweep: run {} failed (status {}): {}",
                                                 dir.string(), status[i],
                                                 first_line_of(dir / "stderr.txt")));
        }
    return skipped;
}

// The table (printed), results.json and results.csv: one row per point, the figures of the
// shared list.
void write_results(const SweepOptions& opt, const SweepPlan& plan, const std::string& out_dir,
                   size_t skipped) {
    // The table: one row per point.
    json results = json::array();
    std::vector<std::vector<std::string>> table;
    std::vector<std::string> head = plan.keys;
    // The table's columns: the figures that tell designs apart at a glance.
    for (const FigureDef& f : figure_list())
        if (f.sweep_table) head.push_back(f.name);
    table.push_back(head);
    std::string csv;
    // Sampled points carry each estimate's 95% half-width (relative, percent) beside it: in the
    // table, in results.json's "intervals" and in results.csv's "<figure> +-%" columns. An
    // estimate with no interval the data support shows as inf (null in JSON).
    bool sampled_columns = false;
    for (size_t i = 0; i < plan.points.size(); ++i) {
        const SweepPoint& p = plan.points[i];
        const std::string stats_path = (fs::path(out_dir) / p.name / "stats.json").string();
        const ComparedRun run = load_compared_run(stats_path, p.name);
        const std::vector<Figure> figures = key_figures(run.stats);
        json row = {{"point", p.name}, {"stats", stats_path}, {"values", json::object()}};
        for (const auto& [k, v] : p.values) row["values"][k] = v;
        json figs = json::object();
        for (const Figure& f : figures)
            figs[f.name] = std::isnan(f.value) ? json(nullptr) : json(f.value);
        row["figures"] = figs;
        std::vector<double> interval(figures.size());
        json intervals = json::object();
        for (size_t k = 0; k < figures.size(); ++k) {
            interval[k] = interval_pct(figure_list()[k], run.stats);
            if (!std::isnan(interval[k]))
                intervals[figures[k].name] =
                    std::isfinite(interval[k]) ? json(interval[k]) : json(nullptr);
        }
        if (!intervals.empty()) row["intervals"] = intervals;
        results.push_back(row);
        std::vector<std::string> cells;
        for (const auto& kv : p.values) cells.push_back(kv.second);
        for (size_t k = 0; k < figures.size(); ++k)
            if (figure_list()[k].sweep_table)
                cells.push_back(format_figure(figures[k].value, figures[k].percent) +
                                (std::isnan(interval[k]) ? std::string()
                                                         : fmt::format(" +-{:.1f}%", interval[k])));
        table.push_back(cells);
        if (i == 0) {
            sampled_columns = run.stats.contains("sampling");
            std::vector<std::string> names = plan.keys;
            for (const Figure& f : figures) names.push_back(f.name);
            if (sampled_columns)
                for (size_t k = 0; k < figures.size(); ++k)
                    if (!figure_list()[k].sampled.empty())
                        names.push_back(figures[k].name + " +-%");
            for (size_t k = 0; k < names.size(); ++k) csv += (k ? "," : "") + names[k];
            csv += "\n";
        }
        std::string line;
        for (const auto& kv : p.values) line += (line.empty() ? "" : ",") + kv.second;
        for (const Figure& f : figures)
            line += "," + (std::isnan(f.value) ? std::string() : fmt::format("{}", f.value));
        if (sampled_columns)
            for (size_t k = 0; k < figures.size(); ++k)
                if (!figure_list()[k].sampled.empty())
                    line += "," + (std::isnan(interval[k]) ? std::string()
                                                           : fmt::format("{}", interval[k]));
        csv += line + "\n";
    }
    write_file_atomically(
        (fs::path(out_dir) / "results.json").string(),
        json({{"sweep", opt.path}, {"keys", plan.keys}, {"points", results}}).dump(1));
    write_file_atomically((fs::path(out_dir) / "results.csv").string(), csv);

    // Plots: the table's figures and energy per ray against each varied axis; the Pareto front.
    SweepPlotData plot;
    plot.keys = plan.keys;
    for (const FigureDef& f : figure_list()) {
        plot.figure_names.push_back(f.name);
        plot.figure_percent.push_back(f.percent);
    }
    for (const FigureDef& f : figure_list())
        plot.panel.push_back(f.sweep_table || f.name == "energy per ray (nJ)");
    for (size_t i = 0; i < plan.points.size(); ++i) plot.values.push_back(plan.points[i].values);
    for (const json& row : results) {
        std::vector<double> v;
        for (const FigureDef& f : figure_list()) {
            const json& x = row["figures"][f.name];
            v.push_back(x.is_number() ? x.get<double>() : std::nan(""));
        }
        plot.figures.push_back(v);
    }
    std::string png_note;
    const std::vector<std::string> plots =
        write_sweep_plots(out_dir, plot, opt.pareto.empty() ? plan.pareto : opt.pareto, png_note);

    fmt::print("{}", format_table(table, false));
    fmt::print(
        "\n{} runs{}; stats under {}; table in results.json and results.csv; {} plots in {}{}\n",
        plan.points.size(),
        skipped ? fmt::format(" ({} finished before, not run again)", skipped) : "", out_dir,
        plots.size(), (fs::path(out_dir) / "plots").string(),
        png_note.empty() ? "" : " (" + png_note + ")");
}

}  // namespace

namespace {

// The points of `plan` that have no finished run in out_dir, and why (the first line of the
// run's stderr, or that it never ran).
std::vector<std::pair<size_t, std::string>> unfinished_points(const SweepPlan& plan,
                                                              const std::string& out_dir) {
    std::vector<std::pair<size_t, std::string>> out;
    for (size_t i = 0; i < plan.points.size(); ++i) {
        const fs::path dir = fs::path(out_dir) / plan.points[i].name;
        if (finished_before(dir, plan.points[i].run_args)) continue;
        const std::string why = first_line_of(dir / "stderr.txt");
        out.push_back(
            {i, fs::exists(dir / "run.json") && !why.empty()
                    ? why
                    : (fs::exists(dir / "run.json") ? "did not finish (killed or cancelled)"
                                                    : "did not run")});
    }
    return out;
}

// Runs point `p` (as spawn_point starts it) and waits for it; true if it succeeded.
bool run_point_now(const std::string& out_dir, const SweepPoint& p) {
    const pid_t pid = spawn_point(out_dir, p);
    if (pid < 0) throw std::runtime_error("sweep: cannot start the run of " + p.name);
    int st = 0;
    if (!wait_rtsim(pid, st)) throw std::runtime_error("sweep: lost the run of " + p.name);
    return WIFEXITED(st) && WEXITSTATUS(st) == 0;
}

// One array task: its points (task * per .. task * per + per - 1) in turn, each as the local sweep
// runs it (the same child run and folder); points already finished are not run again. Returns 1
// if any failed.
int run_task(const SweepPlan& plan, const std::string& out_dir, int task, int per) {
    const size_t first = size_t(task) * size_t(per);
    if (task < 0 || first >= plan.points.size())
        throw InputError(fmt::format("--task: expected 0 to {} ({} points, {} per task), got {}",
                                     (plan.points.size() - 1) / size_t(per), plan.points.size(),
                                     per, task));
    int status = 0;
    for (size_t i = first; i < std::min(plan.points.size(), first + size_t(per)); ++i) {
        const SweepPoint& p = plan.points[i];
        if (finished_before(fs::path(out_dir) / p.name, p.run_args)) continue;
        if (!run_point_now(out_dir, p)) status = 1;
    }
    return status;
}

// The job script (out_dir/slurm/sweep.sbatch), an array task per listed task; returns its path.
std::string write_job_script(const SweepOptions& opt, const std::string& out_dir,
                             const std::vector<size_t>& tasks) {
    const fs::path dir = fs::absolute(out_dir);
    fs::create_directories(dir / "slurm");
    std::string array;
    for (size_t i : tasks) array += (array.empty() ? "" : ",") + std::to_string(i);
    if (opt.max_parallel > 0) array += "%" + std::to_string(opt.max_parallel);
    std::string script = fmt::format(
        "#!/bin/sh\n"
        "# rtsim sweep {} through Slurm: array task K runs points K*{} to K*{}+{}, each as the\n"
        "# local sweep does (its folder under {}). Written by rtsim sweep --slurm; resubmit by\n"
        "# hand with sbatch, or with rtsim sweep --slurm --resume for only what is missing.\n"
        "#SBATCH --job-name=rtsim-sweep\n#SBATCH --array={}\n#SBATCH "
        "--output={}/slurm/task-%a.out\n"
        "#SBATCH --cpus-per-task=1\n",
        opt.path, opt.points_per_task, opt.points_per_task, opt.points_per_task - 1, dir.string(),
        array, dir.string());
    if (!opt.partition.empty()) script += "#SBATCH --partition=" + opt.partition + "\n";
    if (!opt.time_limit.empty()) script += "#SBATCH --time=" + opt.time_limit + "\n";
    if (!opt.mem.empty()) script += "#SBATCH --mem=" + opt.mem + "\n";
    script += fmt::format(
        "exec {} sweep {} --out {} --points-per-task {} --task \"$SLURM_ARRAY_TASK_ID\"\n",
        shell_quoted(fs::canonical("/proc/self/exe").string()),
        shell_quoted(fs::absolute(opt.path).string()), shell_quoted(dir.string()),
        opt.points_per_task);
    const std::string path = (dir / "slurm" / "sweep.sbatch").string();
    write_file_atomically(path, script);
    return path;
}

// Runs a command, returning its exit status and what it printed on stdout.
int capture(const std::string& cmd, std::string& out) {
    out.clear();
    FILE* p = popen(cmd.c_str(), "r");
    if (!p) return -1;
    char buf[512];
    while (fgets(buf, sizeof buf, p)) out += buf;
    const int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

// The table once every point finished; otherwise names each that did not, and returns 1.
int collect(const SweepOptions& opt, const SweepPlan& plan, const std::string& out_dir) {
    const auto missing = unfinished_points(plan, out_dir);
    if (!missing.empty()) {
        std::fprintf(stderr, "rtsim: sweep: %zu of %zu points did not finish under %s:\n",
                     missing.size(), plan.points.size(), out_dir.c_str());
        for (const auto& [i, why] : missing)
            std::fprintf(stderr, "  %s: %s\n", plan.points[i].name.c_str(), why.c_str());
        std::fprintf(stderr,
                     "rtsim: sweep: no table written; rerun them with --slurm --resume -o %s\n",
                     out_dir.c_str());
        return 1;
    }
    write_results(opt, plan, out_dir, 0);
    return 0;
}

int submit(const SweepOptions& opt, const SweepPlan& plan, const std::string& out_dir) {
    // The tasks holding the points to run (all, or with --resume those not finished).
    const size_t per = size_t(opt.points_per_task);
    std::vector<size_t> points, tasks;
    if (opt.resume)
        for (const auto& [i, why] : unfinished_points(plan, out_dir)) points.push_back(i);
    else
        for (size_t i = 0; i < plan.points.size(); ++i) points.push_back(i);
    if (points.empty()) return collect(opt, plan, out_dir);
    for (size_t i : points)
        if (tasks.empty() || tasks.back() != i / per) tasks.push_back(i / per);
    const std::string script = write_job_script(opt, out_dir, tasks);
    // For rtsim sweep --collect DIR: which sweep the folder holds.
    write_file_atomically((fs::path(out_dir) / "slurm" / "sweep_file").string(),
                          fs::absolute(opt.path).string() + "\n");
    std::string out;
    const int st = capture(
        fmt::format("sbatch --parsable{} {} 2>&1", opt.wait ? " --wait" : "", shell_quoted(script)),
        out);
    while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
    const std::string job = out.substr(0, out.find(';'));
    if (!opt.wait || job.empty() || job.find_first_not_of("0123456789") != std::string::npos) {
        if (st != 0)
            throw std::runtime_error(fmt::format("sweep: sbatch {} failed: {}", script, out));
        write_file_atomically((fs::path(out_dir) / "slurm" / "job_id").string(), job + "\n");
        fmt::print(
            "submitted job {} ({} points) with {}; collect with: rtsim sweep {} --collect "
            "-o {}\n",
            job, points.size(), script, opt.path, out_dir);
        return 0;
    }
    // --wait: sbatch returned when the job ended (non-zero if a task failed); the folders say.
    write_file_atomically((fs::path(out_dir) / "slurm" / "job_id").string(), job + "\n");
    return collect(opt, plan, out_dir);
}

}  // namespace

int sweep_command(const SweepOptions& given) {
    SweepOptions opt = given;
    // rtsim sweep --collect DIR: the sweep file is the one submitted from DIR.
    if (opt.collect && opt.out_dir.empty() && fs::is_directory(opt.path)) {
        opt.out_dir = opt.path;
        const fs::path note = fs::path(opt.path) / "slurm" / "sweep_file";
        std::string file = first_line_of(note);
        if (file.empty())
            throw InputError(fmt::format(
                "{}: no slurm/sweep_file (not submitted with --slurm); give the sweep file and "
                "-o {}",
                opt.path, opt.path));
        opt.path = file;
    }
    if (opt.jobs < 1) throw InputError(fmt::format("-j: expected 1 or more, got {}", opt.jobs));
    if ((opt.collect || opt.task >= 0) && opt.out_dir.empty())
        throw InputError(fmt::format("{}: needs --out, the sweep's folder",
                                     opt.collect ? "--collect" : "--task"));
    if (opt.points_per_task < 1)
        throw InputError(
            fmt::format("--points-per-task: expected 1 or more, got {}", opt.points_per_task));
    if (opt.max_parallel < 0)
        throw InputError(
            fmt::format("--max-parallel: expected 0 or more, got {}", opt.max_parallel));
    if (!opt.slurm &&
        (opt.wait || !opt.partition.empty() || !opt.time_limit.empty() || !opt.mem.empty() ||
         opt.max_parallel > 0 || (opt.points_per_task != 1 && opt.task < 0)))
        throw InputError(
            "--wait, --partition, --time, --mem, --max-parallel and --points-per-task need "
            "--slurm");
    if (opt.resume && opt.out_dir.empty())
        throw InputError("--resume: needs --out, the folder of the sweep to finish");
    if (opt.resume && !fs::is_directory(opt.out_dir))
        throw InputError(fmt::format("--resume: {}: no such folder", opt.out_dir));
    if (!opt.pareto.empty()) check_pareto(opt.pareto, "--pareto");
    SweepPlan plan = plan_sweep(opt.path);
    const std::string out_dir =
        opt.out_dir.empty() ? fresh_sweep_dir(fs::path(opt.path).stem().string()) : opt.out_dir;
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec)
        throw InputError(fmt::format("{}: cannot create the folder ({})", out_dir, ec.message()));
    pair_with_reference(plan, out_dir);
    if (opt.task >= 0) return run_task(plan, out_dir, opt.task, opt.points_per_task);
    if (opt.collect) return collect(opt, plan, out_dir);
    // The reference before any point (here, also before a Slurm job's tasks start).
    if (plan.reference &&
        !finished_before(fs::path(out_dir) / plan.reference->name, plan.reference->run_args)) {
        if (!run_point_now(out_dir, *plan.reference)) {
            const fs::path dir = fs::path(out_dir) / plan.reference->name;
            const std::string why = first_line_of(dir / "stderr.txt");
            throw std::runtime_error(fmt::format("sweep: the reference run in {} failed{}",
                                                 dir.string(), why.empty() ? "" : ": " + why));
        }
    }
    if (opt.slurm) return submit(opt, plan, out_dir);
    const size_t skipped = run_points(plan, out_dir, opt.jobs, opt.resume, opt.quiet);
    write_results(opt, plan, out_dir, skipped);
    return 0;
}

}  // namespace rtsim

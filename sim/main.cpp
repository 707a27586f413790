// The rtsim command line. libsystemc supplies main() and calls sc_main().
#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <cstdlib>
#include <systemc>

#include "sim/compare.h"
#include "sim/config.h"
#include "sim/dram_cmd.h"
#include "sim/errors.h"
#include "sim/interrupt.h"
#include "sim/list_cmd.h"
#include "sim/report.h"
#include "sim/run.h"
#include "sim/sweep.h"
#include "sim/trace_cmd.h"
#include "sim/trace_info.h"
#include "workloads/error.h"

namespace {

CLI::App* add_run_command(CLI::App& app, rtsim::RunOptions& run) {
    CLI::App* run_cmd = app.add_subcommand(
        "run", "Simulate a frame's rays on an architecture config; writes stats.json");
    run_cmd->add_option("--config", run.config_path,
                        "Architecture config JSON (default: built-in defaults)");
    run_cmd->add_option("--set", run.sets,
                        "Override a config field, KEY=VALUE (e.g. l1.size_kib=64); repeatable");
    rtsim::add_workload_options(run_cmd, run.workload);
    run_cmd->add_option("--trace", run.trace_path,
                        "Replay a trace file (from rtsim trace -o) instead of generating rays");
    run_cmd->add_option("--out,-o", run.out_dir,
                        "Output folder for stats.json (default: a fresh folder under out/)");
    run_cmd->add_flag("--quiet,-q", run.quiet, "No summary or progress");
    run_cmd->add_option("--mem-trace", run.mem_trace_path,
                        "Also write the requests that reach DRAM, in DRAMsim3's trace format "
                        "(0x<address> READ <cycle>, a line per burst; cycles of dram.device's "
                        "clock with dram.model=command, else chip cycles), for rtsim dram, "
                        "DRAMsim3 or Ramulator");
    rtsim::add_bvh_cache_option(run_cmd, run.bvh_cache);
    run_cmd
        ->add_option("--tracer-threads", run.tracer_threads,
                     "Threads that generate and trace the rays of a generated workload (default "
                     "1). Every simulated figure is the same for any count; a sampled run, which "
                     "traces every ray but times few, waits for them")
        ->check(CLI::Range(1, 256));
    run_cmd
        ->add_option("--target-error", run.target_error_pct,
                     "With sim.sampled=true: the 95% interval wanted on the frame's cycles "
                     "and DRAM bytes, in percent; a pilot sample sizes the rest")
        ->check(CLI::Range(0.01, 100.0));
    run_cmd->add_option("--pilot-units", run.pilot_units, "A --target-error pilot's units")
        ->group("");
    run_cmd->add_option(
        "--reference", run.reference_dir,
        "With sim.sampled=true and sim.sample_fast_forward=skip: the output folder of a run "
        "of a reference design on the same frame that measured every unit "
        "(sim.sample_period_units=1); the reference design is sampled on the same units and "
        "each figure is estimated from the pair, with a far narrower interval for designs near "
        "it; the strata are cut from the units in order of their cycles in DIR, as with "
        "--sample-order DIR. The run's units are sim.sample_paired_unit_tiles tiles, DIR's "
        "merged to them (its units must divide them)");
    run_cmd->add_option(
        "--sample-order", run.sample_order_dir,
        "With sim.sampled=true and sim.sample_fast_forward=skip: cut the strata (one "
        "measured unit in each sim.sample_period_units) from the frame's units in order of their "
        "cycles in DIR, the output folder of a run that measured every unit of the frame "
        "(sim.sample_period_units=1) in units that divide this run's (merged to them), instead "
        "of in the frame's order: like units share a stratum. Any order leaves the estimates "
        "unbiased; this one narrows them");
    run_cmd->add_flag(
        "--bound", run.bound,
        "Also simulate the same rays with ideal memory and unlimited units, and report "
        "achieved / bound rays per second");
    return run_cmd;
}

// `rtsim run` with --trace: the trace fixes the scene and rays.
void refuse_workload_options_with_trace(CLI::App* run_cmd) {
    for (const char* o : {"--scene", "--rays", "--res", "--spp", "--seed", "--light",
                          "--ao-samples", "--ao-length", "--diffuse-depth"})
        if (run_cmd->count(o))
            throw rtsim::InputError(fmt::format(
                "{}: cannot be combined with --trace (the trace fixes the scene and rays)", o));
}

int main_impl(int argc, char** argv) {
    rtsim::install_interrupt_handlers();
    CLI::App app{"RTSim: a cycle-approximate ray-tracing hardware simulator"};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("rtsim ") + RTSIM_VERSION);
    // Checks that a command line parses and does nothing else: the documentation's command
    // lines are tested this way without their files (tests/e2e/test_docs.cpp). Hidden.
    bool parse_only = false;
    app.add_flag("--parse-only", parse_only, "Check the command line only")->group("");

    rtsim::RunOptions run;
    CLI::App* run_cmd = add_run_command(app, run);
    run.argv.assign(argv, argv + argc);

    rtsim::TraceOptions trace;
    CLI::App* trace_cmd = app.add_subcommand(
        "trace", "Run the functional tracer alone on generated or external rays; write hits");
    rtsim::add_trace_options(trace_cmd, trace);

    std::string info_path;
    bool info_json = false;
    CLI::App* info_cmd = app.add_subcommand(
        "trace-info", "Print a trace file's header, counts and per-kind histograms");
    info_cmd->add_option("file", info_path, "Trace file (.rtt)")->required();
    info_cmd->add_flag("--json", info_json, "Print the summary as JSON");

    rtsim::CompareOptions compare;
    CLI::App* compare_cmd = app.add_subcommand(
        "compare", "Compare runs: their stats.json figures side by side, relative to the first");
    compare_cmd->add_option("stats", compare.paths, "stats.json files, or run folders holding one")
        ->required();
    compare_cmd->add_option("--labels", compare.labels, "A label per run (default A, B, C, ...)")
        ->delimiter(',');
    compare_cmd->add_option("--json", compare.json_path, "Also write the comparison as JSON");
    compare_cmd->add_option("--svg", compare.svg_path,
                            "Also draw stall shares (and bandwidth per window, when every run "
                            "recorded sim.window_cycles) as SVG");

    rtsim::ReportOptions report;
    CLI::App* report_cmd = app.add_subcommand(
        "report", "One self-contained HTML page for a run, a comparison of runs, or a sweep");
    report_cmd
        ->add_option("paths", report.paths,
                     "Run folders or stats.json files (a comparison when several), or one sweep "
                     "folder")
        ->required();
    report_cmd->add_option("--labels", report.labels, "A label per run (default A, B, C, ...)")
        ->delimiter(',');
    report_cmd->add_option("-o,--out", report.out_path, "The HTML file to write")
        ->capture_default_str();
    rtsim::SweepOptions sweep;
    CLI::App* sweep_cmd = app.add_subcommand(
        "sweep", "Simulate one workload on every combination of config values; one results table");
    sweep_cmd
        ->add_option("file", sweep.path, "Sweep file (JSON: config, set, workload or trace, vary)")
        ->required();
    sweep_cmd->add_option("--out,-o", sweep.out_dir,
                          "Output folder (default: a fresh folder under out/)");
    sweep_cmd->add_option("-j,--jobs", sweep.jobs, "Runs at once")->capture_default_str();
    sweep_cmd->add_flag("--quiet,-q", sweep.quiet,
                        "No progress line (shown on a terminal only: points done, running and "
                        "failed, and the time left)");
    sweep_cmd
        ->add_option("--pareto", sweep.pareto,
                     "Two figures (as the table names them, comma-separated) whose Pareto front "
                     "plots/pareto.svg draws, e.g. 'cycles,energy per ray (nJ)'")
        ->delimiter(',')
        ->expected(2);
    sweep_cmd->add_flag("--slurm", sweep.slurm,
                        "Submit the points as one Slurm job array (sbatch), a task per point; the "
                        "job script goes to OUT/slurm/");
    sweep_cmd->add_option("--partition", sweep.partition, "--slurm: the partition");
    sweep_cmd->add_option("--time", sweep.time_limit, "--slurm: each task's time limit");
    sweep_cmd->add_option("--mem", sweep.mem, "--slurm: each task's memory");
    sweep_cmd->add_option("--max-parallel", sweep.max_parallel, "--slurm: tasks running at once");
    sweep_cmd->add_flag("--wait", sweep.wait, "--slurm: wait for the job, then collect the table");
    sweep_cmd->add_flag("--collect", sweep.collect,
                        "Write the table from OUT's points once all finished; else name those "
                        "that did not");
    sweep_cmd
        ->add_option("--points-per-task", sweep.points_per_task,
                     "--slurm: points each array task runs in turn (for short runs)")
        ->capture_default_str();
    sweep_cmd->add_option("--task", sweep.task, "Run one array task's points (what Slurm runs)")
        ->group("");
    sweep_cmd->add_flag("--resume", sweep.resume,
                        "Finish the sweep in --out: points that already ran with the same "
                        "arguments are not run again");

    std::string cfg_path;
    std::vector<std::string> cfg_sets;
    bool cfg_doc = false;
    CLI::App* cfg_cmd =
        app.add_subcommand("config", "Print the effective config, or the field reference");
    cfg_cmd->add_option("--config", cfg_path, "Config JSON to resolve");
    cfg_cmd->add_option("--set", cfg_sets, "Override a field, KEY=VALUE; repeatable");
    cfg_cmd->add_flag("--doc", cfg_doc, "Print the reference of every field (Markdown)");

    rtsim::DramTraceOptions dram;
    CLI::App* dram_cmd = app.add_subcommand(
        "dram",
        "Run a memory trace (DRAMsim3 format: 0x<address> READ|WRITE <cycle>) through the "
        "command-level DRAM model alone; report bandwidth, read latency, row hits and energy");
    dram_cmd->add_option("trace", dram.trace_path, "Memory trace file")->required();
    dram_cmd
        ->add_option("--device", dram.device,
                     "A device preset (rtsim list dram_device), a .json device file, or a "
                     "DRAMsim3 .ini device config")
        ->capture_default_str();
    dram_cmd->add_option(
        "--set", dram.sets,
        "Override a device field, FIELD=VALUE (e.g. t_rcd=20, open_page=false); repeatable");
    dram_cmd->add_option("-o,--out", dram.out_dir, "Also write stats.json to this folder");
    dram_cmd->add_option("--commands", dram.commands_path,
                         "Also write every issued command to this CSV file "
                         "(cycle,command,channel,rank,bankgroup,bank,row)");
    dram_cmd->add_flag("-q,--quiet", dram.quiet, "No summary");

    std::string list_kind;
    bool list_json = false;
    CLI::App* list_cmd = app.add_subcommand(
        "list",
        "List the registered components (replacement policies, treelet schedulers, DRAM "
        "models, traversal modes, ...), their descriptions and parameters");
    list_cmd->add_option("kind", list_kind, "Only this kind (e.g. replacement)");
    list_cmd->add_flag("--json", list_json, "Print as JSON");

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const int code = app.exit(e);
        return code == 0 ? 0 : 2;
    }
    if (parse_only) return 0;

    try {
        if (*run_cmd) {
            if (!run.trace_path.empty()) refuse_workload_options_with_trace(run_cmd);
            run.workload.resolve();
            return rtsim::run_command(run);
        }
        if (*trace_cmd) {
            trace.workload.resolve();
            return rtsim::trace_command(trace);
        }
        if (*info_cmd) return rtsim::trace_info_command(info_path, info_json);
        if (*compare_cmd) return rtsim::compare_command(compare);
        if (*sweep_cmd) return rtsim::sweep_command(sweep);
        if (*report_cmd) return rtsim::report_command(report);
        if (*list_cmd) return rtsim::list_command(list_kind, list_json);
        if (*dram_cmd) return rtsim::dram_command(dram);
        if (*cfg_cmd) {
            if (cfg_doc) {
                fmt::print("{}", rtsim::config_reference_markdown());
                return 0;
            }
            const rtsim::Config c = rtsim::load_config(cfg_path, cfg_sets);
            fmt::print("{}\n", c.values.dump(2));
            return 0;
        }
    } catch (const rtsim::Interrupted& e) {
        return rtsim::report_interrupt(e.signal(), e.what());
    } catch (const rtsim::InputError& e) {
        return rtsim::report_failure(e.what(), true);
    } catch (const std::exception& e) {
        return rtsim::report_failure(e.what(), false);
    }
    return 2;
}

}  // namespace

int sc_main(int argc, char** argv) {
    return main_impl(argc, argv);
}

// Our own main (the linker prefers it to libsystemc's): the kernel prints a banner to stderr
// unless this variable is set before it starts, and stderr is for errors and progress.
int main(int argc, char** argv) {
    setenv("SYSTEMC_DISABLE_COPYRIGHT_MESSAGE", "1", 0);
    return sc_core::sc_elab_and_sim(argc, argv);
}

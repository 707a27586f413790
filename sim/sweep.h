// rtsim sweep: one workload simulated on every point of a grid of config values, each point a
// child `rtsim run` (a SystemC kernel runs once per process), up to -j at a time; then one
// results table.
//
// A sweep file is JSON:
//   {
//     "config": "../baseline.json",          base config, relative to the sweep file (optional)
//     "set": {"core.count": 8},              fixed overrides (optional)
//     "workload": {"scene": "builtin:cornell", "rays": "primary,ao", "res": "128x128",
//                  "seed": 1, ...}           rtsim run's ray options without dashes (optional)
//     "trace": "frame.rtt",                  or replay a trace (relative to the sweep file)
//     "vary": {"l1.size_kib": [16, 32, 64], "l1.ways": [2, 4]}   every combination
//     "pareto": ["cycles", "energy per ray (nJ)"]   two figures: plots/pareto.svg (optional)
//     "reference": true                      sampled sweeps: pair every point with the base
//   }                                        design (optional; below)
// With "reference", the base design (config and set, nothing varied; it must set
// sim.sampled=true and sim.sample_fast_forward=skip) first measures every unit of the frame
// into OUT/reference/, and every point runs with --reference OUT/reference
// (sim/sampling/reference.h): each point's figures come from the pair, with far narrower intervals
// for points near the base. The reference's sample with a point's plan is run by the first point
// with that plan and kept for the others (points starting together wait for it: sim/paired_run.cpp
// locks the plan). Besides the table, OUT/plots/ gets a figure per varied axis (each figure of
// merit against it, a line per value of the other axes) as SVG, and PNG where rsvg-convert is
// installed.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace rtsim {

struct SweepOptions {
    std::string path;     // the sweep file
    std::string out_dir;  // empty: a fresh folder under out/
    int jobs = 1;         // runs at once
    // Finish the sweep in out_dir: points whose folder holds a finished run of the same command
    // (stats.json beside a run.json with the same arguments) are not run again.
    bool resume = false;
    bool quiet = false;  // no progress line (it is shown on a terminal only anyway)
    // Through Slurm: one job array, a task per point (sbatch); the job script is written to
    // out_dir/slurm/. `wait`: until the job ends, then collect. `collect`: the table from the
    // points' folders, naming every point that did not finish. `task`: run that task's points
    // (what each array task runs). With `resume`, only missing or failed points are submitted.
    bool slurm = false, wait = false, collect = false;
    std::string partition, time_limit, mem;
    int max_parallel = 0;     // tasks at once (the array's %K); 0: Slurm's choice
    int points_per_task = 1;  // points one task runs in turn (several for short runs)
    int task = -1;            // run task `task`'s points (what each array task runs)
    // Two figure names (as the table names them) to draw the Pareto front of; overrides the
    // file's "pareto".
    std::vector<std::string> pareto;
};

// A sweep's points: the child command line of each, checked (configs resolved, workload parsed)
// before anything runs. Throws InputError naming the file and field.
struct SweepPoint {
    std::vector<std::pair<std::string, std::string>> values;  // varied key -> value text
    std::vector<std::string> run_args;  // `rtsim run` arguments, without --out
    std::string name;                   // folder name: index and values
};
struct SweepPlan {
    std::vector<std::string> keys;  // varied keys, in the file's order
    std::vector<SweepPoint> points;
    // "reference": the base design's run measuring every unit (its folder: "reference"); the
    // points' run_args get --reference once the sweep's folder is known (pair_with_reference).
    std::optional<SweepPoint> reference;
    std::vector<std::string> pareto;  // the file's two objectives, if it names them
};
// Checks that `names` are two figures of the shared list; throws InputError naming `where`.
void check_pareto(const std::vector<std::string>& names, const std::string& where);
SweepPlan plan_sweep(const std::string& path);
// With plan.reference: every point's run_args get --reference OUT_DIR/reference (absolute, so a
// Slurm task and the local collect agree).
void pair_with_reference(SweepPlan& plan, const std::string& out_dir);

// Runs the plan; writes each point's stats.json (and run.json, the arguments it ran with) under
// out_dir/<point>/ and the table to out_dir/results.json and results.csv. Returns the exit status.
int sweep_command(const SweepOptions& opt);

}  // namespace rtsim

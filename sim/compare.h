// rtsim compare: the figures of several runs' stats.json side by side, each relative to the
// first run, with the config fields and workload settings in which the runs differ.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/figures.h"
#include "sim/sampling/matched.h"

namespace rtsim {

struct CompareOptions {
    std::vector<std::string> paths;   // stats.json files, or folders holding one
    std::vector<std::string> labels;  // one per path; default A, B, C, ...
    std::string json_path;            // also write the comparison as JSON here
    std::string svg_path;             // also draw it (stall shares, bandwidth over time) here
};

// One run's stats as read from disk. Throws InputError naming the file for anything that is
// not a readable rtsim stats.json.
struct ComparedRun {
    std::string label, path;
    nlohmann::json stats;
};
ComparedRun load_compared_run(const std::string& path, const std::string& label);

struct Comparison {
    using Relative = FigureDef::Relative;
    struct Row {
        std::string name;
        Relative relative = Relative::Ratio;
        bool percent = false;              // a fraction shown as a percentage
        std::vector<double> values;        // per run; NaN where the run has no such figure
        std::vector<double> interval_pct;  // per run: a sampled run's 95% half-width; else NaN
    };
    std::vector<ComparedRun> runs;
    // Settings that differ between runs: "config: l1.size_kib" -> its value in each run.
    std::vector<std::pair<std::string, std::vector<std::string>>> differences;
    std::vector<Row> rows;
    // Each later run that is a matched pair with the first (sampled runs of one frame that
    // measured the same units): its differences from the first, each with an interval; or why
    // it is not a pair, where both runs were sampled.
    struct Matched {
        size_t run = 0;
        std::vector<MatchedDifference> differences;
        std::string why;
    };
    std::vector<Matched> matched;
};

Comparison compare_runs(std::vector<ComparedRun> runs);

// Rows of cells as aligned text columns: numbers right-aligned, the first column left-aligned
// when `first_left`.
std::string format_table(const std::vector<std::vector<std::string>>& rows, bool first_left);
std::string format_comparison(const Comparison& c);
nlohmann::json comparison_json(const Comparison& c);
// An SVG drawing: each run's stall shares as a stacked bar; when every run recorded a time series
// (sim.window_cycles), its L2->L1 and DRAM bandwidth and box-unit utilisation per window as lines.
std::string comparison_svg(const Comparison& c);

int compare_command(const CompareOptions& opt);

}  // namespace rtsim

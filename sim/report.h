// rtsim report: one self-contained HTML page (inline CSS and SVG; no script, no
// network) for a run, a comparison of runs, or a sweep: the config and workload, the summary
// figures with their confidence intervals when sampled, the stall breakdown, bandwidth over
// time, cache hit rates per level, energy per block, and a sweep's table and plots.
#pragma once

#include <string>
#include <vector>

namespace rtsim {

struct ReportOptions {
    std::vector<std::string> paths;   // run folders or stats.json files; or one sweep folder
    std::vector<std::string> labels;  // one per run; default A, B, C, ...
    std::string out_path = "report.html";
};

// The page for runs (paths to stats.json or run folders).
std::string runs_report_html(const std::vector<std::string>& paths,
                             const std::vector<std::string>& labels);
// The page for a sweep folder (its results.json and plots/).
std::string sweep_report_html(const std::string& dir);

int report_command(const ReportOptions& opt);

}  // namespace rtsim

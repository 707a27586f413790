#include "sim/report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>

#include "sim/compare.h"
#include "sim/config.h"
#include "sim/figures.h"
#include "sim/svg.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

const char* const kStyle =
    "body{font-family:sans-serif;margin:24px;color:#222;max-width:1200px}"
    "h1{font-size:22px}h2{font-size:17px;margin-top:28px;border-bottom:1px solid #ddd}"
    "table{border-collapse:collapse;margin:8px 0;font-size:13px}"
    "th,td{border:1px solid #ddd;padding:3px 8px;text-align:right}"
    "th:first-child,td:first-child{text-align:left}th{background:#f4f4f4}"
    ".note{color:#666;font-size:12px}.bar{display:inline-block;height:10px;background:#4e79a7}";

std::string h(const std::string& t) {
    return escape_xml(t);
}

std::string page(const std::string& title, const std::string& body) {
    return fmt::format(
        "<!DOCTYPE html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n<title>{}</title>\n"
        "<style>{}</style>\n</head>\n<body>\n<h1>{}</h1>\n{}</body>\n</html>\n",
        h(title), kStyle, h(title), body);
}

std::string table(const std::vector<std::vector<std::string>>& rows) {
    std::string t = "<table>\n";
    for (size_t r = 0; r < rows.size(); ++r) {
        t += "<tr>";
        for (const std::string& c : rows[r])
            t += fmt::format(r == 0 ? "<th>{}</th>" : "<td>{}</td>", h(c));
        t += "</tr>\n";
    }
    return t + "</table>\n";
}

std::string text(const json& j, const char* pointer) {
    const json::json_pointer p(pointer);
    if (!j.contains(p)) return "-";
    const json& v = j[p];
    return v.is_string() ? v.get<std::string>() : v.dump();
}

// Each run's figure, with its 95% interval when sampled, and relative to the first run.
std::string summary_table(const Comparison& c) {
    std::vector<std::vector<std::string>> rows;
    std::vector<std::string> head = {"figure"};
    for (const ComparedRun& r : c.runs) head.push_back(r.label);
    for (size_t k = 1; k < c.runs.size(); ++k)
        head.push_back(c.runs[k].label + " vs " + c.runs[0].label);
    rows.push_back(head);
    for (const Comparison::Row& row : c.rows) {
        bool any = false;
        for (double v : row.values) any = any || !std::isnan(v);
        if (!any) continue;
        std::vector<std::string> cells = {row.name};
        for (size_t k = 0; k < row.values.size(); ++k) {
            std::string cell = format_figure(row.values[k], row.percent);
            if (!std::isnan(row.interval_pct[k]))
                cell += fmt::format(" ± {:.2g}%", row.interval_pct[k]);
            cells.push_back(cell);
        }
        for (size_t k = 1; k < row.values.size(); ++k) {
            const double a = row.values[0], b = row.values[k];
            if (std::isnan(a) || std::isnan(b))
                cells.push_back("-");
            else if (row.relative == FigureDef::Relative::Points)
                cells.push_back(fmt::format("{:+.1f} pt", 100 * (b - a)));
            else
                cells.push_back(a != 0 ? fmt::format("{:.3f}x", b / a) : "-");
        }
        rows.push_back(cells);
    }
    return table(rows);
}

std::string caches_table(const Comparison& c) {
    std::vector<std::vector<std::string>> rows = {
        {"run", "cache", "accesses", "hits", "misses", "hit rate"}};
    for (const ComparedRun& r : c.runs) {
        if (!r.stats.contains("caches")) continue;
        for (const auto& [name, e] : r.stats["caches"].items()) {
            if (name.find('[') != std::string::npos) continue;  // per-core L1s: see l1_total
            rows.push_back({r.label, name, text(e, "/accesses"), text(e, "/hits"),
                            text(e, "/misses"),
                            e.contains("hit_rate") && e["hit_rate"].is_number()
                                ? format_figure(e["hit_rate"].get<double>(), true)
                                : "-"});
        }
    }
    return table(rows);
}

// Energy per block per ray, with a bar scaled to the largest.
std::string energy_section(const Comparison& c) {
    std::string out;
    for (const ComparedRun& r : c.runs) {
        if (!r.stats.contains("energy") || !r.stats["energy"].contains("blocks_pj")) continue;
        const json& e = r.stats["energy"];
        const double rays = std::max(1.0, number_at(r.stats, "/rays/total"));
        double most = 0;
        for (const auto& [b, v] : e["blocks_pj"].items()) most = std::max(most, v.get<double>());
        out += fmt::format(
            "<p><b>{}</b>: {:.4g} nJ per ray, {:.4g} W average</p>\n<table>"
            "<tr><th>block</th><th>nJ per ray</th><th>share</th><th></th></tr>\n",
            h(r.label), e.value("per_ray_nj", 0.0), e.value("average_power_w", 0.0));
        const double total = std::max(1e-30, e.value("total_pj", 0.0));
        for (const auto& [b, v] : e["blocks_pj"].items()) {
            const double pj = v.get<double>();
            out += fmt::format(
                "<tr><td>{}</td><td>{:.4g}</td><td>{:.1f}%</td><td style='text-align:left'>"
                "<span class='bar' style='width:{:.0f}px'></span></td></tr>\n",
                h(b), pj / rays / 1000.0, 100.0 * pj / total, most > 0 ? 240.0 * pj / most : 0.0);
        }
        out += "</table>\n";
    }
    return out.empty() ? "<p class='note'>No energy section in these stats.</p>\n" : out;
}

std::string runs_section(const Comparison& c) {
    std::vector<std::vector<std::string>> rows = {
        {"run", "stats", "config", "scene", "rays", "resolution", "fidelity", "rtsim"}};
    for (const ComparedRun& r : c.runs)
        rows.push_back({r.label, r.path, text(r.stats, "/config/name"),
                        text(r.stats, "/scene/name"), text(r.stats, "/workload/rays"),
                        text(r.stats, "/workload/resolution"),
                        text(r.stats, "/config/sim/fidelity"), text(r.stats, "/rtsim_version")});
    std::string out = table(rows);
    if (c.runs.size() > 1) {
        std::vector<std::vector<std::string>> diff = {{"setting"}};
        for (const ComparedRun& r : c.runs) diff[0].push_back(r.label);
        for (const auto& [name, vals] : c.differences) {
            std::vector<std::string> row = {name};
            row.insert(row.end(), vals.begin(), vals.end());
            diff.push_back(row);
        }
        out += diff.size() > 1 ? "<h2>Where the runs differ</h2>\n" + table(diff)
                               : "<p class='note'>The runs' configs and workloads are the same."
                                 "</p>\n";
    }
    return out;
}

// One run's workload and config, field by field (at the end of its page: they are long).
std::string settings_section(const Comparison& c) {
    std::string out;
    if (c.runs.size() == 1) {
        std::vector<std::vector<std::string>> cfg = {{"config field", "value"}};
        std::function<void(const json&, const std::string&)> walk = [&](const json& j,
                                                                        const std::string& p) {
            for (const auto& [k, v] : j.items()) {
                const std::string path = p.empty() ? k : p + "." + k;
                if (v.is_object())
                    walk(v, path);
                else
                    cfg.push_back({path, v.is_string() ? v.get<std::string>() : v.dump()});
            }
        };
        if (c.runs[0].stats.contains("config")) walk(c.runs[0].stats["config"], "");
        std::vector<std::vector<std::string>> wl = {{"workload field", "value"}};
        if (c.runs[0].stats.contains("workload"))
            for (const auto& [k, v] : c.runs[0].stats["workload"].items())
                wl.push_back({k, v.is_string() ? v.get<std::string>() : v.dump()});
        out += "<h2>Workload</h2>\n" + table(wl) + "<h2>Config</h2>\n" + table(cfg);
    }
    return out;
}

std::string slurp(const fs::path& p) {
    return read_file_text(p.string()).value_or("");
}

}  // namespace

std::string runs_report_html(const std::vector<std::string>& paths,
                             const std::vector<std::string>& labels) {
    std::vector<ComparedRun> runs;
    for (size_t i = 0; i < paths.size(); ++i) {
        const std::string label = i < labels.size() ? labels[i]
                                                    : (i < 26 ? std::string(1, char('A' + i))
                                                              : fmt::format("R{}", i + 1));
        runs.push_back(load_compared_run(paths[i], label));
    }
    const Comparison c = compare_runs(std::move(runs));
    std::string body = "<h2>Runs</h2>\n" + runs_section(c);
    body += "<h2>Summary</h2>\n";
    bool sampled = false;
    for (const ComparedRun& r : c.runs) sampled = sampled || r.stats.contains("sampling");
    if (sampled)
        body +=
            "<p class='note'>Sampled runs show their 95% confidence interval (± half-width)."
            "</p>\n";
    body += summary_table(c);
    body += "<h2>Stall breakdown and bandwidth over time</h2>\n";
    body +=
        "<p class='note'>Ray-slot cycles by cause; bandwidth per window when the runs set "
        "sim.window_cycles.</p>\n";
    body += comparison_svg(c);
    body += "<h2>Cache hit rates</h2>\n";
    if (sampled)
        body +=
            "<p class='note'>Counts of the rays simulated in detail (a sampled run's estimates "
            "are in the summary).</p>\n";
    body += caches_table(c);
    body += "<h2>Energy per block</h2>\n" + energy_section(c);
    body += settings_section(c);
    const std::string title = c.runs.size() == 1
                                  ? "RTSim run: " + c.runs[0].path
                                  : fmt::format("RTSim comparison of {} runs", c.runs.size());
    return page(title, body);
}

std::string sweep_report_html(const std::string& dir) {
    const fs::path results = fs::path(dir) / "results.json";
    const json r = read_json_file(results.string(), "a sweep's results.json");
    if (!r.is_object() || !r.contains("points") || !r["points"].is_array() || !r.contains("keys"))
        throw InputError(
            fmt::format("{}: not a sweep's results.json (no keys and points)", results.string()));
    std::vector<std::vector<std::string>> rows;
    std::vector<std::string> head;
    for (const auto& k : r["keys"]) head.push_back(k.get<std::string>());
    std::vector<std::string> figs;
    for (const FigureDef& f : figure_list())
        if (f.sweep_table || f.name == "energy per ray (nJ)") figs.push_back(f.name);
    head.insert(head.end(), figs.begin(), figs.end());
    rows.push_back(head);
    for (const json& p : r["points"]) {
        std::vector<std::string> row;
        for (const auto& k : r["keys"])
            row.push_back(text(p["values"], ("/" + k.get<std::string>()).c_str()));
        for (const std::string& f : figs) {
            const json& v = p["figures"].contains(f) ? p["figures"][f] : json(nullptr);
            bool percent = false;
            for (const FigureDef& d : figure_list())
                if (d.name == f) percent = d.percent;
            row.push_back(v.is_number() ? format_figure(v.get<double>(), percent) : "-");
        }
        rows.push_back(row);
    }
    std::string body = fmt::format(
        "<p>Sweep file: {}; {} points; varied: {}.</p>\n", h(r.value("sweep", std::string("?"))),
        r["points"].size(),
        h(fmt::format("{}", fmt::join(head.begin(), head.begin() + long(r["keys"].size()), ", "))));
    body += "<h2>Results</h2>\n" + table(rows);
    const fs::path plots = fs::path(dir) / "plots";
    std::vector<fs::path> svgs;
    if (fs::is_directory(plots))
        for (const auto& e : fs::directory_iterator(plots))
            if (e.path().extension() == ".svg") svgs.push_back(e.path());
    std::sort(svgs.begin(), svgs.end());
    if (!svgs.empty()) body += "<h2>Plots</h2>\n";
    for (const fs::path& p : svgs) body += "<div>" + slurp(p) + "</div>\n";
    return page("RTSim sweep: " + dir, body);
}

int report_command(const ReportOptions& opt) {
    if (opt.paths.empty())
        throw InputError("report: needs a run folder, stats.json or sweep folder");
    if (!opt.labels.empty() && opt.labels.size() != opt.paths.size())
        throw InputError(
            fmt::format("--labels: {} labels for {} runs", opt.labels.size(), opt.paths.size()));
    const bool sweep = fs::is_regular_file(fs::path(opt.paths[0]) / "results.json");
    if (sweep && opt.paths.size() != 1)
        throw InputError(fmt::format("{}: a sweep folder is reported alone", opt.paths[0]));
    const std::string html =
        sweep ? sweep_report_html(opt.paths[0]) : runs_report_html(opt.paths, opt.labels);
    write_file_atomically(opt.out_path, html);
    fmt::print("report written to {}\n", opt.out_path);
    return 0;
}

}  // namespace rtsim

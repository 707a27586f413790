#include "sim/compare.h"

#include <fmt/format.h>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>

#include "sim/config.h"
#include "sim/figures.h"
#include "sim/stats_report.h"
#include "sim/svg.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// "a.b.c" -> value text, for every leaf of a config object.
void flatten(const json& j, const std::string& prefix, std::map<std::string, std::string>& out) {
    if (j.is_object()) {
        for (const auto& [k, v] : j.items()) flatten(v, prefix.empty() ? k : prefix + "." + k, out);
    } else {
        out[prefix] = j.is_string() ? j.get<std::string>() : j.dump();
    }
}

}  // namespace

namespace {

std::string format_relative(double first, double v, const Comparison::Row& row) {
    if (std::isnan(first) || std::isnan(v)) return "-";
    if (row.relative == Comparison::Relative::Points)
        return fmt::format("{:+.1f} pts", 100 * (v - first));
    if (first == 0) return v == 0 ? "1.000x" : "-";
    return fmt::format("{:.3f}x", v / first);
}

}  // namespace

ComparedRun load_compared_run(const std::string& path, const std::string& label) {
    std::string file = path;
    std::error_code ec;
    if (fs::is_directory(path, ec)) file = (fs::path(path) / "stats.json").string();
    ComparedRun run{label, file, read_json_file(file, "stats file")};
    for (const char* key : {"total_cycles", "rays", "config"})
        if (!run.stats.is_object() || !run.stats.contains(key))
            throw InputError(fmt::format("{}: not an rtsim stats.json (no \"{}\")", file, key));
    return run;
}

Comparison compare_runs(std::vector<ComparedRun> runs) {
    Comparison c;
    c.runs = std::move(runs);
    // Settings in which the runs differ: config fields, then what was simulated.
    std::vector<std::map<std::string, std::string>> settings(c.runs.size());
    for (size_t r = 0; r < c.runs.size(); ++r) {
        const json& s = c.runs[r].stats;
        std::map<std::string, std::string> config;
        flatten(s["config"], "", config);
        for (auto& [k, v] : config) settings[r]["config: " + k] = v;
        if (s.contains("workload")) {
            std::map<std::string, std::string> workload;
            flatten(s["workload"], "", workload);
            for (auto& [k, v] : workload) settings[r]["workload: " + k] = v;
        }
        for (const char* k : {"name", "hash"})
            if (s.contains("scene") && s["scene"].contains(k))
                settings[r][std::string("scene: ") + k] = s["scene"][k].is_string()
                                                              ? s["scene"][k].get<std::string>()
                                                              : s["scene"][k].dump();
    }
    std::map<std::string, bool> keys;
    for (const auto& m : settings)
        for (const auto& kv : m) keys[kv.first] = true;
    for (const auto& [key, unused] : keys) {
        std::vector<std::string> values;
        bool differs = false;
        for (const auto& m : settings) {
            const auto it = m.find(key);
            values.push_back(it == m.end() ? "-" : it->second);
            differs = differs || values.back() != values.front();
        }
        if (differs) c.differences.emplace_back(key, std::move(values));
    }
    for (const FigureDef& m : figure_list()) {
        Comparison::Row row{m.name, m.relative, m.percent, {}, {}};
        bool any = false;
        for (const auto& run : c.runs) {
            row.values.push_back(m.value(run.stats));
            row.interval_pct.push_back(interval_pct(m, run.stats));
            any = any || !std::isnan(row.values.back());
        }
        if (any) c.rows.push_back(std::move(row));
    }
    const json& first = c.runs[0].stats;
    for (size_t r = 1; r < c.runs.size(); ++r) {
        const json& s = c.runs[r].stats;
        if (!first.contains("sampling") || !s.contains("sampling")) continue;
        Comparison::Matched m;
        m.run = r;
        m.differences = matched_differences(first, fs::path(c.runs[0].path).parent_path(), s,
                                            fs::path(c.runs[r].path).parent_path(), &m.why);
        c.matched.push_back(std::move(m));
    }
    return c;
}

namespace {

// "+3.2% (+2.9% to +3.5%)": a difference relative to the first run's figure.
std::string format_difference(const MatchedDifference& d) {
    if (d.base == 0) return "-";
    const double v = 100 * d.difference.value / d.base;
    if (!std::isfinite(d.difference.half_width)) return fmt::format("{:+.2f}% (no interval)", v);
    const double h = 100 * d.difference.half_width / std::fabs(d.base);
    return fmt::format("{:+.2f}% ({:+.2f}% to {:+.2f}%)", v, v - h, v + h);
}

}  // namespace

std::string format_comparison(const Comparison& c) {
    std::string out;
    size_t label_width = 0;
    for (const auto& run : c.runs) label_width = std::max(label_width, run.label.size());
    for (const auto& run : c.runs)
        out += fmt::format("{:<{}}  {}\n", run.label, label_width, run.path);
    if (c.differences.empty()) {
        out += "\nThe runs share every config field and workload setting.\n";
    } else {
        out += "\nDiffering settings:\n";
        for (const auto& [key, values] : c.differences) {
            std::string line = fmt::format("  {:<34} ", key);
            for (size_t r = 0; r < values.size(); ++r)
                line += fmt::format("{}{}", r ? " | " : "", values[r]);
            out += line + "\n";
        }
    }
    // Columns: metric, each run's value, then each later run relative to the first.
    std::vector<std::vector<std::string>> table;
    std::vector<std::string> head{"metric"};
    for (const auto& run : c.runs) head.push_back(run.label);
    for (size_t r = 1; r < c.runs.size(); ++r)
        head.push_back(fmt::format("{} vs {}", c.runs[r].label, c.runs[0].label));
    table.push_back(head);
    for (const auto& row : c.rows) {
        std::vector<std::string> cells{row.name};
        for (size_t r = 0; r < row.values.size(); ++r) {
            std::string cell = format_figure(row.values[r], row.percent);
            // A sampled run's estimate carries its interval.
            if (!std::isnan(row.interval_pct[r]))
                cell += fmt::format(" +-{:.1f}%", row.interval_pct[r]);
            cells.push_back(std::move(cell));
        }
        for (size_t r = 1; r < row.values.size(); ++r)
            cells.push_back(format_relative(row.values[0], row.values[r], row));
        table.push_back(std::move(cells));
    }
    out += "\n" + format_table(table, true);
    if (!c.matched.empty()) {
        out += fmt::format(
            "\nMatched samples (the same units in both runs): difference from {}, with its 95% "
            "interval\n",
            c.runs[0].label);
        for (const auto& m : c.matched) {
            if (m.differences.empty()) {
                out += fmt::format("  {:<{}}  not a matched pair: {}\n", c.runs[m.run].label,
                                   label_width, m.why);
                continue;
            }
            for (const auto& d : m.differences)
                out += fmt::format("  {:<{}}  {:<11} {}\n", c.runs[m.run].label, label_width,
                                   d.figure, format_difference(d));
        }
    }
    out +=
        "\nvs: ratio to the first run, or the difference in percentage points (pts).\n"
        "host: wall-clock timing of the machine that ran the run, not a simulated result.\n"
        "+-: a sampled run's estimate and the half-width of its 95% interval (relative).\n";
    return out;
}

std::string format_table(const std::vector<std::vector<std::string>>& rows, bool first_left) {
    std::vector<size_t> width;
    for (const auto& cells : rows) {
        width.resize(std::max(width.size(), cells.size()), 0);
        for (size_t k = 0; k < cells.size(); ++k) width[k] = std::max(width[k], cells[k].size());
    }
    std::string out;
    for (const auto& cells : rows) {
        std::string line;
        for (size_t k = 0; k < cells.size(); ++k) {
            if (k) line += "  ";
            line += k == 0 && first_left ? fmt::format("{:<{}}", cells[k], width[k])
                                         : fmt::format("{:>{}}", cells[k], width[k]);
        }
        out += line + "\n";
    }
    return out;
}

json comparison_json(const Comparison& c) {
    json out;
    out["runs"] = json::array();
    for (const auto& run : c.runs)
        out["runs"].push_back({{"label", run.label}, {"path", run.path}});
    out["differences"] = json::object();
    for (const auto& [key, values] : c.differences) out["differences"][key] = values;
    out["metrics"] = json::array();
    for (const auto& row : c.rows) {
        json values = json::array(), relative = json::array();
        for (size_t r = 0; r < row.values.size(); ++r) {
            const double v = row.values[r], first = row.values[0];
            values.push_back(std::isnan(v) ? json(nullptr) : json(v));
            const bool known = !std::isnan(v) && !std::isnan(first);
            if (row.relative == Comparison::Relative::Points)
                relative.push_back(known ? json(v - first) : json(nullptr));
            else
                relative.push_back(known && first != 0 ? json(v / first) : json(nullptr));
        }
        out["metrics"].push_back(
            {{"name", row.name},
             {"values", values},
             {"relative", relative},
             {"relative_kind",
              row.relative == Comparison::Relative::Points ? "difference" : "ratio"}});
    }
    if (!c.matched.empty()) {
        out["matched"] = json::array();
        for (const auto& m : c.matched) {
            json j = {{"label", c.runs[m.run].label}};
            if (m.differences.empty()) j["not_matched"] = m.why;
            for (const auto& d : m.differences) {
                const double h = d.difference.half_width;
                j["differences"][d.figure] = {
                    {"value", d.difference.value},
                    {"lo", std::isfinite(h) ? json(d.difference.value - h) : json(nullptr)},
                    {"hi", std::isfinite(h) ? json(d.difference.value + h) : json(nullptr)},
                    {"base", d.base}};
            }
            out["matched"].push_back(std::move(j));
        }
    }
    return out;
}

namespace {

// One per stall cause (stall_causes() order).
// (no_work, the last cause, always light grey.)
const char* const kStallColours[] = {"#8c8c8c", "#4e79a7", "#76b7b2", "#e15759", "#f28e2b",
                                     "#edc948", "#b07aa1", "#59a14f", "#ff9da7", "#9c755f"};
const char* stall_colour(size_t k, size_t causes) {
    if (k + 1 == causes) return "#dddddd";
    return kStallColours[k % std::size(kStallColours)];
}
const char* const kRunColours[] = {"#4e79a7", "#e15759", "#59a14f", "#f28e2b",
                                   "#b07aa1", "#76b7b2", "#edc948", "#9c755f"};

// One line chart: `series` values of every run per window, x in cycles.
void line_chart(std::string& svg, const Comparison& c, const char* series, const char* title,
                double top) {
    const double x0 = 70, w = 560, h = 150;
    double peak = 0, last_cycle = 0;
    for (const auto& run : c.runs) {
        const json& ts = run.stats["time_series"];
        for (const auto& v : ts[series]) peak = std::max(peak, v.get<double>());
        last_cycle = std::max(last_cycle, ts["window_cycles"].get<double>() * ts[series].size());
    }
    if (peak <= 0) peak = 1;
    svg += fmt::format("<text x='{}' y='{}' font-weight='bold'>{}</text>\n", x0, top - 8,
                       escape_xml(title));
    svg += fmt::format("<rect x='{}' y='{}' width='{}' height='{}' fill='none' stroke='#999'/>\n",
                       x0, top, w, h);
    svg += fmt::format("<text x='{}' y='{}' text-anchor='end'>{}</text>\n", x0 - 4, top + 10,
                       format_figure(peak, false));
    svg += fmt::format("<text x='{}' y='{}' text-anchor='end'>0</text>\n", x0 - 4, top + h);
    svg += fmt::format("<text x='{}' y='{}' text-anchor='end'>{} cycles</text>\n", x0 + w,
                       top + h + 14, format_figure(last_cycle, false));
    for (size_t r = 0; r < c.runs.size(); ++r) {
        const json& ts = c.runs[r].stats["time_series"];
        const double window = ts["window_cycles"].get<double>();
        std::string points;
        for (size_t k = 0; k < ts[series].size(); ++k)
            points += fmt::format("{:.1f},{:.1f} ", x0 + w * (k + 0.5) * window / last_cycle,
                                  top + h - h * ts[series][k].get<double>() / peak);
        svg += fmt::format("<polyline points='{}' fill='none' stroke='{}' stroke-width='1.5'/>\n",
                           points, kRunColours[r % 8]);
    }
}

}  // namespace

std::string comparison_svg(const Comparison& c) {
    const double x0 = 110, bar_w = 520, bar_h = 22;
    // Each chart when every run recorded its series.
    auto all_have = [&](const char* name) {
        bool all = !c.runs.empty();
        for (const auto& run : c.runs)
            all =
                all && run.stats.contains("time_series") && run.stats["time_series"].contains(name);
        return all;
    };
    const bool series = all_have("l2_to_l1_gbps") && all_have("dram_gbps");
    const bool util = all_have("box_unit_utilization");
    const double bars_h = 60 + c.runs.size() * (bar_h + 8) + 56;  // a legend of up to 2 rows
    const double height = bars_h + (series ? 2 * 200 + 30 : 0) + (util ? 200 : 0);
    const std::vector<std::string> causes = stall_causes();
    std::string svg = fmt::format(
        "<svg xmlns='http://www.w3.org/2000/svg' width='680' height='{:.0f}' "
        "font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' "
        "fill='white'/>\n<text x='10' y='24' font-size='15' font-weight='bold'>Ray-slot cycles "
        "by stall cause</text>\n",
        height);
    for (size_t r = 0; r < c.runs.size(); ++r) {
        const double y = 44 + r * (bar_h + 8);
        svg += fmt::format("<text x='{}' y='{}' text-anchor='end' fill='{}'>{}</text>\n", x0 - 8,
                           y + 15, kRunColours[r % 8], escape_xml(c.runs[r].label));
        double x = x0;
        for (size_t k = 0; k < causes.size(); ++k) {
            const double share =
                number_at(c.runs[r].stats, ("/stalls/total/share/" + causes[k]).c_str());
            if (!(share > 0)) continue;
            svg += fmt::format(
                "<rect x='{:.1f}' y='{:.1f}' width='{:.1f}' height='{}' fill='{}'><title>{} "
                "{:.1f}%</title></rect>\n",
                x, y, bar_w * share, bar_h, stall_colour(k, causes.size()),
                stall_cause_label(causes[k]), 100 * share);
            x += bar_w * share;
        }
    }
    double legend_y = 44 + c.runs.size() * (bar_h + 8) + 14;
    double legend_x = 10;
    for (size_t k = 0; k < causes.size(); ++k) {
        const std::string name = stall_cause_label(causes[k]);
        if (legend_x + 13 + 7.0 * double(name.size()) > 670) {  // on to a second row
            legend_x = 10;
            legend_y += 16;
        }
        svg += fmt::format("<rect x='{}' y='{}' width='10' height='10' fill='{}'/>\n", legend_x,
                           legend_y - 9, stall_colour(k, causes.size()));
        svg += fmt::format("<text x='{}' y='{}'>{}</text>\n", legend_x + 13, legend_y, name);
        legend_x += 13 + 7.0 * double(name.size()) + 12;  // about 7 pixels per character
    }
    if (series) {
        line_chart(svg, c, "l2_to_l1_gbps", "L2 -> L1 GB/s per window", bars_h + 30);
        line_chart(svg, c, "dram_gbps", "DRAM GB/s per window", bars_h + 230);
    }
    if (util)
        line_chart(svg, c, "box_unit_utilization", "Box unit utilisation per window",
                   bars_h + 30 + (series ? 400 : 0));
    svg += "</svg>\n";
    return svg;
}

int compare_command(const CompareOptions& opt) {
    if (opt.paths.size() < 2)
        throw InputError(
            fmt::format("compare: needs at least two stats files, got {}", opt.paths.size()));
    if (!opt.labels.empty() && opt.labels.size() != opt.paths.size())
        throw InputError(fmt::format("--labels: {} labels for {} stats files", opt.labels.size(),
                                     opt.paths.size()));
    std::vector<ComparedRun> runs;
    for (size_t i = 0; i < opt.paths.size(); ++i) {
        const std::string label = opt.labels.empty() ? (i < 26 ? std::string(1, char('A' + i))
                                                               : fmt::format("R{}", i + 1))
                                                     : opt.labels[i];
        runs.push_back(load_compared_run(opt.paths[i], label));
    }
    const Comparison c = compare_runs(std::move(runs));
    if (!opt.json_path.empty()) write_file_atomically(opt.json_path, comparison_json(c).dump(1));
    if (!opt.svg_path.empty()) write_file_atomically(opt.svg_path, comparison_svg(c));
    fmt::print("{}", format_comparison(c));
    return 0;
}

}  // namespace rtsim

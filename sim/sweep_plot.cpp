#include "sim/sweep_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>

#include "sim/figures.h"
#include "sim/shell.h"
#include "sim/svg.h"
#include "workloads/output_file.h"

namespace rtsim {

namespace fs = std::filesystem;

namespace {

const char* const kColours[] = {"#4e79a7", "#e15759", "#59a14f", "#f28e2b", "#b07aa1",
                                "#76b7b2", "#edc948", "#9c755f", "#ff9da7", "#bab0ac"};

bool as_number(const std::string& s, double& v) {
    char* end = nullptr;
    v = std::strtod(s.c_str(), &end);
    return end != s.c_str() && *end == '\0';
}

// A key as a label: its last part ("l1.size_kib" -> "size_kib") unless that is ambiguous.
std::string short_key(const std::vector<std::string>& keys, const std::string& key) {
    const std::string tail = key.substr(key.rfind('.') + 1);
    for (const std::string& k : keys)
        if (k != key && k.substr(k.rfind('.') + 1) == tail) return key;
    return tail;
}

// The distinct values of key k, numerically sorted when all are numbers, else in first-seen order.
std::vector<std::string> axis_values(const SweepPlotData& d, size_t k) {
    std::vector<std::string> vals;
    for (const auto& p : d.values)
        if (std::find(vals.begin(), vals.end(), p[k].second) == vals.end())
            vals.push_back(p[k].second);
    bool numeric = true;
    double x;
    for (const std::string& v : vals) numeric = numeric && as_number(v, x);
    if (numeric)
        std::stable_sort(vals.begin(), vals.end(), [](const std::string& a, const std::string& b) {
            return std::strtod(a.c_str(), nullptr) < std::strtod(b.c_str(), nullptr);
        });
    return vals;
}

std::string point_label(const SweepPlotData& d, size_t p, size_t skip) {
    std::string s;
    for (size_t k = 0; k < d.keys.size(); ++k)
        if (k != skip)
            s += (s.empty() ? "" : ", ") + short_key(d.keys, d.keys[k]) + "=" +
                 d.values[p][k].second;
    return s;
}

struct Series {
    std::string label;
    std::vector<std::pair<size_t, double>> points;  // x index, value
};

// One panel: `title` against the categorical x values, a polyline per series with its label at
// its right end (labels pushed apart so none overlap).
void draw_panel(std::string& svg, double x0, double y0, double w, double h,
                const std::string& title, const std::vector<std::string>& xs,
                const std::vector<Series>& series, bool percent) {
    const double left = x0 + 64, right = x0 + w - 96, top = y0 + 30, bottom = y0 + h - 38;
    double lo = INFINITY, hi = -INFINITY;
    for (const Series& s : series)
        for (const auto& pt : s.points) {
            lo = std::min(lo, pt.second);
            hi = std::max(hi, pt.second);
        }
    if (!(lo <= hi)) return;
    const double data_lo = lo, data_hi = hi;
    if (hi - lo < 1e-12 * std::max(1.0, std::fabs(hi))) {
        const double pad = std::max(std::fabs(hi) * 0.1, percent ? 0.01 : 1.0);
        lo -= pad;
        hi += pad;
    }
    const double span = hi - lo;
    lo -= span * 0.06;
    hi += span * 0.06;
    auto X = [&](size_t i) {
        return xs.size() > 1 ? left + (right - left) * double(i) / double(xs.size() - 1)
                             : (left + right) / 2;
    };
    auto Y = [&](double v) { return bottom - (bottom - top) * (v - lo) / (hi - lo); };
    svg += fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='13' font-weight='bold'>{}</text>\n",
                       x0 + 8, y0 + 18, escape_xml(title));
    // Three ticks: bottom, middle, top of the data (one when every value is the same).
    for (int t = data_hi > data_lo ? 0 : 2; t <= 2; ++t) {
        const double v = data_lo + (data_hi - data_lo) * t / 2.0;
        const double y = Y(v);
        svg += fmt::format(
            "<line x1='{:.1f}' y1='{:.1f}' x2='{:.1f}' y2='{:.1f}' stroke='#e6e6e6'/>\n"
            "<text x='{:.1f}' y='{:.1f}' font-size='10' text-anchor='end' fill='#555'>{}</text>\n",
            left, y, right, y, left - 4, y + 3, escape_xml(format_figure(v, percent)));
    }
    svg +=
        fmt::format("<line x1='{0:.1f}' y1='{1:.1f}' x2='{2:.1f}' y2='{1:.1f}' stroke='#888'/>\n",
                    left, bottom, right);
    for (size_t i = 0; i < xs.size(); ++i)
        svg += fmt::format(
            "<text x='{:.1f}' y='{:.1f}' font-size='10' text-anchor='middle' "
            "fill='#333'>{}</text>\n",
            X(i), bottom + 14, escape_xml(xs[i]));
    // Labels at the lines' ends, pushed apart by at least 11 px.
    std::vector<std::pair<double, size_t>> ends;
    for (size_t s = 0; s < series.size(); ++s)
        if (!series[s].points.empty()) ends.push_back({Y(series[s].points.back().second), s});
    std::sort(ends.begin(), ends.end());
    for (size_t k = 1; k < ends.size(); ++k)
        ends[k].first = std::max(ends[k].first, ends[k - 1].first + 11);
    std::map<size_t, double> label_y;
    for (const auto& [y, s] : ends) label_y[s] = y;
    for (size_t s = 0; s < series.size(); ++s) {
        const Series& ser = series[s];
        if (ser.points.empty()) continue;
        const char* colour = kColours[s % std::size(kColours)];
        std::string pts;
        for (const auto& [i, v] : ser.points) pts += fmt::format("{:.1f},{:.1f} ", X(i), Y(v));
        svg += fmt::format("<polyline points='{}' fill='none' stroke='{}' stroke-width='2'/>\n",
                           pts, colour);
        for (const auto& [i, v] : ser.points)
            svg += fmt::format("<circle cx='{:.1f}' cy='{:.1f}' r='3' fill='{}'/>\n", X(i), Y(v),
                               colour);
        if (!ser.label.empty())
            svg += fmt::format("<text x='{:.1f}' y='{:.1f}' font-size='10' fill='{}'>{}</text>\n",
                               X(ser.points.back().first) + 7, label_y[s] + 3, colour,
                               escape_xml(ser.label));
    }
}

}  // namespace

bool figure_higher_is_better(const std::string& name) {
    static const char* const higher[] = {"simulated Mrays/s",
                                         "L1 hit rate",
                                         "L2 hit rate",
                                         "DRAM row hit rate",
                                         "packet lane utilisation",
                                         "rays per treelet batch",
                                         "host: simulated Mrays/host s"};
    for (const char* h : higher)
        if (name == h) return true;
    return name.find("utilisation") != std::string::npos;
}

std::string sweep_axis_svg(const SweepPlotData& d, size_t key) {
    const std::vector<std::string> xs = axis_values(d, key);
    std::vector<size_t> plotted;
    for (size_t f = 0; f < d.figure_names.size(); ++f) {
        if (!d.panel.empty() && !d.panel[f]) continue;
        bool any = false;
        for (const auto& p : d.figures) any = any || std::isfinite(p[f]);
        if (any) plotted.push_back(f);
    }
    if (plotted.empty() || xs.empty()) return {};
    // Series: the points grouped by the other axes' values, in first-seen order.
    std::vector<std::string> labels;
    std::vector<size_t> series_of(d.values.size());
    for (size_t p = 0; p < d.values.size(); ++p) {
        const std::string l = point_label(d, p, key);
        auto it = std::find(labels.begin(), labels.end(), l);
        series_of[p] = size_t(it - labels.begin());
        if (it == labels.end()) labels.push_back(l);
    }
    const size_t cols = std::min<size_t>(3, plotted.size());
    const size_t rows = (plotted.size() + cols - 1) / cols;
    const double pw = 340, ph = 240, head = 52;
    const double width = cols * pw + 20, height = head + rows * ph + 10;
    std::string others;
    for (size_t k = 0; k < d.keys.size(); ++k)
        if (k != key) others += (others.empty() ? "" : ", ") + d.keys[k];
    std::string svg = fmt::format(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{:.0f}' height='{:.0f}' "
        "font-family='sans-serif'>\n<rect width='100%' height='100%' fill='white'/>\n"
        "<text x='10' y='22' font-size='16' font-weight='bold'>Each figure of merit against "
        "{}</text>\n<text x='10' y='40' font-size='12' fill='#555'>{}</text>\n",
        width, height, escape_xml(d.keys[key]),
        escape_xml(others.empty()
                       ? "one point per value"
                       : "one line per value of " + others + ", labelled at its right end"));
    for (size_t n = 0; n < plotted.size(); ++n) {
        const size_t f = plotted[n];
        std::vector<Series> series(labels.size());
        for (size_t s = 0; s < labels.size(); ++s) series[s].label = labels[s];
        for (size_t p = 0; p < d.values.size(); ++p) {
            const double v = d.figures[p][f];
            if (!std::isfinite(v)) continue;
            const size_t xi =
                size_t(std::find(xs.begin(), xs.end(), d.values[p][key].second) - xs.begin());
            series[series_of[p]].points.push_back({xi, v});
        }
        for (Series& s : series) std::sort(s.points.begin(), s.points.end());
        const std::string dir = figure_higher_is_better(d.figure_names[f]) ? " (higher is better)"
                                                                           : " (lower is better)";
        draw_panel(svg, 10 + double(n % cols) * pw, head + double(n / cols) * ph, pw, ph,
                   d.figure_names[f] + dir, xs, series, d.figure_percent[f]);
    }
    return svg + "</svg>\n";
}

std::vector<size_t> pareto_front(const std::vector<std::pair<double, double>>& pts, bool a_higher,
                                 bool b_higher) {
    // Better-or-equal on both and strictly better on one beats a point.
    auto better = [](double x, double y, bool higher) { return higher ? x > y : x < y; };
    std::vector<size_t> front;
    for (size_t i = 0; i < pts.size(); ++i) {
        if (!std::isfinite(pts[i].first) || !std::isfinite(pts[i].second)) continue;
        bool beaten = false;
        for (size_t j = 0; j < pts.size() && !beaten; ++j) {
            if (j == i || !std::isfinite(pts[j].first) || !std::isfinite(pts[j].second)) continue;
            const bool ge_a = !better(pts[i].first, pts[j].first, a_higher);
            const bool ge_b = !better(pts[i].second, pts[j].second, b_higher);
            const bool gt = better(pts[j].first, pts[i].first, a_higher) ||
                            better(pts[j].second, pts[i].second, b_higher);
            beaten = ge_a && ge_b && gt;
        }
        if (!beaten) front.push_back(i);
    }
    std::sort(front.begin(), front.end(), [&](size_t x, size_t y) {
        return pts[x].first < pts[y].first || (pts[x].first == pts[y].first && x < y);
    });
    return front;
}

std::string sweep_pareto_svg(const SweepPlotData& d, size_t a, size_t b, bool a_higher,
                             bool b_higher) {
    std::vector<std::pair<double, double>> pts;
    for (const auto& p : d.figures) pts.push_back({p[a], p[b]});
    const std::vector<size_t> front = pareto_front(pts, a_higher, b_higher);
    double xlo = INFINITY, xhi = -INFINITY, ylo = INFINITY, yhi = -INFINITY;
    for (const auto& [x, y] : pts)
        if (std::isfinite(x) && std::isfinite(y)) {
            xlo = std::min(xlo, x);
            xhi = std::max(xhi, x);
            ylo = std::min(ylo, y);
            yhi = std::max(yhi, y);
        }
    if (!(xlo <= xhi)) return {};
    auto widen = [](double& lo, double& hi) {
        const double span = hi - lo > 0 ? hi - lo : std::max(1e-9, std::fabs(hi) * 0.1);
        lo -= span * 0.08;
        hi += span * 0.08;
    };
    widen(xlo, xhi);
    widen(ylo, yhi);
    const double W = 760, H = 520, left = 90, right = W - 200, top = 60, bottom = H - 60;
    auto X = [&](double v) { return left + (right - left) * (v - xlo) / (xhi - xlo); };
    auto Y = [&](double v) { return bottom - (bottom - top) * (v - ylo) / (yhi - ylo); };
    const auto dir = [](bool higher) { return higher ? "higher is better" : "lower is better"; };
    std::string svg = fmt::format(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{:.0f}' height='{:.0f}' "
        "font-family='sans-serif'>\n<rect width='100%' height='100%' fill='white'/>\n"
        "<text x='10' y='22' font-size='16' font-weight='bold'>Pareto front: {} against {}"
        "</text>\n<text x='10' y='40' font-size='12' fill='#555'>every point grey; the {} "
        "points no other point beats on both, in colour, joined and labelled</text>\n",
        W, H, escape_xml(d.figure_names[b]), escape_xml(d.figure_names[a]), front.size());
    svg += fmt::format(
        "<line x1='{0}' y1='{1}' x2='{2}' y2='{1}' stroke='#888'/>\n"
        "<line x1='{0}' y1='{3}' x2='{0}' y2='{1}' stroke='#888'/>\n"
        "<text x='{4}' y='{5}' font-size='12' text-anchor='middle'>{6} ({7})</text>\n"
        "<text x='20' y='{8}' font-size='12' transform='rotate(-90 20 {8})' "
        "text-anchor='middle'>{9} ({10})</text>\n",
        left, bottom, right, top, (left + right) / 2, H - 18, escape_xml(d.figure_names[a]),
        dir(a_higher), (top + bottom) / 2, escape_xml(d.figure_names[b]), dir(b_higher));
    for (int t = 0; t <= 2; ++t) {
        const double vx = xlo + (xhi - xlo) * (0.08 + 0.84 * t / 2.0);
        const double vy = ylo + (yhi - ylo) * (0.08 + 0.84 * t / 2.0);
        svg += fmt::format(
            "<text x='{:.1f}' y='{:.1f}' font-size='10' text-anchor='middle' fill='#555'>{}"
            "</text>\n<text x='{:.1f}' y='{:.1f}' font-size='10' text-anchor='end' "
            "fill='#555'>{}</text>\n",
            X(vx), bottom + 14, escape_xml(format_figure(vx, d.figure_percent[a])), left - 4,
            Y(vy) + 3, escape_xml(format_figure(vy, d.figure_percent[b])));
    }
    for (size_t p = 0; p < pts.size(); ++p)
        if (std::isfinite(pts[p].first) && std::isfinite(pts[p].second))
            svg += fmt::format("<circle cx='{:.1f}' cy='{:.1f}' r='3.5' fill='#bbbbbb'/>\n",
                               X(pts[p].first), Y(pts[p].second));
    std::string line;
    for (size_t p : front) line += fmt::format("{:.1f},{:.1f} ", X(pts[p].first), Y(pts[p].second));
    svg += fmt::format("<polyline points='{}' fill='none' stroke='#e15759' stroke-width='2'/>\n",
                       line);
    for (size_t p : front)
        svg += fmt::format(
            "<circle cx='{:.1f}' cy='{:.1f}' r='5' fill='#e15759'/>\n<text x='{:.1f}' y='{:.1f}' "
            "font-size='10' fill='#333'>{}</text>\n",
            X(pts[p].first), Y(pts[p].second), X(pts[p].first) + 8, Y(pts[p].second) - 6,
            escape_xml(point_label(d, p, d.keys.size())));
    return svg + "</svg>\n";
}

std::vector<std::string> write_sweep_plots(const std::string& out_dir, const SweepPlotData& d,
                                           const std::vector<std::string>& pareto,
                                           std::string& png_note) {
    const fs::path dir = fs::path(out_dir) / "plots";
    fs::create_directories(dir);
    std::vector<std::pair<std::string, std::string>> svgs;  // file stem, content
    for (size_t k = 0; k < d.keys.size(); ++k)
        if (axis_values(d, k).size() > 1) svgs.push_back({d.keys[k], sweep_axis_svg(d, k)});
    if (pareto.size() == 2) {
        const auto a = std::find(d.figure_names.begin(), d.figure_names.end(), pareto[0]);
        const auto b = std::find(d.figure_names.begin(), d.figure_names.end(), pareto[1]);
        if (a != d.figure_names.end() && b != d.figure_names.end())
            svgs.push_back({"pareto", sweep_pareto_svg(d, size_t(a - d.figure_names.begin()),
                                                       size_t(b - d.figure_names.begin()),
                                                       figure_higher_is_better(pareto[0]),
                                                       figure_higher_is_better(pareto[1]))});
    }
    const bool rsvg = std::system("command -v rsvg-convert >/dev/null 2>&1") == 0;
    if (!rsvg) png_note = "no PNGs: rsvg-convert (Debian's librsvg2-bin) is not installed";
    std::vector<std::string> written;
    for (const auto& [stem, content] : svgs) {
        if (content.empty()) continue;
        const std::string svg_path = (dir / (stem + ".svg")).string();
        write_file_atomically(svg_path, content);
        written.push_back(svg_path);
        if (!rsvg) continue;
        const std::string png_path = (dir / (stem + ".png")).string();
        const std::string tmp = png_path + ".tmp";
        const std::string cmd = "rsvg-convert -b white -o " + shell_quoted(tmp) + " " +
                                shell_quoted(svg_path) + " 2>/dev/null";
        if (std::system(cmd.c_str()) == 0) {
            fs::rename(tmp, png_path);
            written.push_back(png_path);
        } else {
            fs::remove(tmp);
            png_note = "rsvg-convert failed on " + svg_path;
        }
    }
    return written;
}

}  // namespace rtsim

// Sweep plots: for each varied axis, one figure of small multiples, each figure of
// merit against that axis with one line per combination of the other axes' values, labelled at
// its end; and, with two objectives named, the Pareto front of the points. Written as SVG here,
// and as PNG through rsvg-convert (librsvg2-bin) when the machine has it.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace rtsim {

struct SweepPlotData {
    std::vector<std::string> keys;  // varied keys, file order
    std::vector<std::vector<std::pair<std::string, std::string>>> values;  // per point
    std::vector<std::string> figure_names;                                 // plotted figures
    std::vector<bool> figure_percent;                                      // per figure: a fraction
    std::vector<std::vector<double>> figures;  // per point, per figure (NaN: none)
    std::vector<bool> panel;  // per figure: drawn against the axes (empty: every figure)
};

// The SVG of axis `key`: each figure against it. Empty when the figure list has nothing to draw.
std::string sweep_axis_svg(const SweepPlotData& d, size_t key);
// The SVG of the Pareto front of figures a and b (indices into figure_names): every point, the
// ones no other point beats on both marked and joined. `a_higher_better`/`b_...`: the direction.
std::string sweep_pareto_svg(const SweepPlotData& d, size_t a, size_t b, bool a_higher_better,
                             bool b_higher_better);
// Indices of the points on the front (none beaten on both objectives; ties kept), by a.
std::vector<size_t> pareto_front(const std::vector<std::pair<double, double>>& points,
                                 bool a_higher_better, bool b_higher_better);

// Writes OUT_DIR/plots/<name>.svg for every varied axis (and pareto.svg when `pareto` names two
// figures), and a PNG beside each when rsvg-convert is on PATH. Returns the files written and
// sets `png_note` when PNGs could not be made (why).
std::vector<std::string> write_sweep_plots(const std::string& out_dir, const SweepPlotData& d,
                                           const std::vector<std::string>& pareto,
                                           std::string& png_note);

// Whether a figure of merit is better higher (rays per second, hit rates, utilisations).
bool figure_higher_is_better(const std::string& name);

}  // namespace rtsim

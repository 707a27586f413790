// The figures of merit read from a run's stats.json: one list that `compare` (its rows), `sweep`
// (its table, results.json and results.csv) and reports share, so a figure is named and
// defined once.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace rtsim {

struct FigureDef {
    enum class Relative { Ratio, Points };  // run / first, or run - first in percentage points
    std::string name;                       // as tables show it: "L1 hit rate"
    Relative relative = Relative::Ratio;
    bool percent = false;  // a fraction, shown as a percentage
    // The figure in one stats.json; NaN where the run has none (a mode's figures).
    std::function<double(const nlohmann::json&)> value;
    bool sweep_table = false;  // one of the columns of a sweep's printed table
    // A sampled run's estimate of the figure (its "sampling" section), if it has one: the
    // JSON pointer of the estimate object ({value, lo, hi, half_width_pct}); empty: none.
    std::string sampled = {};
};

// The half-width of a sampled run's 95% interval on figure `f`, in percent; NaN when the run is
// not sampled or the figure has no interval.
double interval_pct(const FigureDef& f, const nlohmann::json& stats);

// Every figure, in table order.
const std::vector<FigureDef>& figure_list();

// The figures of one stats.json, and how one is printed.
struct Figure {
    std::string name;
    double value;
    bool percent;  // a fraction, shown as a percentage
};
std::vector<Figure> key_figures(const nlohmann::json& stats);
std::string format_figure(double value, bool percent);
// The number at `pointer` (a JSON pointer such as /bandwidth/dram/bytes) in `stats`, or NaN.
double number_at(const nlohmann::json& stats, const char* pointer);

}  // namespace rtsim

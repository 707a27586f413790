// Sweep plots: the Pareto front against hand-picked points, and the per-axis figure's
// content (a panel per figure, a line per value of the other axes, labels, directions).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "sim/sweep_plot.h"

using namespace rtsim;

namespace {
size_t count(const std::string& s, const std::string& what) {
    size_t n = 0;
    for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
    return n;
}

// A 3 x 2 sweep of (size, ways), two figures: cycles falls with size, the hit rate rises.
SweepPlotData grid() {
    SweepPlotData d;
    d.keys = {"l1.size_kib", "l1.ways"};
    d.figure_names = {"cycles", "L1 hit rate", "rays per treelet batch"};
    d.figure_percent = {false, true, false};
    for (int size : {16, 8, 32})  // not in order: the axis sorts numbers
        for (int ways : {2, 4}) {
            d.values.push_back(
                {{"l1.size_kib", std::to_string(size)}, {"l1.ways", std::to_string(ways)}});
            d.figures.push_back({1000.0 / size + ways, 0.5 + size / 100.0, std::nan("")});
        }
    return d;
}
}  // namespace

// Minimising both: (1,5), (2,3) and (4,1) are beaten by nothing; (3,4) by (2,3); (2,6) by
// (2,3); a point with no value on an objective is left out.
TEST(SweepPlot, ParetoFrontByHand) {
    const std::vector<std::pair<double, double>> pts = {{3, 4}, {1, 5}, {4, 1},
                                                        {2, 3}, {2, 6}, {std::nan(""), 0}};
    EXPECT_EQ(pareto_front(pts, false, false), (std::vector<size_t>{1, 3, 2}));
    // Maximising the first: (4,1) is best on both and beats every other point.
    EXPECT_EQ(pareto_front(pts, true, false), (std::vector<size_t>{2}));
    // Maximising both: (4,1), (3,4) and (2,6) (each best on one side of the others).
    EXPECT_EQ(pareto_front(pts, true, true), (std::vector<size_t>{4, 0, 2}));
    // Equal points both stay.
    EXPECT_EQ(pareto_front({{1, 1}, {1, 1}, {2, 2}}, false, false), (std::vector<size_t>{0, 1}));
}

TEST(SweepPlot, AxisFigureHasAPanelPerFigureAndALinePerOtherValue) {
    const SweepPlotData d = grid();
    const std::string svg = sweep_axis_svg(d, 0);
    // Two figures with values (the third has none): two panels, two lines (ways 2 and 4) each.
    EXPECT_EQ(count(svg, "<polyline"), 4u);
    EXPECT_EQ(count(svg, "<circle"), 12u);
    EXPECT_NE(svg.find("cycles (lower is better)"), std::string::npos);
    EXPECT_NE(svg.find("L1 hit rate (higher is better)"), std::string::npos);
    EXPECT_EQ(svg.find("rays per treelet batch"), std::string::npos);
    EXPECT_EQ(count(svg, ">ways=2<"), 2u);  // each line labelled at its end, in both panels
    EXPECT_EQ(count(svg, ">ways=4<"), 2u);
    // The x axis in numeric order: 8 before 16 before 32.
    EXPECT_LT(svg.find(">8<"), svg.find(">16<"));
    EXPECT_LT(svg.find(">16<"), svg.find(">32<"));
    // A percent figure's ticks: its lowest, middle and highest value (0.58, 0.70, 0.82).
    EXPECT_NE(svg.find(">58.0%<"), std::string::npos);
    EXPECT_NE(svg.find(">70.0%<"), std::string::npos);
    EXPECT_NE(svg.find(">82.0%<"), std::string::npos);
    // Against ways: one line per size.
    EXPECT_EQ(count(sweep_axis_svg(d, 1), "<polyline"), 6u);
    // A panel mask keeps only the named figures.
    SweepPlotData only = d;
    only.panel = {true, false, false};
    EXPECT_EQ(count(sweep_axis_svg(only, 0), "<polyline"), 2u);
}

TEST(SweepPlot, ParetoFigureMarksTheFront) {
    const SweepPlotData d = grid();
    // cycles (lower better) against the hit rate (higher better): larger L1s win both, so the
    // front is the 32 KiB points: ways 2 (fewer cycles) and ways 4 tie on the rate.
    const std::string svg = sweep_pareto_svg(d, 0, 1, false, true);
    EXPECT_NE(svg.find("the 1 points"), std::string::npos) << svg.substr(0, 600);
    EXPECT_NE(svg.find("size_kib=32, ways=2"), std::string::npos);
    EXPECT_EQ(count(svg, "r='3.5'"), 6u);  // every point drawn
    EXPECT_TRUE(figure_higher_is_better("L2 hit rate"));
    EXPECT_FALSE(figure_higher_is_better("DRAM bytes per ray"));
}

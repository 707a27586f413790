// rtsim report: one self-contained HTML page for a run, a comparison or a sweep, checked
// for its content, for needing nothing outside itself, and rendered by a real browser (headless
// Chromium) into a screenshot that is not blank, with no script error logged.
#include <gtest/gtest.h>
#include <zlib.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/run_rtsim.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace rtsim::test;

namespace {

size_t count(const std::string& s, const std::string& what) {
    size_t n = 0;
    for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
    return n;
}

fs::path run_to(const std::string& name, const std::string& args) {
    const fs::path out = work_dir() / name;
    const Result r = run_rtsim(fmt::format("run -q {} -o '{}'", args, out.string()));
    EXPECT_EQ(r.status, 0) << r.err;
    return out;
}

// Nothing fetched from elsewhere: no script, no stylesheet or image by reference, no URL but
// the SVG namespace.
void expect_self_contained(const std::string& html) {
    EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
    EXPECT_NE(html.find("</html>"), std::string::npos);
    EXPECT_EQ(html.find("<script"), std::string::npos);
    EXPECT_EQ(html.find("src="), std::string::npos);
    EXPECT_EQ(html.find("href="), std::string::npos);
    EXPECT_EQ(count(html, "http"), count(html, "http://www.w3.org/2000/svg"));
}

// The bytes of a PNG's image data, inflated (filter bytes included).
std::string png_pixels(const std::string& png) {
    std::string idat;
    for (size_t p = 8; p + 12 <= png.size();) {
        const uint32_t len = uint32_t(uint8_t(png[p])) << 24 | uint32_t(uint8_t(png[p + 1])) << 16 |
                             uint32_t(uint8_t(png[p + 2])) << 8 | uint32_t(uint8_t(png[p + 3]));
        if (png.compare(p + 4, 4, "IDAT") == 0) idat += png.substr(p + 8, len);
        p += 12 + len;
    }
    std::string out(64 << 20, '\0');
    uLongf size = out.size();
    if (uncompress(reinterpret_cast<Bytef*>(out.data()), &size,
                   reinterpret_cast<const Bytef*>(idat.data()), idat.size()) != Z_OK)
        return {};
    out.resize(size);
    return out;
}

}  // namespace

TEST(Report, OneRunShowsItsConfigFiguresStallsCachesAndEnergy) {
    const fs::path run =
        run_to("rep_one", "--rays primary,ao --res 48x48 --set sim.window_cycles=500");
    const fs::path html_path = work_dir() / "one.html";
    const Result r =
        run_rtsim(fmt::format("report '{}' -o '{}'", run.string(), html_path.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const std::string html = slurp(html_path);
    expect_self_contained(html);
    const json s = json::parse(slurp(run / "stats.json"));
    for (const char* section : {"Runs", "Workload", "Config", "Summary", "Stall breakdown",
                                "Cache hit rates", "Energy per block"})
        EXPECT_NE(html.find(std::string(">") + section), std::string::npos) << section;
    EXPECT_NE(html.find("<td>l1.size_kib</td><td>32</td>"), std::string::npos);
    // The cycles as the run reported them, digits grouped as tables show them.
    std::string cycles = std::to_string(s["total_cycles"].get<uint64_t>());
    for (int i = int(cycles.size()) - 3; i > 0; i -= 3) cycles.insert(size_t(i), ",");
    EXPECT_NE(html.find("<td>" + cycles + "</td>"), std::string::npos) << cycles;
    EXPECT_NE(html.find("<td>l2</td>"), std::string::npos);
    EXPECT_NE(html.find("<td>box_unit</td>"), std::string::npos);  // an energy block
    EXPECT_NE(html.find("Ray-slot cycles by stall cause"), std::string::npos);
    // Bandwidth and utilisation over time (the run kept a time series).
    EXPECT_NE(html.find("DRAM GB/s per window"), std::string::npos);
    EXPECT_NE(html.find("Box unit utilisation per window"), std::string::npos);
}

TEST(Report, AComparisonShowsRatiosDifferencesAndIntervals) {
    const fs::path a = run_to("rep_a", "--rays primary --res 32x32");
    const fs::path b = run_to("rep_b", "--rays primary --res 32x32 --set l1.size_kib=8");
    const fs::path sampled =
        run_to("rep_s",
               "--rays ao --res 96x96 --set sim.sampled=true "
               "--set sim.sample_period_units=4 --set sim.sample_unit_rays=128");
    const fs::path out = work_dir() / "cmp.html";
    const Result r = run_rtsim(fmt::format("report '{}' '{}' '{}' --labels base,small,samp -o '{}'",
                                           a.string(), b.string(), sampled.string(), out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const std::string html = slurp(out);
    expect_self_contained(html);
    EXPECT_NE(html.find("<th>small vs base</th>"), std::string::npos);
    EXPECT_NE(html.find("Where the runs differ"), std::string::npos);
    EXPECT_NE(html.find("l1.size_kib"), std::string::npos);
    EXPECT_NE(html.find(" ± "), std::string::npos);  // the sampled run's intervals
    EXPECT_NE(html.find("95% confidence interval"), std::string::npos);
}

TEST(Report, ASweepShowsItsTableAndPlotsAndBadInputIsRefused) {
    const fs::path file = work_dir() / "rep_sweep.json";
    std::ofstream(file) << R"({"workload": {"rays": "primary", "res": "24x24"},
                               "vary": {"l1.ways": [1, 2, 4]}})";
    const fs::path dir = work_dir() / "rep_sweep";
    ASSERT_EQ(run_rtsim(fmt::format("sweep -q '{}' -o '{}'", file.string(), dir.string())).status,
              0);
    const fs::path out = work_dir() / "sweep.html";
    const Result r = run_rtsim(fmt::format("report '{}' -o '{}'", dir.string(), out.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    const std::string html = slurp(out);
    expect_self_contained(html);
    EXPECT_EQ(count(html, "<tr>"), 1u + 3u);  // the results table: header and three points
    EXPECT_EQ(count(html, "<svg"), 1u);       // the one varied axis's figure
    // A path that is no run is refused in one line, and no page is written.
    const fs::path never = work_dir() / "never.html";
    expect_one_line_error(
        run_rtsim(fmt::format("report '{}' -o '{}'", (work_dir() / "nothing_here").string(),
                              never.string())),
        "nothing_here");
    EXPECT_FALSE(fs::exists(never));
}

// A real browser renders the page: the screenshot is not blank and no script error is logged.
TEST(Report, HeadlessChromiumRendersThePage) {
    const char* const browsers[] = {"chromium", "chromium-browser", "google-chrome"};
    std::string browser;
    for (const char* b : browsers)
        if (browser.empty() &&
            std::system(fmt::format("command -v {} >/dev/null 2>&1", b).c_str()) == 0)
            browser = b;
    if (browser.empty())
        GTEST_SKIP() << "no headless Chromium installed (Debian's chromium): page not rendered";
    const fs::path run = run_to("rep_browser", "--rays primary,ao --res 48x48");
    const fs::path html = work_dir() / "browser.html", shot = work_dir() / "shot.png",
                   log = work_dir() / "browser.log";
    ASSERT_EQ(run_rtsim(fmt::format("report '{}' -o '{}'", run.string(), html.string())).status, 0);
    const std::string cmd = fmt::format(
        "timeout 120 {} --headless --no-sandbox --disable-gpu --hide-scrollbars "
        "--enable-logging=stderr --v=0 --window-size=1280,1600 --screenshot='{}' 'file://{}' "
        ">'{}' 2>&1",
        browser, shot.string(), fs::absolute(html).string(), log.string());
    ASSERT_EQ(std::system(cmd.c_str()), 0) << slurp(log);
    const std::string png = slurp(shot);
    ASSERT_GT(png.size(), 100u) << slurp(log);
    ASSERT_EQ(png.substr(1, 3), "PNG");
    // Not blank: a white page inflates to filter bytes and 0x00/0xFF only; text and charts give
    // thousands of other values.
    const std::string pixels = png_pixels(png);
    ASSERT_FALSE(pixels.empty());
    size_t inked = 0;
    for (char ch : pixels) inked += ch != '\0' && ch != '\xff';
    EXPECT_GT(inked, 10000u);
    const std::string messages = slurp(log);
    EXPECT_EQ(messages.find("Uncaught"), std::string::npos) << messages;
    EXPECT_EQ(messages.find("CONSOLE"), std::string::npos) << messages;
}

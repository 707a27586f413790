#include "sim/figures.h"

#include <fmt/format.h>
#include <cmath>
#include <limits>

#include "sim/stats_report.h"

namespace rtsim {

using nlohmann::json;

namespace {
constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
}  // namespace

double number_at(const json& j, const char* pointer) {
    const json::json_pointer p(pointer);
    if (!j.contains(p)) return kNone;
    const json& v = j.at(p);
    return v.is_number() ? v.get<double>() : kNone;
}

namespace {

// `field` averaged over the sections of `group` whose name starts with `prefix` ("box_unit[").
double mean_over(const json& j, const char* group, const std::string& prefix, const char* field) {
    if (!j.contains(group) || !j[group].is_object()) return kNone;
    double sum = 0;
    int n = 0;
    for (const auto& [name, section] : j[group].items())
        if (name.rfind(prefix, 0) == 0 && section.is_object() && section.contains(field) &&
            section[field].is_number()) {
            sum += section[field].get<double>();
            ++n;
        }
    return n ? sum / n : kNone;
}

double per_ray(const json& j, const char* pointer) {
    const double rays = number_at(j, "/rays/total");
    return rays > 0 ? number_at(j, pointer) / rays : kNone;
}

std::vector<FigureDef> make_figures() {
    using R = FigureDef::Relative;
    auto at = [](const char* p) { return [p](const json& j) { return number_at(j, p); }; };
    auto share = [](const std::string& cause) {
        const std::string p = "/stalls/total/share/" + cause;
        return [p](const json& j) { return number_at(j, p.c_str()); };
    };
    // A sampled run's estimate where it has one, else the run's own figure.
    auto estimate_or = [](std::string sampled, std::function<double(const json&)> plain,
                          double scale = 1.0) {
        return [sampled, plain, scale](const json& j) {
            const double v = number_at(j, (sampled + "/value").c_str());
            return std::isnan(v) ? plain(j) : v * scale;
        };
    };
    // Bytes per ray through a level: a sampled run's estimate of `counter`, else the run's
    // bandwidth section for `level`.
    auto bytes_per_ray = [](std::string counter, std::string level) {
        return [counter, level](const json& j) {
            const double est = number_at(j, ("/sampling/counters/" + counter + "/value").c_str());
            return std::isnan(est) ? per_ray(j, ("/bandwidth/" + level + "/bytes").c_str())
                                   : est / number_at(j, "/rays/total");
        };
    };
    std::vector<FigureDef> list = {
        {"cycles", R::Ratio, false, at("/total_cycles"), true, "/sampling/total_cycles"},
        {"simulated Mrays/s", R::Ratio, false,
         [](const json& j) { return number_at(j, "/rays_per_second") / 1e6; }, true,
         "/sampling/figures/rays_per_second"},
        {"rays", R::Ratio, false, at("/rays/total")},
        {"steps per ray", R::Ratio, false, [](const json& j) { return per_ray(j, "/rays/steps"); }},
        {"L1 hit rate", R::Points, true,
         estimate_or("/sampling/figures/l1_hit_rate", at("/caches/l1_total/hit_rate")), true,
         "/sampling/figures/l1_hit_rate"},
        {"L2 hit rate", R::Points, true,
         estimate_or("/sampling/figures/l2_hit_rate", at("/caches/l2/hit_rate")), true,
         "/sampling/figures/l2_hit_rate"},
        {"L2->L1 bytes per ray", R::Ratio, false, bytes_per_ray("l2.bytes_requested", "l2"), true,
         "/sampling/counters/l2.bytes_requested"},
        {"DRAM bytes per ray", R::Ratio, false, bytes_per_ray("dram.bytes", "dram"), true,
         "/sampling/counters/dram.bytes"},
        {"DRAM write bytes per ray", R::Ratio, false,
         [](const json& j) { return per_ray(j, "/bandwidth/dram/write_bytes"); }},
        {"DRAM GB/s", R::Ratio, false,
         [](const json& j) {
             // bytes per cycle x GHz = GB/s
             const double est = number_at(j, "/sampling/figures/dram_bytes_per_cycle/value");
             return std::isnan(est) ? number_at(j, "/bandwidth/dram/gbps")
                                    : est * number_at(j, "/clock_ghz");
         },
         false, "/sampling/figures/dram_bytes_per_cycle"},
        {"DRAM utilisation", R::Points, true, at("/bandwidth/dram/utilization")},
        {"DRAM row hit rate", R::Points, true, at("/bandwidth/dram/row_hit_rate")},
        {"energy per ray (nJ)", R::Ratio, false, at("/energy/per_ray_nj"), false,
         "/sampling/energy/per_ray_nj"},
        {"power (W)", R::Ratio, false, at("/energy/average_power_w"), false,
         "/sampling/energy/average_power_w"},
        // The command-level DRAM model's energy (absent from other models' stats).
        {"DRAM energy per ray (nJ)", R::Ratio, false,
         [](const json& j) { return per_ray(j, "/bandwidth/dram/energy_pj/total") / 1e3; }},
        {"DRAM power (mW)", R::Ratio, false, at("/bandwidth/dram/average_power_mw")},
        {"crossbar utilisation", R::Points, true, at("/bandwidth/crossbar/utilization")},
        {"box unit utilisation", R::Points, true,
         estimate_or(
             "/sampling/figures/box_unit_utilization",
             [](const json& j) { return mean_over(j, "units", "box_unit[", "utilization"); }),
         false, "/sampling/figures/box_unit_utilization"},
        {"triangle unit utilisation", R::Points, true,
         estimate_or(
             "/sampling/figures/triangle_unit_utilization",
             [](const json& j) { return mean_over(j, "units", "triangle_unit[", "utilization"); }),
         false, "/sampling/figures/triangle_unit_utilization"},
    };
    for (const std::string& cause : stall_causes()) {
        const std::string sampled = "/sampling/figures/stall_shares/" + cause;
        list.push_back({"stall: " + stall_cause_label(cause), R::Points, true,
                        estimate_or(sampled, share(cause)), false, sampled});
    }
    list.insert(
        list.end(),
        {
            // Treelet and packet modes (absent from other runs' stats).
            {"ray buffer bytes per ray", R::Ratio, false,
             [](const json& j) { return per_ray(j, "/ray_buffer/bytes"); }},
            {"treelet crossings per ray", R::Ratio, false, at("/ray_buffer/crossings_per_ray")},
            {"rays per treelet batch", R::Ratio, false, at("/ray_buffer/rays_per_batch")},
            {"packet lane utilisation", R::Points, true, at("/packets/lane_utilization")},
            {"host: simulated Mrays/host s", R::Ratio, false,
             [](const json& j) {
                 return number_at(j, "/host/simulated_rays_per_host_second") / 1e6;
             }},
        });
    return list;
}

}  // namespace

double interval_pct(const FigureDef& f, const json& stats) {
    if (f.sampled.empty()) return kNone;
    const json::json_pointer p(f.sampled + "/half_width_pct");
    // An estimate with no interval the data support (null): infinitely wide, not exact.
    if (stats.contains(p) && stats.at(p).is_null()) return std::numeric_limits<double>::infinity();
    return number_at(stats, (f.sampled + "/half_width_pct").c_str());
}

const std::vector<FigureDef>& figure_list() {
    static const std::vector<FigureDef> list = make_figures();
    return list;
}

std::vector<Figure> key_figures(const json& stats) {
    std::vector<Figure> out;
    for (const FigureDef& f : figure_list()) out.push_back({f.name, f.value(stats), f.percent});
    return out;
}

std::string format_figure(double v, bool percent) {
    if (std::isnan(v)) return "-";
    if (percent) return fmt::format("{:.1f}%", 100 * v);
    const double a = std::fabs(v);
    if (a < 1000) return fmt::format("{:#.4g}", v);
    std::string s = fmt::format("{:.0f}", a);  // counts and large figures: digits grouped
    for (int i = int(s.size()) - 3; i > 0; i -= 3) s.insert(size_t(i), ",");
    return v < 0 ? "-" + s : s;
}

}  // namespace rtsim

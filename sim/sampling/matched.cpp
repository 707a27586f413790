#include "sim/sampling/matched.h"

#include <fmt/format.h>

#include <optional>

#include "sim/sampling/reference.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

std::optional<UnitTable> read_table(const fs::path& dir) {
    const fs::path path = dir / "sampled_units.csv";
    const std::optional<std::string> text = read_file_text(path.string());
    if (!text) return std::nullopt;
    return parse_units_csv(*text, path.string());
}

// The estimate of figure `name` in a stats.json's sampling section.
const json* estimate_of(const json& sampling, const std::string& name) {
    if (name == "cycles")
        return sampling.contains("total_cycles") ? &sampling["total_cycles"] : nullptr;
    if (sampling.contains("counters") && sampling["counters"].contains(name))
        return &sampling["counters"][name];
    return nullptr;
}

}  // namespace

std::vector<MatchedDifference> matched_differences(const json& a, const fs::path& a_dir,
                                                   const json& b, const fs::path& b_dir,
                                                   std::string* why) {
    auto fail = [&](std::string reason) {
        if (why) *why = std::move(reason);
        return std::vector<MatchedDifference>{};
    };
    if (!a.contains("sampling") || !b.contains("sampling")) return fail("not both sampled");
    const json &sa = a["sampling"], &sb = b["sampling"];
    if (!sa.contains("regression") || !sb.contains("regression"))
        return fail("no estimates to match (a run without them, or from an older rtsim)");
    if (sa["regression"] != sb["regression"])
        return fail("not the same frame and design (their regressions' populations differ)");
    const std::optional<UnitTable> ta = read_table(a_dir), tb = read_table(b_dir);
    if (!ta || !tb) return fail("a sampled_units.csv is missing beside its stats.json");
    if (!ta->has("unit") || !tb->has("unit") || ta->cols.at("unit") != tb->cols.at("unit"))
        return fail("the runs measured different units (another sample seed or design)");

    // The auxiliaries the runs regressed on, as the table names them, and who stands for what.
    const json& reg = sa["regression"];
    std::vector<Auxiliary> aux;
    std::vector<std::string> names;
    for (const auto& [name, total] : reg["totals"].items()) {
        if (!ta->has(name)) continue;
        names.push_back(name);
        aux.push_back({{}, total.get<double>()});
    }
    // The first auxiliary (the variance model's) is work.
    const auto work = std::find(names.begin(), names.end(), "work");
    if (work == names.end()) return fail("the units' work is not in sampled_units.csv");
    std::iter_swap(names.begin(), work);
    std::iter_swap(aux.begin(), aux.begin() + (work - names.begin()));
    const bool by_work = ta->has("certainty") && ta->has("design_weight");
    std::vector<size_t> drawn, certain;
    for (size_t i = 0; i < ta->rows; ++i)
        (by_work && ta->cols.at("certainty")[i] != 0 ? certain : drawn).push_back(i);
    std::vector<double> expansion;
    for (size_t i : drawn) {
        for (size_t k = 0; k < names.size(); ++k) aux[k].x.push_back(ta->cols.at(names[k])[i]);
        if (by_work) expansion.push_back(ta->cols.at("design_weight")[i]);
    }
    const uint64_t population = reg["population"].get<uint64_t>();
    if (drawn.size() < 2) return fail("fewer than 2 units drawn");
    const RegressionDesign design(aux, population, by_work ? &expansion : nullptr);

    std::vector<MatchedDifference> out;
    for (const char* figure : {"cycles", "dram.bytes"}) {
        const json *ea = estimate_of(sa, figure), *eb = estimate_of(sb, figure);
        if (!ea || !eb || !ta->has(figure) || !tb->has(figure)) continue;
        const std::vector<double>&ya = ta->cols.at(figure), &yb = tb->cols.at(figure);
        std::vector<double> d;
        double exact = 0;
        for (size_t i : drawn) d.push_back(yb[i] - ya[i]);
        for (size_t i : certain) exact += yb[i] - ya[i];
        MatchedDifference m;
        m.figure = figure;
        m.difference = design.total(d);
        m.difference.value += exact;
        // The cycles after the last hand-out are each run's own, measured in full.
        if (m.figure == "cycles")
            m.difference.value += sb.value("drain_cycles", 0.0) - sa.value("drain_cycles", 0.0);
        m.base = (*ea)["value"].get<double>();
        out.push_back(std::move(m));
    }
    if (out.empty()) return fail("no figure to compare");
    return out;
}

}  // namespace rtsim

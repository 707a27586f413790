#include "sim/energy.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "sim/sampling/sampler.h"
#include "workloads/reduced_box.h"

namespace rtsim {

using nlohmann::json;

double sram_word_pj(const EnergyParams& e, double bytes) {
    const double x[3] = {std::log2(8.0 * 1024), std::log2(32.0 * 1024), std::log2(1024.0 * 1024)};
    const double y[3] = {e.sram_8kib_pj, e.sram_32kib_pj, e.sram_1mib_pj};
    const double lx = std::log2(std::max(bytes, 1.0));
    // Below the smallest point, the power law through the first two (energy ~ size^0.5 with
    // Horowitz's figures: a quarter of the size, half the energy); a straight line in log(size)
    // would reach zero at 2 KiB.
    if (lx < x[0] && y[0] > 0 && y[1] > 0) {
        const double exponent = std::log2(y[1] / y[0]) / (x[1] - x[0]);
        return y[0] * std::exp2((lx - x[0]) * exponent);
    }
    const int seg = lx < x[1] ? 0 : 1;  // the segment, extended beyond the ends
    const double t = (lx - x[seg]) / (x[seg + 1] - x[seg]);
    return std::max(0.0, y[seg] + t * (y[seg + 1] - y[seg]));
}

namespace {

// A counter's total: a sampled run's estimate where it has one, else the run's count.
double counter(const json& stats, const std::string& name) {
    if (stats.contains("sampling") && stats["sampling"].contains("counters")) {
        const json& c = stats["sampling"]["counters"];
        if (c.contains(name)) return c[name]["value"].get<double>();
        if (stats["sampling"].contains("total_cycles")) return 0.0;  // never moved when measured
    }
    const json& c = stats["counters"];
    return c.contains(name) ? c[name].get<double>() : 0.0;
}

// The counters of every block named prefix[i] ending in suffix (l1[0].accesses, l1[1].accesses,
// ...), found once per (prefix, suffix): a sampled run evaluates the model again for each
// jackknife replicate.
class BlockNames {
  public:
    explicit BlockNames(const json& stats) : stats_(stats) {}
    const std::vector<std::string>& of(const std::string& prefix, const std::string& suffix) {
        auto [it, added] = names_.try_emplace(prefix + "\n" + suffix);
        if (added)
            for (const auto& [name, value] : stats_["counters"].items()) {
                (void)value;
                if (name.rfind(prefix + "[", 0) == 0 && name.size() > suffix.size() &&
                    name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
                    it->second.push_back(name);
            }
        return it->second;
    }

  private:
    const json& stats_;
    std::map<std::string, std::vector<std::string>> names_;
};

// What the energy model reads of a run: its counters' totals through `total` (the run's
// counts, a sampled run's estimates, or one of their jackknife replicates) and its seconds.
class EnergyInputs {
  public:
    EnergyInputs(const json& stats, BlockNames& names,
                 std::function<double(const std::string&)> total, double seconds)
        : stats_(stats), names_(names), total_(std::move(total)), seconds_(seconds) {}
    const json& stats() const { return stats_; }
    double seconds() const { return seconds_; }
    double counter(const std::string& name) const { return total_(name); }
    // The sum of `suffix` over every block named prefix[i].
    double sum_blocks(const std::string& prefix, const std::string& suffix) const {
        double sum = 0;
        for (const std::string& name : names_.of(prefix, suffix)) sum += total_(name);
        return sum;
    }

  private:
    const json& stats_;
    BlockNames& names_;
    std::function<double(const std::string&)> total_;
    double seconds_;
};

// The model's figures; blocks and per-access costs by name (in name order, as stats.json has
// them).
struct EnergyFigures {
    std::map<std::string, double> blocks_pj, per_access_pj;
    double total_pj = 0, per_ray_nj = 0, average_power_w = 0;
    json to_json() const {
        return {{"blocks_pj", blocks_pj},
                {"total_pj", total_pj},
                {"per_ray_nj", per_ray_nj},
                {"average_power_w", average_power_w},
                {"per_access_pj", per_access_pj}};
    }
};

// Plain figures rather than JSON: a sampled run evaluates the model once per jackknife
// replicate.
EnergyFigures energy_of(const Params& P, const EnergyInputs& in) {
    const json& stats = in.stats();
    const EnergyParams& e = P.energy;
    EnergyFigures out;
    auto& per_access = out.per_access_pj;
    auto& blocks = out.blocks_pj;
    auto line_pj = [&](const CacheParams& c) {
        return sram_word_pj(e, double(c.size_bytes) / std::max(1, c.banks)) * double(c.line_bytes) /
               8.0;
    };
    // Caches: every lookup reads a line's worth of its bank, every miss writes a line in; a
    // written line is a line written, a dirty line written back one read out.
    auto cache = [&](const char* block, const CacheParams& c, bool indexed) {
        auto sum = [&](const char* suffix) {
            return indexed ? in.sum_blocks(block, suffix) : in.counter(std::string(block) + suffix);
        };
        const double accesses = sum(".accesses") + sum(".write_hits") + sum(".write_misses");
        const double misses = sum(".misses") + sum(".writebacks");
        if (accesses + misses <= 0) return;
        const double pj = line_pj(c);
        per_access[std::string(block) + "_line_pj"] = pj;
        blocks[block] = (accesses + misses) * pj;
    };
    cache("l1", P.l1, true);
    cache("l1_tri", P.l1, true);
    if (P.traversal.treelet_cache_bytes > 0) {
        CacheParams t = P.l1;
        t.size_bytes = P.traversal.treelet_cache_bytes;
        t.banks = 1;
        cache("treelet_cache", t, true);
    }
    cache("l2", P.l2, false);
    // The ray buffer: an SRAM bank of its capacity / banks, a ray record per access.
    // (Records in memory cost what the L2 and DRAM counted for them.)
    const double rb = P.ray_buffer.in_memory
                          ? 0.0
                          : in.counter("ray_buffer.reads") + in.counter("ray_buffer.writes");
    if (rb > 0) {
        const double bytes = double(P.ray_buffer.capacity_rays) * P.ray_buffer.ray_bytes /
                             double(std::max<uint32_t>(1, P.ray_buffer.banks));
        const double pj = sram_word_pj(e, bytes) * P.ray_buffer.ray_bytes / 8.0;
        per_access["ray_buffer_record_pj"] = pj;
        blocks["ray_buffer"] = rb * pj;
    }
    // The crossbar: bits times the distance they travel.
    const double xbar_bytes = in.counter("crossbar.bytes") + in.counter("crossbar.write_bytes");
    if (xbar_bytes > 0) {
        const double mm = e.crossbar_mm > 0 ? e.crossbar_mm : std::sqrt(double(P.core_count));
        per_access["crossbar_pj_per_byte"] = 8.0 * e.wire_pj_per_bit_mm * mm;
        blocks["crossbar"] = xbar_bytes * 8.0 * e.wire_pj_per_bit_mm * mm;
    }
    // Units: a W-wide box operation switches all W lanes' datapaths; a triangle operation tests
    // one triangle.
    const double m = (double(P.bvh.box_mantissa_bits) + 1.0) / (kFullMantissaBits + 1.0);
    const double box_pj = 6 * e.fp32_mul_pj * m * m + 12 * e.fp32_add_pj * m;
    const double tri_pj = 20 * e.fp32_mul_pj + 20 * e.fp32_add_pj;
    per_access["box_test_pj"] = box_pj;
    per_access["triangle_test_pj"] = tri_pj;
    const auto box = size_t(StepKind::Node);
    const double box_ops = in.sum_blocks("box_unit", ".ops"),
                 tri_ops = in.sum_blocks("triangle_unit", ".ops");
    if (box_ops > 0) blocks["box_unit"] = box_ops * P.unit[box].width * box_pj;
    if (tri_ops > 0) blocks["triangle_unit"] = tri_ops * tri_pj;
    // An instance transform: a 3x4 matrix on the origin (9 multiplies, 9 adds) and the
    // direction (9 multiplies, 6 adds). Only two-level scenes have any.
    const double xf_ops = in.sum_blocks("transform_unit", ".ops");
    if (xf_ops > 0) {
        const double xf_pj = 18 * e.fp32_mul_pj + 15 * e.fp32_add_pj;
        per_access["transform_pj"] = xf_pj;
        blocks["transform_unit"] = xf_ops * xf_pj;
    }
    // An any-hit shader call's arithmetic: the hit's texture coordinates interpolated from the
    // triangle's (4 multiplies, 4 adds) and the alpha compare (1 add); its reads are counted by
    // the caches and DRAM. Only scenes with non-opaque instances call it.
    const double ah_calls = in.sum_blocks("any_hit_shader", ".ops");
    if (ah_calls > 0) {
        const double ah_pj = 4 * e.fp32_mul_pj + 5 * e.fp32_add_pj;
        per_access["any_hit_pj"] = ah_pj;
        blocks["any_hit_shader"] = ah_calls * ah_pj;
    }
    // DRAM: the command-level model's own figure (scaled to a sampled run's estimated reads),
    // else bytes times a cost per byte.
    const double dram_bytes = in.counter("dram.bytes");
    const json::json_pointer cmd("/bandwidth/dram/energy_pj/total");
    if (stats.contains(cmd)) {
        const double measured = stats["counters"].value("dram.bytes", 0.0);
        const double scale = measured > 0 ? dram_bytes / measured : 1.0;
        blocks["dram"] = stats.at(cmd).get<double>() * scale;
    } else if (dram_bytes > 0) {
        per_access["dram_pj_per_byte"] = e.dram_pj_per_byte;
        blocks["dram"] = dram_bytes * e.dram_pj_per_byte;
    }
    double total = 0;
    for (const auto& [name, pj] : blocks) {
        (void)name;
        total += pj;
    }
    const double rays = stats["rays"]["total"].get<double>();
    const double seconds = in.seconds();
    out.total_pj = total;
    out.per_ray_nj = rays > 0 ? total / rays / 1e3 : 0.0;
    out.average_power_w = seconds > 0 ? total * 1e-12 / seconds : 0.0;
    return out;
}

}  // namespace

json energy_report(const Params& P, const json& stats) {
    BlockNames names(stats);
    return energy_of(
               P, EnergyInputs(
                      stats, names, [&](const std::string& name) { return counter(stats, name); },
                      stats.value("simulated_seconds", 0.0)))
        .to_json();
}

json sampled_energy(const Params& P, const json& stats, const JointEstimates& joint,
                    double clock_hz) {
    const json point = stats.at("energy");
    // The figures, in this order: total, per ray, power, then each block present.
    std::vector<std::string> names = {"total_pj", "per_ray_nj", "average_power_w"};
    for (const auto& [block, pj] : point["blocks_pj"].items()) {
        (void)pj;
        names.push_back(block);
    }
    BlockNames block_names(stats);
    const std::vector<Estimate> est = joint.of_many([&](const JointEstimates::Lookup& total) {
        const EnergyFigures e =
            energy_of(P, EnergyInputs(stats, block_names, total, total("cycles") / clock_hz));
        std::vector<double> v = {e.total_pj, e.per_ray_nj, e.average_power_w};
        for (size_t i = 3; i < names.size(); ++i) {
            const auto b = e.blocks_pj.find(names[i]);
            v.push_back(b == e.blocks_pj.end() ? 0.0 : b->second);
        }
        return v;
    });
    json out = {{"total_pj", estimate_json(est[0])},
                {"per_ray_nj", estimate_json(est[1])},
                {"average_power_w", estimate_json(est[2])},
                {"blocks_pj", json::object()}};
    for (size_t i = 3; i < names.size(); ++i) out["blocks_pj"][names[i]] = estimate_json(est[i]);
    return out;
}

}  // namespace rtsim

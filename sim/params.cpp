#include "sim/params.h"

#include <type_traits>

#include "models/memory_block.h"
#include "sim/config.h"

namespace rtsim {

using nlohmann::json;

namespace {

// A row for a member reached by `at`, converted by `scale` (schema unit x scale = member unit:
// 1024 for KiB to bytes).
template <typename At>
FieldBinding field(const char* path, At at, int64_t scale = 1, bool mirrors = true) {
    using T = std::remove_reference_t<decltype(at(std::declval<Params&>()))>;
    FieldBinding b;
    b.path = path;
    b.cpp_default_mirrors_schema = mirrors;
    b.set = [at, scale](Params& p, const json& v) {
        (void)scale;  // unused for strings and flags (clang warns per instance)
        if constexpr (std::is_same_v<T, std::string> || std::is_same_v<T, bool>)
            at(p) = v.get<T>();
        else if constexpr (std::is_floating_point_v<T>)
            at(p) = T(v.get<double>() * double(scale));
        else
            at(p) = T(v.get<int64_t>() * scale);
    };
    b.get = [at, scale](const Params& p) -> json {
        (void)scale;
        const T& m = at(const_cast<Params&>(p));
        if constexpr (std::is_same_v<T, std::string> || std::is_same_v<T, bool>)
            return m;
        else if constexpr (std::is_floating_point_v<T>)
            return double(m) / double(scale);
        else
            return int64_t(m) / scale;
    };
    return b;
}

// A row whose value is converted by hand (names to enums).
FieldBinding custom(const char* path, std::function<void(Params&, const json&)> set,
                    std::function<json(const Params&)> get) {
    return FieldBinding{path, std::move(set), std::move(get), true};
}

#define M(expr)               \
    [](Params & p) -> auto& { \
        return p.expr;        \
    }

// A unit kind's section (box_unit, triangle_unit): the same fields into its StepKind's
// UnitParams; `width` only where the unit tests several items per operation.
void add_unit_rows(std::vector<FieldBinding>& t, StepKind kind, bool mirrors, bool width) {
    const auto k = size_t(kind);
    const std::string s = step_kind_info(kind).unit;
    auto row = [&](const char* f, auto at) { t.push_back(field((s + f).c_str(), at, 1, mirrors)); };
    row(
        ".count", [k](Params & p) -> auto& { return p.unit[k].count; });
    t.push_back(
        field((s + ".shared_by").c_str(), [k](Params & p) -> auto& { return p.unit_shared_by[k]; },
              1, false));
    if (width)
        row(
            ".width", [k](Params & p) -> auto& { return p.unit[k].width; });
    row(
        ".latency_cycles", [k](Params & p) -> auto& { return p.unit[k].latency_cycles; });
    row(
        ".interval_cycles", [k](Params & p) -> auto& { return p.unit[k].interval_cycles; });
}

// A cache section (l1, l2): the same fields into its CacheParams.
void add_cache_rows(std::vector<FieldBinding>& t, const std::string& s, CacheParams Params::*c,
                    bool mirrors) {
    auto row = [&](const char* f, auto at, int64_t scale = 1) {
        t.push_back(field((s + f).c_str(), at, scale, mirrors));
    };
    row(
        ".size_kib", [c](Params & p) -> auto& { return (p.*c).size_bytes; }, 1024);
    row(
        ".ways", [c](Params & p) -> auto& { return (p.*c).ways; });
    row(
        ".line_bytes", [c](Params & p) -> auto& { return (p.*c).line_bytes; });
    row(
        ".hit_latency_cycles", [c](Params & p) -> auto& { return (p.*c).hit_latency_cycles; });
    row(
        ".mshrs", [c](Params & p) -> auto& { return (p.*c).mshrs; });
    row(
        ".replacement", [c](Params & p) -> auto& { return (p.*c).replacement; });
    row(
        ".rrpv_bits", [c](Params & p) -> auto& { return (p.*c).rrpv_bits; });
    row(
        ".banks", [c](Params & p) -> auto& { return (p.*c).banks; });
    row(
        ".prefetcher", [c](Params & p) -> auto& { return (p.*c).prefetcher; });
    row(
        ".prefetch_degree", [c](Params & p) -> auto& { return (p.*c).prefetch_degree; });
}

std::vector<FieldBinding> make_bindings() {
    constexpr bool kNotMirrored = false;
    std::vector<FieldBinding> t = {
        field("name", M(name), 1, kNotMirrored),
        field("clock_ghz", M(clock_ghz), 1, kNotMirrored),
        field("core.count", M(core_count), 1, kNotMirrored),
        field("core.ray_slots", M(core.ray_slots)),
        field("core.issue_width", M(core.issue_width)),
        field("core.issue_latency_cycles", M(core.issue_latency_cycles)),
        field("core.node_step_instructions", M(core.step_instructions[0])),
        field("core.triangle_step_instructions", M(core.step_instructions[1])),
        field("core.transform_step_instructions", M(core.step_instructions[2])),
        field("core.any_hit_step_instructions", M(core.step_instructions[3])),
        field("core.ray_setup_instructions", M(core.ray_setup_instructions)),
        field("core.short_stack_entries", M(core.short_stack_entries)),
        field("core.stack_entry_bytes", M(core.stack_entry_bytes)),
        field("core.hit_record_bytes", M(core.hit_record_bytes)),
        field("core.write_buffer_entries", M(core.write_buffer_entries)),
    };
    // CacheParams and UnitParams default to the first section's values (l1, box_unit).
    add_unit_rows(t, StepKind::Node, true, /*width=*/true);
    add_unit_rows(t, StepKind::Triangle, kNotMirrored, /*width=*/false);
    add_unit_rows(t, StepKind::Transform, kNotMirrored, /*width=*/false);
    add_unit_rows(t, StepKind::AnyHit, kNotMirrored, /*width=*/false);
    t.push_back(field("any_hit_shader.alpha_read_bytes", M(alpha_read_bytes), 1, kNotMirrored));
    t.push_back(field("box_unit.mantissa_bits", M(bvh.box_mantissa_bits)));
    t.push_back(field("box_unit.translate_origin", M(bvh.box_translate_origin)));
    add_cache_rows(t, "l1", &Params::l1, true);
    t.push_back(field("l1.split", M(l1_split), 1, kNotMirrored));
    add_cache_rows(t, "l2", &Params::l2, kNotMirrored);
    t.push_back(custom(
        "l2.write_policy",
        [](Params& p, const json& v) { p.l2.write_back = v.get<std::string>() == "write_back"; },
        [](const Params& p) -> json { return p.l2.write_back ? "write_back" : "write_through"; }));
    const std::vector<FieldBinding> rest = {
        field("crossbar.bytes_per_cycle", M(crossbar_bytes_per_cycle), 1, kNotMirrored),
        field("dram.model", M(dram_model), 1, kNotMirrored),
        field("dram.latency_cycles", M(dram.latency_cycles)),
        field("dram.bytes_per_cycle", M(dram.bytes_per_cycle)),
        field("dram.channels", M(dram.channels)),
        field("dram.banks", M(dram.banks)),
        field("dram.row_bytes", M(dram.row_bytes)),
        field("dram.burst_bytes", M(dram.burst_bytes)),
        field("dram.t_rcd_cycles", M(dram.t_rcd_cycles)),
        field("dram.t_cas_cycles", M(dram.t_cas_cycles)),
        field("dram.t_ccd_cycles", M(dram.t_ccd_cycles)),
        field("dram.t_rp_cycles", M(dram.t_rp_cycles)),
        field("dram.device", M(dram.device)),
        field("dram.page_policy", M(dram.page_policy)),
        field("dram.address_mapping", M(dram.address_mapping)),
        field("dram.refresh", M(dram.refresh)),
        field("dram.tlm_target", M(dram.tlm_target)),
        custom(
            "bvh.builder",
            [](Params& p, const json& v) {
                p.bvh.builder = parse_bvh_builder(v.get<std::string>(), "bvh.builder");
            },
            [](const Params& p) -> json { return bvh_builder_name(p.bvh.builder); }),
        field("bvh.restructure_passes", M(bvh.restructure_passes)),
        field("bvh.width", M(bvh.width)),
        field("bvh.sah_buckets", M(bvh.sah_buckets)),
        field("bvh.max_leaf_size", M(bvh.max_leaf_size)),
        custom(
            "bvh.node_format",
            [](Params& p, const json& v) {
                p.bvh.node_format = parse_node_format(v.get<std::string>(), "bvh.node_format");
            },
            [](const Params& p) -> json { return node_format_name(p.bvh.node_format); }),
        field("bvh.node_size_bytes", M(node_size_bytes), 1, kNotMirrored),
        field("bvh.triangle_size_bytes", M(triangle_size_bytes), 1, kNotMirrored),
        field("bvh.treelet_bytes", M(bvh.treelet_bytes)),
        field("traversal.mode", M(traversal.mode), 1, kNotMirrored),
        field("traversal.packet_size", M(traversal.packet_size), 1, kNotMirrored),
        field("traversal.treelet_scheduler", M(ray_buffer.scheduler)),
        field("traversal.treelet_max_wait_batches", M(ray_buffer.max_wait_batches)),
        field("traversal.treelet_batch_rays", M(ray_buffer.batch_rays)),
        field("traversal.treelet_prefetch", M(core.treelet_prefetch)),
        field("traversal.treelet_cache_kib", M(traversal.treelet_cache_bytes), 1024, kNotMirrored),
        field("traversal.treelet_cache_latency_cycles", M(traversal.treelet_cache_latency_cycles),
              1, kNotMirrored),
        field("ray_buffer.capacity_rays", M(ray_buffer.capacity_rays)),
        field("ray_buffer.ray_bytes", M(ray_buffer.ray_bytes)),
        field("ray_buffer.ports", M(ray_buffer.ports)),
        field("ray_buffer.latency_cycles", M(ray_buffer.latency_cycles)),
        field("ray_buffer.banks", M(ray_buffer.banks)),
        custom(
            "ray_buffer.storage",
            [](Params& p, const json& v) {
                p.ray_buffer.in_memory = v.get<std::string>() == "memory";
            },
            [](const Params& p) -> json { return p.ray_buffer.in_memory ? "memory" : "sram"; }),
        field("sim.ideal_memory", M(sim.ideal_memory), 1, kNotMirrored),
        field("sim.ideal_units", M(sim.ideal_units), 1, kNotMirrored),
        field("sim.window_cycles", M(sim.window_cycles), 1, kNotMirrored),
        field("sim.fidelity", M(sim.fidelity), 1, kNotMirrored),
        field("sim.sampled", M(sim.sampled)),
        field("sim.sample_unit_rays", M(sim.sample_unit_rays)),
        field("sim.sample_period_units", M(sim.sample_period_units)),
        field("sim.sample_warmup_rays", M(sim.sample_warmup_rays)),
        field("sim.sample_design", M(sim.sample_design)),
        field("sim.sample_seed", M(sim.sample_seed)),
        field("sim.sample_first_unit", M(sim.sample_first_unit)),
        field("sim.sample_fast_forward", M(sim.sample_fast_forward)),
        field("sim.sample_unit_tiles", M(sim.sample_unit_tiles)),
        field("sim.sample_warm_tiles", M(sim.sample_warm_tiles)),
        field("sim.sample_warmup_tiles", M(sim.sample_warmup_tiles)),
        field("sim.sample_warmup_tile_rays", M(sim.sample_warmup_tile_rays)),
        field("sim.sample_paired_unit_tiles", M(sim.sample_paired_unit_tiles)),
        field("sim.sample_paired_warmup_tiles", M(sim.sample_paired_warmup_tiles)),
        field("sim.sample_paired_warmup_tile_rays", M(sim.sample_paired_warmup_tile_rays)),
        field("sim.sample_warmup_slot_fills", M(sim.sample_warmup_slot_fills)),
        field("sim.sample_unit_slot_fills", M(sim.sample_unit_slot_fills)),
        field("sim.sample_startup_slot_fills", M(sim.sample_startup_slot_fills)),
        field("sim.sample_paired_warmup_slot_fills", M(sim.sample_paired_warmup_slot_fills)),
        field("sim.sample_window_hold", M(sim.sample_window_hold)),
        field("sim.sample_window_hold_release_share", M(sim.sample_window_hold_release_share)),
        field("sim.sample_warmup_work", M(sim.sample_warmup_work)),
        field("energy.sram_8kib_pj", M(energy.sram_8kib_pj), 1, kNotMirrored),
        field("energy.sram_32kib_pj", M(energy.sram_32kib_pj), 1, kNotMirrored),
        field("energy.sram_1mib_pj", M(energy.sram_1mib_pj), 1, kNotMirrored),
        field("energy.fp32_add_pj", M(energy.fp32_add_pj), 1, kNotMirrored),
        field("energy.fp32_mul_pj", M(energy.fp32_mul_pj), 1, kNotMirrored),
        field("energy.wire_pj_per_bit_mm", M(energy.wire_pj_per_bit_mm), 1, kNotMirrored),
        field("energy.crossbar_mm", M(energy.crossbar_mm), 1, kNotMirrored),
        field("energy.dram_pj_per_byte", M(energy.dram_pj_per_byte), 1, kNotMirrored),
    };
    t.insert(t.end(), rest.begin(), rest.end());
    for (int i = 0; i < kMemoryPathPositions; ++i) {
        const std::string path =
            std::string("memory_path.") + memory_path_position_name(MemoryPathPosition(i));
        t.push_back(field(
            path.c_str(), [i](Params & p) -> auto& { return p.memory_path[size_t(i)]; }, 1,
            kNotMirrored));
    }
    // A memory block's own section, whatever fields its schema entry has: each reaches the
    // block's JSON, which the block reads when it is built (a new block needs no row here).
    for (const auto& [block, section] :
         config_schema()["fields"]["memory_path"]["fields"].items()) {
        if (!section.contains("fields")) continue;
        for (const auto& [leaf, unused] : section["fields"].items()) {
            (void)unused;
            FieldBinding b;
            b.path = "memory_path." + block + "." + leaf;
            b.cpp_default_mirrors_schema = false;
            b.set = [block = block, leaf = leaf](Params& p, const json& v) {
                p.memory_block_config[block][leaf] = v;
            };
            b.get = [block = block, leaf = leaf](const Params& p) -> json {
                return p.memory_block_config.at(block).at(leaf);
            };
            t.push_back(std::move(b));
        }
    }
    return t;
}

#undef M

const json& at_path(const json& values, const std::string& path) {
    const json* node = &values;
    size_t start = 0;
    while (true) {
        const size_t dot = path.find('.', start);
        node = &node->at(path.substr(start, dot - start));
        if (dot == std::string::npos) return *node;
        start = dot + 1;
    }
}

}  // namespace

const std::vector<FieldBinding>& config_bindings() {
    static const std::vector<FieldBinding> table = make_bindings();
    return table;
}

Params bind_params(const json& values) {
    Params p;
    for (const FieldBinding& b : config_bindings()) b.set(p, at_path(values, b.path));
    return p;
}

}  // namespace rtsim

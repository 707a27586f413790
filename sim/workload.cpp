#include "sim/workload.h"

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <cstdio>

#include "models/traversal_mode.h"
#include "sim/sampling/registry.h"
#include "workloads/error.h"
#include "workloads/reduced_box.h"
#include "workloads/trace_file.h"

namespace rtsim {

using nlohmann::json;

namespace {

json aabb_json(const AABB& b) {
    return {{"lo", {b.lo.x, b.lo.y, b.lo.z}}, {"hi", {b.hi.x, b.hi.y, b.hi.z}}};
}

}  // namespace

void parse_resolution(const std::string& text, const std::string& what, int& width, int& height) {
    int w = 0, h = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') ||
        w <= 0 || h <= 0 || w > 65536 || h > 65536)
        throw InputError(
            fmt::format("{}: expected WIDTHxHEIGHT with each in 1..65536, got '{}'", what, text));
    width = w;
    height = h;
}

Bvh build_bvh_from_config(const Config& cfg, const Scene& scene, const std::string& cache_dir,
                          BvhCacheStatus* status, std::optional<uint64_t> scene_hash) {
    return build_bvh_cached(scene, cfg.typed.bvh, layout_sizes_from_config(cfg), cache_dir, status,
                            scene_hash);
}

BvhLayout layout_sizes_from_config(const Config& cfg) {
    BvhLayout layout;
    layout.node_size_bytes = cfg.typed.node_size_bytes;
    layout.tri_size_bytes = cfg.typed.triangle_size_bytes;
    layout.alpha_size_bytes = cfg.typed.alpha_read_bytes;
    return layout;
}

TwoLevelBvh build_two_level_from_config(const Config& cfg, const InstancedScene& scene,
                                        const std::string& cache_dir, size_t* blas_cache_hits) {
    return build_two_level(scene, cfg.typed.bvh, layout_sizes_from_config(cfg), cache_dir,
                           blas_cache_hits);
}

std::string resolve_bvh_cache_dir(const std::string& option) {
    if (option == "off") return {};
    return option.empty() ? default_bvh_cache_dir() : option;
}

void add_bvh_cache_option(CLI::App* cmd, std::string& dir) {
    cmd->add_option("--bvh-cache", dir,
                    "Folder of built BVHs, reused by runs with the same scene content and BVH "
                    "settings ('off': build every time; default $RTSIM_BVH_CACHE, else "
                    "~/.cache/rtsim/bvh)");
}

void WorkloadOptions::resolve() {
    parse_resolution(res, "--res", gen.width, gen.height);
    gen.kinds = parse_ray_kinds(rays, "--rays");
    gen.light = parse_light_kind(light, "--light");
    gen.validate();
}

void add_workload_options(CLI::App* cmd, WorkloadOptions& w) {
    cmd->add_option("--scene", w.scene,
                    "Mesh file (OBJ, PLY, OFF, STL, glTF, ...; one whose nodes share meshes is "
                    "read as instances), builtin:NAME (cornell, sphere), or a scene file of "
                    "instances (.json, docs/scenes.md)")
        ->capture_default_str();
    cmd->add_flag("--flatten", w.flatten,
                  "Read a mesh file whose nodes share meshes as one flattened mesh (one BVH) "
                  "instead of instances over two levels");
    cmd->add_option("--rays", w.rays,
                    "Comma list of ray kinds: primary, shadow, ao, diffuse, reflection")
        ->capture_default_str();
    cmd->add_option("--res", w.res, "Image resolution WIDTHxHEIGHT")->capture_default_str();
    cmd->add_option("--spp", w.gen.spp, "Primary samples per pixel (jittered when more than 1)")
        ->capture_default_str();
    cmd->add_option("--seed", w.gen.seed, "Seed for sampled rays")->capture_default_str();
    cmd->add_option("--light", w.light, "Light for shadow rays: point or area")
        ->capture_default_str();
    cmd->add_option("--ao-samples", w.gen.ao_samples, "AO rays per primary hit")
        ->capture_default_str();
    cmd->add_option("--ao-length", w.gen.ao_length_fraction,
                    "AO ray length as a fraction of the scene diagonal")
        ->capture_default_str();
    cmd->add_option("--diffuse-depth", w.gen.diffuse_depth, "Diffuse bounces per primary hit")
        ->capture_default_str();
}

json scene_summary(const Scene& scene) {
    return scene_summary(scene, scene.content_hash());
}

json scene_summary(const Scene& scene, uint64_t content_hash) {
    return {{"name", scene.name},
            {"source", scene.source},
            {"triangles", scene.triangle_count()},
            {"vertices", scene.vertices.size()},
            {"hash", fmt::format("{:016x}", content_hash)},
            {"bounds", aabb_json(scene.bounds())}};
}

json scene_summary(const InstancedScene& scene) {
    return {{"name", scene.name},
            {"source", scene.source},
            {"triangles", scene.unique_triangle_count()},
            {"meshes", scene.meshes.size()},
            {"instances", scene.instances.size()},
            {"instanced_triangles", scene.instanced_triangle_count()},
            {"hash", fmt::format("{:016x}", scene.content_hash())},
            {"bounds", aabb_json(scene.bounds())}};
}

json workload_summary(const RayGenOptions& rg, float ao_length) {
    return {{"rays", ray_kinds_to_string(rg.kinds)},
            {"resolution", fmt::format("{}x{}", rg.width, rg.height)},
            {"seed", rg.seed},
            {"spp", rg.spp},
            {"light", light_kind_name(rg.light)},
            {"diffuse_depth", rg.diffuse_depth},
            {"ao_samples", rg.ao_samples},
            {"ao_length_fraction", rg.ao_length_fraction},
            {"ao_length", ao_length},
            {"tile_size", rg.tile_size}};
}

json open_trace_metadata(TraceReader& reader, const std::string& path) {
    json meta = reader.metadata();
    if (meta.is_discarded() || !meta.is_object() || !meta.contains("bvh") ||
        !meta["bvh"].is_object() || !meta.contains("scene"))
        throw InputError(
            fmt::format("{}: header metadata is not the JSON an RTSim trace carries", path));
    // Traces from before reduced-precision box units were all traced in fp32.
    if (!meta["bvh"].contains("box_mantissa_bits")) {
        meta["bvh"]["box_mantissa_bits"] = kFullMantissaBits;
        meta["bvh"]["box_translate_origin"] = true;
    }
    return meta;
}

void check_config_combination(const Config& cfg, const std::string& trace_path) {
    const TraversalModeEntry& mode = TraversalModeRegistry::at(cfg.typed.traversal.mode);
    if (cfg.typed.sim.sampled && (mode.needs_treelets || mode.packets))
        throw InputError(
            fmt::format("sim.sampled: not yet with traversal.mode={} (a treelet ray buffer admits "
                        "rays ahead of the cores, a packet spans unit boundaries)",
                        mode.name));
    if (cfg.typed.sim.sampled &&
        FastForwardRegistry::at(cfg.typed.sim.sample_fast_forward).needs_profile &&
        !trace_path.empty())
        throw InputError(fmt::format(
            "{}: sim.sample_fast_forward=skip skips tiles before they are traced and needs rays "
            "generated on the fly; a trace replay samples with sim.sample_fast_forward=warm",
            trace_path));
    if (!mode.replays_traces && !trace_path.empty())
        throw InputError(
            fmt::format("{}: a trace records single-ray traversal; traversal.mode={} needs rays "
                        "generated on the fly (drop --trace)",
                        trace_path, mode.name));
}

void check_trace_matches_config(const json& bvh, const Config& cfg, const std::string& where) {
    auto refuse = [&](const std::string& field, const std::string& recorded,
                      const std::string& wanted) {
        throw InputError(fmt::format(
            "{}: recorded with {}={}, but the config asks for {}; record the trace again "
            "or use a config with the same BVH layout",
            where, field, recorded, wanted));
    };
    const Params& P = cfg.typed;
    const int width = bvh.value("width", 0);
    if (width != P.bvh.width)
        refuse("bvh.width", std::to_string(width), std::to_string(P.bvh.width));
    const std::string format = bvh.value("node_format", std::string("?"));
    if (format != node_format_name(P.bvh.node_format))
        refuse("bvh.node_format", format, node_format_name(P.bvh.node_format));
    const int bits = bvh.value("box_mantissa_bits", kFullMantissaBits);
    if (bits != P.bvh.box_mantissa_bits)
        refuse("box_unit.mantissa_bits", std::to_string(bits),
               std::to_string(P.bvh.box_mantissa_bits));
    // Translation changes nothing in fp32, where it is not applied.
    const bool translate = bvh.value("box_translate_origin", true);
    if (bits < kFullMantissaBits && translate != P.bvh.box_translate_origin)
        refuse("box_unit.translate_origin", translate ? "true" : "false",
               P.bvh.box_translate_origin ? "true" : "false");
    const BvhLayout L = layout_from_summary(bvh, where);
    if (P.node_size_bytes != 0 && P.node_size_bytes != L.node_size_bytes)
        refuse("bvh.node_size_bytes", std::to_string(L.node_size_bytes),
               std::to_string(P.node_size_bytes));
    if (P.triangle_size_bytes != L.tri_size_bytes)
        refuse("bvh.triangle_size_bytes", std::to_string(L.tri_size_bytes),
               std::to_string(P.triangle_size_bytes));
    if (P.bvh.treelet_bytes != L.treelet_bytes)
        refuse("bvh.treelet_bytes", std::to_string(L.treelet_bytes),
               std::to_string(P.bvh.treelet_bytes));
}

}  // namespace rtsim

#include "workloads/bvh_summary.h"

#include <fmt/format.h>

#include "workloads/error.h"

namespace rtsim {

using nlohmann::json;

namespace {

// A layout's record regions; `treelet_tables` adds the treelet start tables (a trace needs them
// to replay treelet mode; stats keep only the figures). Two-level layouts add their instance
// records and alpha data.
json layout_summary(const BvhLayout& L, bool treelet_tables) {
    json out = {{"node_base_addr", L.node_base_addr},
                {"node_size_bytes", L.node_size_bytes},
                {"inner_node_count", L.inner_node_count},
                {"triangle_base_addr", L.tri_base_addr},
                {"triangle_size_bytes", L.tri_size_bytes},
                {"triangle_count", L.triangle_count},
                {"treelet_bytes", L.treelet_bytes},
                {"treelets", L.treelet_bytes ? L.treelet_count() : 0}};
    if (L.instance_count) {
        out["instance_base_addr"] = L.instance_base_addr;
        out["instance_size_bytes"] = L.instance_size_bytes;
        out["instance_count"] = L.instance_count;
        out["alpha_base_addr"] = L.alpha_base_addr;
        out["alpha_size_bytes"] = L.alpha_size_bytes;
        out["alpha_count"] = L.alpha_count;
    }
    if (treelet_tables) {
        out["treelet_node_start"] = L.treelet_node_start;
        out["treelet_tri_start"] = L.treelet_tri_start;
        if (!L.treelet_instance_start.empty())
            out["treelet_instance_start"] = L.treelet_instance_start;
    }
    return out;
}

}  // namespace

json bvh_summary(const Bvh& bvh, bool treelet_tables) {
    const BvhQuality& q = bvh.quality;
    const BvhBuildOptions& bo = bvh.options;
    json out = {{"builder", bvh_builder_name(bo.builder)},
                {"restructure_passes", bo.restructure_passes},
                {"width", bvh.width()},
                {"node_format", node_format_name(bo.node_format)},
                {"box_mantissa_bits", bo.box_mantissa_bits},
                {"box_translate_origin", bo.box_translate_origin},
                {"sah_cost", q.sah_cost},
                {"sah_traversal_cost", bo.traversal_cost},
                {"sah_intersection_cost", bo.intersection_cost},
                {"nodes", q.node_count},
                {"inner_nodes", q.inner_count},
                {"leaves", q.leaf_count},
                {"max_depth", q.max_depth},
                {"mean_leaf_size", q.mean_leaf_size},
                {"mean_children", q.mean_children},
                {"bytes", q.bytes},
                {"layout", layout_summary(bvh.layout, treelet_tables)}};
    return out;
}

json bvh_summary(const TwoLevelBvh& two, bool treelet_tables) {
    json out = bvh_summary(two.tlas);
    out["tlas"] = {{"sah_cost", two.tlas.quality.sah_cost},
                   {"inner_nodes", two.tlas.quality.inner_count},
                   {"leaves", two.tlas.quality.leaf_count},
                   {"max_depth", two.tlas.quality.max_depth}};
    uint64_t nodes = two.tlas.quality.node_count, inner = two.tlas.quality.inner_count,
             leaves = two.tlas.quality.leaf_count;
    uint32_t blas_depth = 0;
    for (const Bvh& b : two.blas) {
        nodes += b.quality.node_count;
        inner += b.quality.inner_count;
        leaves += b.quality.leaf_count;
        blas_depth = std::max(blas_depth, b.quality.max_depth);
    }
    const BvhLayout& L = two.layout;
    out["levels"] = 2;
    out["blas"] = two.blas.size();
    out["instances"] = two.instances.size();
    out["nodes"] = nodes;
    out["inner_nodes"] = inner;
    out["leaves"] = leaves;
    out["max_depth"] = two.tlas.quality.max_depth + blas_depth;  // a path through both levels
    out.erase("mean_leaf_size");
    out.erase("mean_children");
    out["bytes"] = L.node_bytes_total() + L.tri_bytes_total() + L.instance_bytes_total() +
                   L.alpha_bytes_total();
    out["non_opaque_instances"] = std::count_if(two.instances.begin(), two.instances.end(),
                                                [](const Instance& i) { return !i.opaque; });
    out["layout"] = layout_summary(L, treelet_tables);
    return out;
}

BvhLayout layout_from_summary(const json& bvh, const std::string& where) {
    try {
        const json& l = bvh.at("layout");
        BvhLayout L;
        L.node_base_addr = l.at("node_base_addr").get<uint64_t>();
        L.node_size_bytes = l.at("node_size_bytes").get<uint32_t>();
        L.inner_node_count = l.at("inner_node_count").get<uint32_t>();
        L.tri_base_addr = l.at("triangle_base_addr").get<uint64_t>();
        L.tri_size_bytes = l.at("triangle_size_bytes").get<uint32_t>();
        L.triangle_count = l.at("triangle_count").get<uint32_t>();
        // One-level layouts (and traces from before instances) have no instance records.
        L.instance_base_addr = l.value("instance_base_addr", uint64_t(0));
        L.instance_size_bytes = l.value("instance_size_bytes", 64u);
        L.instance_count = l.value("instance_count", 0u);
        // ...nor alpha data (nor do scenes whose instances are all opaque).
        L.alpha_base_addr = l.value("alpha_base_addr", uint64_t(0));
        L.alpha_size_bytes = l.value("alpha_size_bytes", 16u);
        L.alpha_count = l.value("alpha_count", 0u);
        // Traces from before treelets carry no treelet fields: a layout without treelets.
        L.treelet_bytes = l.value("treelet_bytes", 0u);
        L.treelet_node_start = l.value("treelet_node_start", std::vector<uint32_t>());
        L.treelet_tri_start = l.value("treelet_tri_start", std::vector<uint32_t>());
        L.treelet_instance_start = l.value("treelet_instance_start", std::vector<uint32_t>());
        if (!L.index_treelets() || (L.treelet_bytes == 0) != L.treelet_node_start.empty())
            throw InputError(fmt::format(
                "{}: header metadata bvh.layout has treelet tables that do not cover its {} "
                "nodes and {} triangles",
                where, L.inner_node_count, L.triangle_count));
        return L;
    } catch (const json::exception& e) {
        throw InputError(
            fmt::format("{}: header metadata has no valid bvh.layout ({})", where, e.what()));
    }
}

}  // namespace rtsim

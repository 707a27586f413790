#include "workloads/instances.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "workloads/bvh_cache.h"
#include "workloads/cache_entry.h"
#include "workloads/error.h"
#include "workloads/memory_limit.h"

namespace rtsim {

double Affine3x4::determinant() const {
    const auto a = [this](int r, int c) { return double(at(r, c)); };
    return a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) -
           a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0)) +
           a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
}

Affine3x4 compose(const Affine3x4& a, const Affine3x4& b) {
    Affine3x4 out;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
            double v = c == 3 ? double(a.at(r, 3)) : 0.0;
            for (int k = 0; k < 3; ++k) v += double(a.at(r, k)) * double(b.at(k, c));
            out.m[size_t(r * 4 + c)] = float(v);
        }
    return out;
}

bool invert(const Affine3x4& a, Affine3x4& out) {
    for (float v : a.m)
        if (!std::isfinite(v)) return false;
    const double det = a.determinant();
    if (!std::isfinite(det) || det == 0.0) return false;
    const auto e = [&a](int r, int c) { return double(a.at(r, c)); };
    // The adjugate over the determinant, then -L^-1 t for the translation.
    double inv[3][3] = {
        {e(1, 1) * e(2, 2) - e(1, 2) * e(2, 1), e(0, 2) * e(2, 1) - e(0, 1) * e(2, 2),
         e(0, 1) * e(1, 2) - e(0, 2) * e(1, 1)},
        {e(1, 2) * e(2, 0) - e(1, 0) * e(2, 2), e(0, 0) * e(2, 2) - e(0, 2) * e(2, 0),
         e(0, 2) * e(1, 0) - e(0, 0) * e(1, 2)},
        {e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0), e(0, 1) * e(2, 0) - e(0, 0) * e(2, 1),
         e(0, 0) * e(1, 1) - e(0, 1) * e(1, 0)}};
    Affine3x4 r;
    for (int i = 0; i < 3; ++i) {
        double t = 0;
        for (int j = 0; j < 3; ++j) {
            inv[i][j] /= det;
            r.m[size_t(i * 4 + j)] = float(inv[i][j]);
            t -= inv[i][j] * e(j, 3);
        }
        r.m[size_t(i * 4 + 3)] = float(t);
    }
    for (float v : r.m)
        if (!std::isfinite(v)) return false;
    out = r;
    return true;
}

AABB transform_box(const Affine3x4& a, const AABB& b) {
    AABB out;
    if (b.empty()) return out;
    for (int corner = 0; corner < 8; ++corner)
        out.grow(a.point(Vec3(corner & 1 ? b.hi.x : b.lo.x, corner & 2 ? b.hi.y : b.lo.y,
                              corner & 4 ? b.hi.z : b.lo.z)));
    return out;
}

uint64_t InstancedScene::unique_triangle_count() const {
    uint64_t n = 0;
    for (const Scene& m : meshes) n += m.triangle_count();
    return n;
}

uint64_t InstancedScene::instanced_triangle_count() const {
    uint64_t n = 0;
    for (const Instance& i : instances)
        n += i.mesh < meshes.size() ? meshes[i.mesh].triangle_count() : 0;
    return n;
}

AABB InstancedScene::bounds() const {
    std::vector<AABB> mesh_box(meshes.size());
    for (size_t k = 0; k < meshes.size(); ++k) mesh_box[k] = meshes[k].bounds();
    AABB b;
    for (const Instance& i : instances) b.grow(transform_box(i.object_to_world, mesh_box[i.mesh]));
    return b;
}

uint64_t InstancedScene::content_hash() const {
    uint64_t h = kFnvOffset;
    for (const Scene& m : meshes) {
        const uint64_t mh = m.content_hash();
        h = fnv1a(h, &mh, sizeof mh);
    }
    for (const Instance& i : instances) {
        h = fnv1a(h, i.object_to_world.m.data(), sizeof(float) * 12);
        const uint32_t rest[3] = {i.mesh, i.mask, i.opaque};
        h = fnv1a(h, rest, sizeof rest);
    }
    for (const AlphaMask& a : alpha) {  // (none: the hash of a scene without masks)
        const uint32_t fields[3] = {uint32_t(a.pattern), a.seed, a.cells};
        h = fnv1a(h, fields, sizeof fields);
        h = fnv1a(h, &a.keep, sizeof a.keep);
        if (a.texture) {
            const AlphaTexture& t = *a.texture;
            const uint32_t size[2] = {t.width, t.height};
            const float levels[2] = {t.factor, t.cutoff};
            h = fnv1a(h, size, sizeof size);
            h = fnv1a(h, levels, sizeof levels);
            h = fnv1a(h, t.alpha.data(), t.alpha.size());
            h = fnv1a(h, t.corner_st.data(), t.corner_st.size() * sizeof(t.corner_st[0]));
        }
    }
    return h;
}

void InstancedScene::validate() const {
    const std::string& name = source.empty() ? this->name : source;  // errors name the file
    if (instances.empty()) throw InputError(fmt::format("{}: the scene has no instances", name));
    for (size_t k = 0; k < meshes.size(); ++k)
        if (meshes[k].triangles.empty())
            throw InputError(
                fmt::format("{}: mesh {} ({}) has no triangles", name, k, meshes[k].name));
    Affine3x4 inverse;
    for (size_t k = 0; k < instances.size(); ++k) {
        if (instances[k].mesh >= meshes.size())
            throw InputError(fmt::format("{}: instance {} names mesh {}, but the scene has {}",
                                         name, k, instances[k].mesh, meshes.size()));
        if (!invert(instances[k].object_to_world, inverse))
            throw InputError(fmt::format(
                "{}: instance {} has a singular or non-finite transform (determinant {:g})", name,
                k, instances[k].object_to_world.determinant()));
    }
}

TwoLevelBvh build_two_level(const InstancedScene& scene, const BvhBuildOptions& options,
                            const BvhLayout& layout_sizes, const std::string& cache_dir,
                            size_t* blas_cache_hits) {
    scene.validate();
    check_prepare_memory(scene.source.empty() ? scene.name : scene.source,
                         scene.unique_triangle_count(), scene.instances.size());
    TwoLevelBvh two;
    two.options = options;
    two.instances = scene.instances;
    for (uint32_t m = 0; m < scene.meshes.size(); ++m) two.alpha.push_back(scene.mesh_alpha(m));
    if (blas_cache_hits) *blas_cache_hits = 0;
    for (const Scene& mesh : scene.meshes) {
        BvhCacheStatus status;
        two.blas.push_back(build_bvh_cached(mesh, options, layout_sizes, cache_dir, &status));
        if (blas_cache_hits && status.outcome == BvhCacheOutcome::Hit) ++*blas_cache_hits;
    }
    // The TLAS is built by the same builders over a proxy scene whose triangle k spans instance
    // k's world box exactly (corners lo and hi), so its leaves' slots name instances.
    Scene proxy;
    proxy.name = scene.name + " (instances)";
    std::vector<Vec3> corners;
    std::vector<std::array<uint32_t, 3>> tris;
    two.world_to_object.resize(scene.instances.size());
    for (size_t k = 0; k < scene.instances.size(); ++k) {
        const Instance& inst = scene.instances[k];
        invert(inst.object_to_world, two.world_to_object[k]);  // validate() checked it
        const AABB box = transform_box(inst.object_to_world, two.blas[inst.mesh].bounds());
        const auto v = uint32_t(corners.size());
        corners.push_back(box.lo);
        corners.push_back(box.hi);
        tris.push_back({v, v + 1, v});
    }
    proxy.vertices = std::move(corners);
    proxy.triangles = std::move(tris);
    BvhLayout tlas_layout = layout_sizes;
    tlas_layout.tri_size_bytes = two.instance_size_bytes;
    two.tlas = build_bvh(proxy, options, tlas_layout);
    // One address space: the TLAS's nodes, then each BLAS's; the instance records where the
    // TLAS's triangles would be; then every BLAS's triangles.
    const uint64_t page = 4096;
    const uint32_t node_bytes = two.tlas.layout.node_size_bytes;
    two.tlas_node_count = two.tlas.layout.inner_node_count;
    uint64_t nodes = two.tlas_node_count, tris_total = 0;
    for (const Bvh& b : two.blas) {
        two.blas_node_offset.push_back(uint32_t(nodes));
        two.blas_tri_offset.push_back(uint32_t(tris_total));
        nodes += b.layout.inner_node_count;
        tris_total += b.layout.triangle_count;
    }
    if (nodes > UINT32_MAX || tris_total > UINT32_MAX)
        throw InputError(fmt::format("{}: more than 2^32 nodes or triangles", scene.name));
    const uint64_t node_base = two.tlas.layout.node_base_addr;
    two.instance_base_addr = (node_base + nodes * node_bytes + page - 1) / page * page;
    two.tlas.layout.tri_base_addr = two.instance_base_addr;
    const uint64_t tri_base =
        (two.instance_base_addr + scene.instances.size() * two.instance_size_bytes + page - 1) /
        page * page;
    for (size_t k = 0; k < two.blas.size(); ++k) {
        BvhLayout& L = two.blas[k].layout;
        L.node_base_addr = node_base + uint64_t(two.blas_node_offset[k]) * node_bytes;
        L.tri_base_addr = tri_base + uint64_t(two.blas_tri_offset[k]) * L.tri_size_bytes;
    }
    BvhLayout& G = two.layout;
    G = two.tlas.layout;
    G.inner_node_count = uint32_t(nodes);
    G.tri_base_addr = tri_base;
    G.tri_size_bytes =
        two.blas.empty() ? layout_sizes.tri_size_bytes : two.blas[0].layout.tri_size_bytes;
    G.triangle_count = uint32_t(tris_total);
    G.instance_base_addr = two.instance_base_addr;
    G.instance_size_bytes = two.instance_size_bytes;
    G.instance_count = uint32_t(scene.instances.size());
    // Alpha data after the triangles, in the same slot order, when any-hit shaders may read it.
    const bool any_non_opaque = std::any_of(scene.instances.begin(), scene.instances.end(),
                                            [](const Instance& i) { return !i.opaque; });
    G.alpha_size_bytes = layout_sizes.alpha_size_bytes;
    G.alpha_count = any_non_opaque ? G.triangle_count : 0;
    G.alpha_base_addr =
        any_non_opaque ? (tri_base + G.tri_bytes_total() + page - 1) / page * page : 0;
    // Treelets: the TLAS's (its node records and the instance records of its leaves), then each
    // BLAS's (its node records and triangle slots), as one table in the global numbering.
    G.treelet_node_start.clear();
    G.treelet_tri_start.clear();
    G.treelet_instance_start.clear();
    if (options.treelet_bytes > 0) {
        const BvhLayout& T = two.tlas.layout;
        G.treelet_node_start = {0};
        G.treelet_tri_start = {0};
        G.treelet_instance_start = {0};
        for (uint32_t k = 0; k < T.treelet_count(); ++k) {
            G.treelet_node_start.push_back(T.treelet_node_start[k + 1]);
            G.treelet_tri_start.push_back(0);
            G.treelet_instance_start.push_back(T.treelet_tri_start[k + 1]);
        }
        for (size_t b = 0; b < two.blas.size(); ++b) {
            const BvhLayout& B = two.blas[b].layout;
            for (uint32_t k = 0; k < B.treelet_count(); ++k) {
                G.treelet_node_start.push_back(two.blas_node_offset[b] +
                                               B.treelet_node_start[k + 1]);
                G.treelet_tri_start.push_back(two.blas_tri_offset[b] + B.treelet_tri_start[k + 1]);
                G.treelet_instance_start.push_back(G.instance_count);
            }
        }
    }
    if (!G.index_treelets())
        throw std::logic_error("build_two_level: treelet tables do not cover the layout");
    return two;
}

}  // namespace rtsim

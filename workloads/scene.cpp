#include "workloads/scene.h"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <fmt/format.h>
#include <assimp/Importer.hpp>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "workloads/error.h"

namespace rtsim {

AABB Scene::bounds() const {
    AABB b;
    for (const auto& t : triangles)
        for (uint32_t i : t) b.grow(vertices[i]);
    return b;
}

AABB Scene::triangle_bounds(uint32_t prim) const {
    AABB b;
    for (int c = 0; c < 3; ++c) b.grow(v(prim, c));
    return b;
}

uint64_t Scene::content_hash() const {
    uint64_t h = 1469598103934665603ull;
    auto mix = [&h](const void* data, size_t n) {
        const auto* p = static_cast<const unsigned char*>(data);
        for (size_t i = 0; i < n; ++i) {
            h ^= p[i];
            h *= 1099511628211ull;
        }
    };
    mix(vertices.data(), vertices.size() * sizeof(Vec3));
    mix(triangles.data(), triangles.size() * sizeof(triangles[0]));
    return h;
}

namespace {

void append_node(const aiScene* ai, const aiNode* node, const aiMatrix4x4& parent, Scene& out) {
    const aiMatrix4x4 xf = parent * node->mTransformation;
    for (unsigned m = 0; m < node->mNumMeshes; ++m) {
        const aiMesh* mesh = ai->mMeshes[node->mMeshes[m]];
        if (!(mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
        const auto base = static_cast<uint32_t>(out.vertices.size());
        for (unsigned i = 0; i < mesh->mNumVertices; ++i) {
            aiVector3D p = xf * mesh->mVertices[i];
            out.vertices.emplace_back(p.x, p.y, p.z);
        }
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const aiFace& face = mesh->mFaces[f];
            if (face.mNumIndices != 3) continue;  // points and lines carry no surface
            out.triangles.push_back(
                {base + face.mIndices[0], base + face.mIndices[1], base + face.mIndices[2]});
        }
    }
    for (unsigned c = 0; c < node->mNumChildren; ++c) append_node(ai, node->mChildren[c], xf, out);
}

}  // namespace

Scene load_scene(const std::string& spec) {
    constexpr const char* kBuiltin = "builtin:";
    if (spec.rfind(kBuiltin, 0) == 0) return make_builtin_scene(spec.substr(std::strlen(kBuiltin)));

    namespace fs = std::filesystem;
    std::error_code ec;
    if (!fs::exists(spec, ec)) throw InputError(fmt::format("{}: scene file not found", spec));
    if (fs::is_directory(spec, ec))
        throw InputError(fmt::format("{}: is a directory, expected a mesh file", spec));

    Scene scene;
    std::string ext = fs::path(spec).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".off") {
        scene = read_off(spec);
    } else {
        read_with_assimp(spec, scene);
    }
    scene.name = fs::path(spec).filename().string();
    scene.source = spec;
    if (scene.triangles.empty()) throw InputError(fmt::format("{}: mesh has no triangles", spec));
    for (const Vec3& p : scene.vertices)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw InputError(fmt::format("{}: mesh has a non-finite vertex coordinate", spec));
    return scene;
}

void read_with_assimp(const std::string& spec, Scene& scene) {
    Assimp::Importer importer;
    // Triangulate splits polygons in file order; no vertex joining or sorting, so primitive ids
    // follow the file's own face order.
    const aiScene* ai = importer.ReadFile(spec, aiProcess_Triangulate);
    if (!ai || !ai->mRootNode || (ai->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
        std::string why = importer.GetErrorString();
        for (char& c : why)
            if (c == '\n' || c == '\r') c = ' ';
        throw InputError(
            fmt::format("{}: cannot read mesh: {}", spec, why.empty() ? "unknown format" : why));
    }
    append_node(ai, ai->mRootNode, aiMatrix4x4(), scene);
}

}  // namespace rtsim

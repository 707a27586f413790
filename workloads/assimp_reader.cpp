// The mesh formats read through assimp (all but OFF), built as a module of its own
// (librtsim_assimp.so) that read_with_assimp loads when a file first needs it. assimp and the
// libraries it brings (draco, minizip) then cost a process nothing unless it parses such a file:
// linked in, their loading and relocation took about 6 ms of every rtsim process (a bare SystemC
// program starts in 8.7 ms, the same linked with assimp in 15 ms), while a run whose mesh is in
// the mesh cache (workloads/mesh_cache.h) never calls them.
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/Importer.hpp>
#include <string>

#include "workloads/assimp_reader.h"
#include "workloads/scene.h"

namespace {

void append_node(const aiScene* ai, const aiNode* node, const aiMatrix4x4& parent,
                 rtsim::Scene& out) {
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

extern "C" __attribute__((visibility("default"))) bool rtsim_assimp_read(const char* path,
                                                                         rtsim::Scene* scene,
                                                                         std::string* error) {
    Assimp::Importer importer;
    // Triangulate splits polygons in file order; no vertex joining or sorting, so primitive ids
    // follow the file's own face order.
    const aiScene* ai = importer.ReadFile(path, aiProcess_Triangulate);
    if (!ai || !ai->mRootNode || (ai->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
        *error = importer.GetErrorString();
        return false;
    }
    append_node(ai, ai->mRootNode, aiMatrix4x4(), *scene);
    return true;
}

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

#include <vector>

#include "workloads/assimp_reader.h"
#include "workloads/instances.h"
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

bool has_triangles(const aiMesh* mesh) {
    return (mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) != 0;
}

// Per mesh, the nodes that place it.
void count_placements(const aiScene* ai, const aiNode* node, std::vector<unsigned>& count) {
    for (unsigned m = 0; m < node->mNumMeshes; ++m) count[node->mMeshes[m]]++;
    for (unsigned c = 0; c < node->mNumChildren; ++c)
        count_placements(ai, node->mChildren[c], count);
}

// One instance per node placement of a mesh with triangles, in the order append_node visits
// them, with the node's global transform (assimp's matrices are row-major, as Affine3x4).
void add_instances(const aiNode* node, const aiMatrix4x4& parent,
                   const std::vector<int>& blas_of_mesh, rtsim::InstancedScene& out) {
    const aiMatrix4x4 xf = parent * node->mTransformation;
    for (unsigned m = 0; m < node->mNumMeshes; ++m) {
        const int blas = blas_of_mesh[node->mMeshes[m]];
        if (blas < 0) continue;
        rtsim::Instance inst;
        inst.mesh = uint32_t(blas);
        inst.object_to_world.m = {xf.a1, xf.a2, xf.a3, xf.a4, xf.b1, xf.b2,
                                  xf.b3, xf.b4, xf.c1, xf.c2, xf.c3, xf.c4};
        out.instances.push_back(inst);
    }
    for (unsigned c = 0; c < node->mNumChildren; ++c)
        add_instances(node->mChildren[c], xf, blas_of_mesh, out);
}

// Each placed mesh with triangles once, in object space, in the file's mesh order.
void add_meshes(const aiScene* ai, const std::vector<unsigned>& placements,
                std::vector<int>& blas_of_mesh, rtsim::InstancedScene& out) {
    for (unsigned k = 0; k < ai->mNumMeshes; ++k) {
        const aiMesh* mesh = ai->mMeshes[k];
        if (!placements[k] || !has_triangles(mesh)) continue;
        rtsim::Scene s;
        s.name = mesh->mName.length ? mesh->mName.C_Str() : "mesh " + std::to_string(k);
        for (unsigned i = 0; i < mesh->mNumVertices; ++i)
            s.vertices.emplace_back(mesh->mVertices[i].x, mesh->mVertices[i].y,
                                    mesh->mVertices[i].z);
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const aiFace& face = mesh->mFaces[f];
            if (face.mNumIndices == 3)
                s.triangles.push_back({face.mIndices[0], face.mIndices[1], face.mIndices[2]});
        }
        if (s.triangles.empty()) continue;
        blas_of_mesh[k] = int(out.meshes.size());
        out.meshes.push_back(std::move(s));
    }
}

}  // namespace

extern "C" __attribute__((visibility("default"))) bool rtsim_assimp_read(
    const char* path, rtsim::Scene* scene, rtsim::InstancedScene* instanced, bool* shared,
    std::string* error) {
    Assimp::Importer importer;
    // Triangulate splits polygons in file order; no vertex joining or sorting, so primitive ids
    // follow the file's own face order.
    const aiScene* ai = importer.ReadFile(path, aiProcess_Triangulate);
    if (!ai || !ai->mRootNode || (ai->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
        *error = importer.GetErrorString();
        return false;
    }
    std::vector<unsigned> placements(ai->mNumMeshes, 0);
    count_placements(ai, ai->mRootNode, placements);
    *shared = false;
    for (unsigned k = 0; k < ai->mNumMeshes; ++k)
        *shared = *shared || (placements[k] > 1 && has_triangles(ai->mMeshes[k]));
    if (*shared && instanced) {
        std::vector<int> blas_of_mesh(ai->mNumMeshes, -1);
        add_meshes(ai, placements, blas_of_mesh, *instanced);
        add_instances(ai->mRootNode, aiMatrix4x4(), blas_of_mesh, *instanced);
        return true;
    }
    append_node(ai, ai->mRootNode, aiMatrix4x4(), *scene);
    return true;
}

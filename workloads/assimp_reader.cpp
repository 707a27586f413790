// The mesh formats read through assimp (all but OFF), built as a module of its own
// (librtsim_assimp.so) that read_with_assimp loads when a file first needs it. assimp and the
// libraries it brings (draco, minizip) then cost a process nothing unless it parses such a file:
// linked in, their loading and relocation took about 6 ms of every rtsim process (a bare SystemC
// program starts in 8.7 ms, the same linked with assimp in 15 ms), while a run whose mesh is in
// the mesh cache (workloads/mesh_cache.h) never calls them.
#include <assimp/GltfMaterial.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <png.h>

#include <assimp/Importer.hpp>
#include <cstring>
#include <filesystem>
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

// The alpha channel of a PNG (in memory when `size` > 0, else the file `where`); false if it
// cannot be decoded. Other image formats (JPEG) carry no alpha.
bool read_png_alpha(const void* bytes, size_t size, const std::string& where,
                    rtsim::AlphaTexture& out) {
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    const bool begun = size ? png_image_begin_read_from_memory(&image, bytes, size)
                            : png_image_begin_read_from_file(&image, where.c_str());
    if (!begun) return false;
    image.format = PNG_FORMAT_GA;  // grey and alpha: the alpha is all a mask needs
    std::vector<uint8_t> ga(PNG_IMAGE_SIZE(image));
    if (!png_image_finish_read(&image, nullptr, ga.data(), 0, nullptr)) {
        png_image_free(&image);
        return false;
    }
    out.width = image.width;
    out.height = image.height;
    out.alpha.resize(size_t(image.width) * image.height);
    for (size_t i = 0; i < out.alpha.size(); ++i) out.alpha[i] = ga[2 * i + 1];
    return true;
}

// Whether the mesh's material is glTF's alphaMode MASK.
bool is_masked(const aiScene* ai, const aiMesh* mesh) {
    if (mesh->mMaterialIndex >= ai->mNumMaterials) return false;
    aiString mode;
    return ai->mMaterials[mesh->mMaterialIndex]->Get(AI_MATKEY_GLTF_ALPHAMODE, mode) ==
               AI_SUCCESS &&
           std::strcmp(mode.C_Str(), "MASK") == 0;
}

// A mesh's alpha mask from its material, if the material is glTF's alphaMode MASK: the base
// colour factor's alpha, its cutoff, and the base colour texture's alpha (embedded, or a file
// beside the model) with the mesh's texture coordinates per triangle corner. `error` is set
// when the texture is named but cannot be read.
rtsim::AlphaMask material_alpha(const aiScene* ai, const aiMesh* mesh, const std::string& model,
                                std::string* error) {
    rtsim::AlphaMask mask;
    if (!is_masked(ai, mesh)) return mask;
    const aiMaterial* mat = ai->mMaterials[mesh->mMaterialIndex];
    auto tex = std::make_shared<rtsim::AlphaTexture>();
    float cutoff = 0.5f;
    if (mat->Get(AI_MATKEY_GLTF_ALPHACUTOFF, cutoff) == AI_SUCCESS) tex->cutoff = cutoff;
    aiColor4D colour(1, 1, 1, 1);
    if (mat->Get(AI_MATKEY_BASE_COLOR, colour) == AI_SUCCESS ||
        mat->Get(AI_MATKEY_COLOR_DIFFUSE, colour) == AI_SUCCESS)
        tex->factor = colour.a;
    aiString file;
    unsigned uv_channel = 0;
    bool textured = false;
    for (const aiTextureType type : {aiTextureType_BASE_COLOR, aiTextureType_DIFFUSE})
        if (mat->GetTexture(type, 0, &file, nullptr, &uv_channel) == AI_SUCCESS) {
            textured = true;
            break;
        }
    if (textured && uv_channel < AI_MAX_NUMBER_OF_TEXTURECOORDS &&
        mesh->mTextureCoords[uv_channel]) {
        bool read = false;
        if (const aiTexture* embedded = ai->GetEmbeddedTexture(file.C_Str())) {
            if (embedded->mHeight == 0) {  // compressed: mWidth bytes of a PNG or JPEG file
                read = !embedded->CheckFormat("png") ||
                       read_png_alpha(embedded->pcData, embedded->mWidth, model, *tex);
            } else {  // texels, ARGB8888
                tex->width = embedded->mWidth;
                tex->height = embedded->mHeight;
                tex->alpha.resize(size_t(tex->width) * tex->height);
                for (size_t i = 0; i < tex->alpha.size(); ++i)
                    tex->alpha[i] = embedded->pcData[i].a;
                read = true;
            }
        } else {
            const std::string path =
                (std::filesystem::path(model).parent_path() / file.C_Str()).string();
            const std::string ext = std::filesystem::path(path).extension().string();
            read = (ext != ".png" && ext != ".PNG") || read_png_alpha(nullptr, 0, path, *tex);
            if (!read) *error = "cannot read the alpha texture " + path;
        }
        if (!read && error->empty()) *error = "cannot decode an embedded alpha texture";
        if (tex->width) {
            const aiVector3D* st = mesh->mTextureCoords[uv_channel];
            for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
                const aiFace& face = mesh->mFaces[f];
                if (face.mNumIndices != 3) continue;
                std::array<float, 6> c;
                for (int k = 0; k < 3; ++k) {
                    c[size_t(2 * k)] = st[face.mIndices[k]].x;
                    c[size_t(2 * k + 1)] = st[face.mIndices[k]].y;
                }
                tex->corner_st.push_back(c);
            }
        }
    }
    mask.pattern = rtsim::AlphaPattern::Texture;
    mask.texture = std::move(tex);
    return mask;
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
        inst.opaque = out.mesh_alpha(inst.mesh).pattern == rtsim::AlphaPattern::None;
        inst.object_to_world.m = {xf.a1, xf.a2, xf.a3, xf.a4, xf.b1, xf.b2,
                                  xf.b3, xf.b4, xf.c1, xf.c2, xf.c3, xf.c4};
        out.instances.push_back(inst);
    }
    for (unsigned c = 0; c < node->mNumChildren; ++c)
        add_instances(node->mChildren[c], xf, blas_of_mesh, out);
}

// Each placed mesh with triangles once, in object space, in the file's mesh order, with its
// material's alpha mask.
bool add_meshes(const aiScene* ai, const std::vector<unsigned>& placements, const char* model,
                std::vector<int>& blas_of_mesh, rtsim::InstancedScene& out, std::string* error) {
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
        out.alpha.push_back(material_alpha(ai, mesh, model, error));
        if (!error->empty()) return false;
    }
    out.drop_alpha_if_none();
    return true;
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
    // Files whose nodes share meshes, or whose materials cut geometry out (alphaMode MASK: the
    // masks live with a scene of instances), keep their instances.
    *shared = false;
    for (unsigned k = 0; k < ai->mNumMeshes; ++k)
        *shared = *shared || (placements[k] && has_triangles(ai->mMeshes[k]) &&
                              (placements[k] > 1 || is_masked(ai, ai->mMeshes[k])));
    if (*shared && instanced) {
        std::vector<int> blas_of_mesh(ai->mNumMeshes, -1);
        error->clear();
        if (!add_meshes(ai, placements, path, blas_of_mesh, *instanced, error)) return false;
        add_instances(ai->mRootNode, aiMatrix4x4(), blas_of_mesh, *instanced);
        return true;
    }
    append_node(ai, ai->mRootNode, aiMatrix4x4(), *scene);
    return true;
}

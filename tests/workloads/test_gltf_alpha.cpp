// glTF materials with alphaMode MASK (workloads/assimp_reader.cpp): a hand-made file of two
// quads, the front one masked by a 2 x 2 PNG whose texels are known, the back one opaque. Rays
// through each quarter of the front quad hit it where factor x texel alpha >= alphaCutoff and
// pass on to the back quad elsewhere; the answer is worked out from the texels by hand.
#include <gtest/gtest.h>
#include <png.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "support/input_error.h"
#include "support/scratch_dir.h"
#include "workloads/instances.h"
#include "workloads/scene.h"
#include "workloads/scene_file.h"

namespace fs = std::filesystem;
using namespace rtsim;

namespace {

// A 2 x 2 RGBA PNG whose alphas are, row 0 (the image's top) first: a00 a01 / a10 a11.
void write_png(const fs::path& path, const uint8_t alpha[4]) {
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    image.width = image.height = 2;
    image.format = PNG_FORMAT_RGBA;
    std::vector<uint8_t> rgba(16, 200);
    for (int i = 0; i < 4; ++i) rgba[size_t(4 * i + 3)] = alpha[i];
    ASSERT_TRUE(png_image_write_to_file(&image, path.c_str(), 0, rgba.data(), 0, nullptr));
}

// Two unit quads in x, y: the front one at z = 0 with texture coordinates (x, 1 - y) (glTF's t
// runs down the image), masked; the back one at z = -1, opaque. Returns the .gltf path.
std::string write_quads(const fs::path& dir, float factor, float cutoff, const char* image) {
    fs::create_directories(dir);
    std::vector<float> pos = {0,  0,  0,  1, 0,  0,  1, 1, 0,  0,  1, 0,
                              -1, -1, -1, 2, -1, -1, 2, 2, -1, -1, 2, -1};
    std::vector<float> st = {0, 1, 1, 1, 1, 0, 0, 0};
    std::vector<uint16_t> idx = {0, 1, 2, 0, 2, 3};
    std::ofstream bin(dir / "quads.bin", std::ios::binary);
    bin.write(reinterpret_cast<const char*>(pos.data()), 96);
    bin.write(reinterpret_cast<const char*>(st.data()), 32);
    bin.write(reinterpret_cast<const char*>(idx.data()), 12);
    bin.close();
    const std::string gltf = R"({
      "asset": {"version": "2.0"},
      "scene": 0, "scenes": [{"nodes": [0, 1]}],
      "nodes": [{"mesh": 0}, {"mesh": 1}],
      "meshes": [
        {"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 2}, "indices": 4,
                         "material": 0}]},
        {"primitives": [{"attributes": {"POSITION": 1}, "indices": 4, "material": 1}]}],
      "materials": [
        {"alphaMode": "MASK", "alphaCutoff": )" +
                             std::to_string(cutoff) + R"(,
         "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, )" +
                             std::to_string(factor) + R"(], "baseColorTexture": {"index": 0}}},
        {"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}}],
      "textures": [{"source": 0}],
      "images": [{"uri": ")" +
                             std::string(image) +
                             R"("}],
      "buffers": [{"uri": "quads.bin", "byteLength": 140}],
      "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                      {"buffer": 0, "byteOffset": 48, "byteLength": 48},
                      {"buffer": 0, "byteOffset": 96, "byteLength": 32},
                      {"buffer": 0, "byteOffset": 128, "byteLength": 12}],
      "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
         "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3",
         "min": [-1, -1, -1], "max": [2, 2, -1]},
        {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
        {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
        {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}]
    })";
    std::ofstream(dir / "quads.gltf") << gltf;
    return (dir / "quads.gltf").string();
}

// The distance at which a ray down -z from (x, y, 1) stops: 1 on the front quad, 2 on the back.
float depth_at(const TwoLevelBvh& bvh, float x, float y, HitQuery query) {
    Ray r;
    r.org = Vec3(x, y, 1);
    r.dir = Vec3(0, 0, -1);
    const Hit h = trace_ray(bvh, r, query);
    return h.valid() ? h.t : -1.0f;
}

}  // namespace

TEST(GltfAlpha, MaskedMaterialsCutOutWhereTheTextureSays) {
    const fs::path dir = test::scratch_dir() / "gltf-alpha";
    const uint8_t alpha[4] = {255, 128, 0, 255};
    fs::create_directories(dir);
    write_png(dir / "mask.png", alpha);
    // Quarter centres, (x, y) -> texel (column floor(2x), row floor(2(1 - y))).
    struct Quarter {
        float x, y;
        int texel;
    };
    const Quarter quarters[4] = {
        {0.25f, 0.75f, 0}, {0.75f, 0.75f, 1}, {0.25f, 0.25f, 2}, {0.75f, 0.25f, 3}};
    struct Case {
        float factor, cutoff;
    };
    for (const Case c : {Case{1.0f, 0.5f}, Case{0.6f, 0.5f}, Case{1.0f, 0.3f}}) {
        SCOPED_TRACE(testing::Message() << "factor " << c.factor << " cutoff " << c.cutoff);
        const std::string path = write_quads(dir, c.factor, c.cutoff, "mask.png");
        InstancedScene scene;
        bool kept = false;
        load_scene(path, &scene, &kept);
        ASSERT_TRUE(kept) << "a masked file keeps its instances";
        ASSERT_EQ(scene.meshes.size(), 2u);
        ASSERT_EQ(scene.instances.size(), 2u);
        EXPECT_FALSE(scene.instances[0].opaque);
        EXPECT_TRUE(scene.instances[1].opaque);
        for (const int width : {2, 8}) {
            BvhBuildOptions o;
            o.width = width;
            const TwoLevelBvh bvh = build_two_level(scene, o);
            for (const Quarter& q : quarters) {
                const bool solid = c.factor * float(alpha[q.texel]) / 255.0f >= c.cutoff;
                EXPECT_FLOAT_EQ(depth_at(bvh, q.x, q.y, HitQuery::Closest), solid ? 1.0f : 2.0f)
                    << "quarter " << q.texel << " width " << width;
            }
        }
    }
}

TEST(GltfAlpha, AnUnreadableAlphaTextureIsAnError) {
    const fs::path dir = test::scratch_dir() / "gltf-alpha-missing";
    const std::string path = write_quads(dir, 1.0f, 0.5f, "missing.png");
    InstancedScene scene;
    bool kept = false;
    test::expect_input_error([&] { load_scene(path, &scene, &kept); }, path, "missing.png");
}

// A scene file nesting the masked file keeps its masks and opaque flags in every copy, unless
// the entry gives a mask of its own.
TEST(GltfAlpha, SceneFilesKeepANestedFilesMasks) {
    const fs::path dir = test::scratch_dir() / "gltf-alpha-nested";
    const uint8_t alpha[4] = {255, 0, 0, 255};
    fs::create_directories(dir);
    write_png(dir / "mask.png", alpha);
    write_quads(dir, 1.0f, 0.5f, "mask.png");
    std::ofstream(dir / "two.json") << R"({"meshes": {"q": "quads.gltf"},
        "instances": [{"mesh": "q", "grid": {"count": [2, 1, 1], "spacing": [10, 0, 0]}}]})";
    const InstancedScene scene = load_scene_file((dir / "two.json").string());
    ASSERT_EQ(scene.instances.size(), 4u);
    const TwoLevelBvh bvh = build_two_level(scene, BvhBuildOptions());
    for (const float dx : {0.0f, 10.0f}) {
        EXPECT_FLOAT_EQ(depth_at(bvh, dx + 0.25f, 0.75f, HitQuery::Closest), 1.0f);
        EXPECT_FLOAT_EQ(depth_at(bvh, dx + 0.75f, 0.75f, HitQuery::Closest), 2.0f);
    }
    // An entry's own mask replaces the file's: every triangle kept.
    std::ofstream(dir / "kept.json") << R"({"meshes": {"q": {"file": "quads.gltf",
        "alpha": {"pattern": "triangles", "keep": 1}}}, "instances": [{"mesh": "q"}]})";
    const TwoLevelBvh kept =
        build_two_level(load_scene_file((dir / "kept.json").string()), BvhBuildOptions());
    EXPECT_FLOAT_EQ(depth_at(kept, 0.75f, 0.75f, HitQuery::Closest), 1.0f);
}

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "support/input_error.h"
#include "support/scratch_dir.h"
#include "workloads/error.h"
#include "workloads/scene.h"

namespace fs = std::filesystem;
using namespace rtsim;

namespace {

std::string write_temp(const std::string& name, const std::string& text) {
    const fs::path p = test::scratch_dir() / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
}

// load_scene(path) must fail with one line naming the file and containing `fragment`.
void expect_input_error(const std::string& path, const std::string& fragment) {
    test::expect_input_error([&] { load_scene(path); }, path, fragment);
}

}  // namespace

TEST(Scene, BuiltinScenesNeedNoFile) {
    for (const std::string& name : builtin_scene_names()) {
        Scene s = load_scene("builtin:" + name);
        EXPECT_GT(s.triangle_count(), 1000u) << name;
        EXPECT_FALSE(s.bounds().empty());
        for (const auto& t : s.triangles)
            for (uint32_t i : t) ASSERT_LT(i, s.vertices.size());
    }
    EXPECT_THROW(load_scene("builtin:nope"), InputError);
}

TEST(Scene, BuiltinCornellHasExpectedTriangleCount) {
    // 5 walls of 16x16 quads, 2 boxes of 6 faces x 8x8 quads, icosphere level 5.
    EXPECT_EQ(load_scene("builtin:cornell").triangle_count(), 5u * 512 + 2u * 6 * 128 + 20u * 1024);
}

TEST(Scene, ContentHashIdentifiesGeometry) {
    Scene a = load_scene("builtin:sphere"), b = load_scene("builtin:sphere");
    EXPECT_EQ(a.content_hash(), b.content_hash());
    b.vertices.mutable_at(0).x += 1e-3f;
    EXPECT_NE(a.content_hash(), b.content_hash());
}

TEST(Scene, LoadsGlmark2BunnyInFileOrder) {
    ASSERT_TRUE(fs::exists(RTSIM_BUNNY_OBJ)) << "run scripts/setup.sh (package glmark2-data)";
    Scene s = load_scene(RTSIM_BUNNY_OBJ);
    // Count the file's faces independently of the loader: every face of this OBJ is a triangle.
    std::ifstream in(RTSIM_BUNNY_OBJ);
    std::string line;
    size_t faces = 0;
    while (std::getline(in, line)) faces += line.rfind("f ", 0) == 0;
    EXPECT_EQ(s.triangle_count(), faces);
    EXPECT_EQ(s.name, "bunny.obj");
}

TEST(Scene, LoadsEveryCgalDemoMesh) {
    const fs::path dir = RTSIM_CGAL_MESH_DIR;
    ASSERT_TRUE(fs::is_directory(dir)) << "run scripts/setup.sh to fetch libcgal-demo's meshes";
    int loaded = 0;
    for (const auto& e : fs::directory_iterator(dir)) {
        if (e.path().extension() != ".off") continue;
        Scene s;
        ASSERT_NO_THROW(s = load_scene(e.path().string())) << e.path();
        EXPECT_GT(s.triangle_count(), 0u) << e.path();
        ++loaded;
    }
    EXPECT_GE(loaded, 100);
}

TEST(Scene, OffCommentsColorsAndPolygons) {
    const std::string p =
        write_temp("poly.off",
                   "# leading comment\nCOFF\n5 2 0\n0 0 0 255 0 0 # red\n1 0 0\n1 1 0\n"
                   "0 1 0\n0.5 2 0\n4 0 1 2 3 0.5 0.5 0.5\n3 3 2 4\n");
    Scene s = load_scene(p);
    ASSERT_EQ(s.triangle_count(), 3u);  // quad -> 2-triangle fan, then the triangle
    EXPECT_EQ(s.triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));
    EXPECT_EQ(s.triangles[1], (std::array<uint32_t, 3>{0, 2, 3}));
    EXPECT_EQ(s.triangles[2], (std::array<uint32_t, 3>{3, 2, 4}));
}

// Found by fuzzing (scripts/fuzz.sh, fuzz_off): counts are claims, not allocations. A face of
// 1.2e17 vertices asked for 480 PB; a short file claiming 2^30 vertices reserved 12 GiB. Both are
// now one-line errors, quickly.
TEST(Scene, OffCountsBeyondTheFileAreErrorsNotAllocations) {
    const std::string face =
        write_temp("huge_face.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n121111111111111111 0 1 2\n");
    try {
        load_scene(face);
        ADD_FAILURE() << "a face of 1.2e17 vertices was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("does not fit its line"), std::string::npos)
            << e.what();
    }
    const std::string vertices = write_temp("huge_count.off", "OFF\n1000000000 1 0\n0 0 0\n");
    try {
        load_scene(vertices);
        ADD_FAILURE() << "a file with 1 of 1e9 vertices was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("file ends after 1 of 1000000000 vertices"),
                  std::string::npos)
            << e.what();
    }
}

TEST(Scene, LoadsPlyAndStlThroughAssimp) {
    const std::string ply = write_temp("tri.ply",
                                       "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                       "property float y\nproperty float z\nelement face 1\n"
                                       "property list uchar int vertex_indices\nend_header\n"
                                       "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(load_scene(ply).triangle_count(), 1u);
    const std::string stl =
        write_temp("tri.stl",
                   "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
                   "vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n");
    EXPECT_EQ(load_scene(stl).triangle_count(), 1u);
}

TEST(Scene, MissingFileIsAnInputError) {
    expect_input_error("/nonexistent/dir/mesh.obj", "not found");
}

TEST(Scene, MalformedFilesAreInputErrors) {
    expect_input_error(write_temp("trunc.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n"),
                       "file ends after 2 of 4 vertices");
    expect_input_error(write_temp("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
                       "out of range");
    expect_input_error(write_temp("nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"),
                       "finite");
    expect_input_error(write_temp("header.off", "4OFF\n3 1 0\n"), "unsupported OFF variant");
    static const char kJunk[] = "\x01\x02\x03 not a mesh \xff\xfe";
    expect_input_error(write_temp("junk.obj", std::string(kJunk, sizeof kJunk - 1)),
                       "no triangles");
    expect_input_error(
        write_temp("trunc.ply",
                   "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                   "property float y\nproperty float z\nelement face 1\n"
                   "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0\n"),
        "no triangles");
    expect_input_error(write_temp("mesh.unknownformat", "whatever\n"), "cannot read mesh");
    expect_input_error(
        write_temp("bad.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n"), "");
    expect_input_error(write_temp("empty.obj", "# no faces\nv 0 0 0\n"), "");
    expect_input_error(fs::temp_directory_path().string(), "directory");
}

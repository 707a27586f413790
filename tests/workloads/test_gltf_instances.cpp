// Mesh files whose nodes share meshes keep their instancing (workloads/assimp_reader.cpp): real
// glTF assets from assimp-testmodels (scripts/setup.sh), with the expected meshes and instances
// counted from the files' own JSON, and the instanced scene checked against the same file
// flattened (the one-level path every mesh file took before) on hits.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>

#include "support/scratch_dir.h"
#include "workloads/instances.h"
#include "workloads/intersect.h"
#include "workloads/mesh_cache.h"
#include "workloads/scene.h"
#include "workloads/scene_file.h"
#include "workloads/tracer.h"

namespace fs = std::filesystem;
using namespace rtsim;

namespace {

std::string model(const char* name) {
    return (fs::path(RTSIM_ASSIMP_MODEL_DIR) / name).string();
}

// A glTF file's JSON: the .gltf text, or a .glb's first chunk (12-byte header, then the chunk's
// length and type, then the JSON).
nlohmann::json gltf_json(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    const std::string bytes = ss.str();
    if (path.size() > 4 && path.substr(path.size() - 4) == ".glb") {
        uint32_t length = 0;
        std::memcpy(&length, bytes.data() + 12, 4);
        return nlohmann::json::parse(bytes.substr(20, length));
    }
    return nlohmann::json::parse(bytes);
}

// What the file says: each primitive of a mesh a node places is one mesh (assimp makes one per
// primitive), and each placement of it one instance. glTF 1 keys meshes and nodes by name and
// lets a node list meshes; glTF 2 indexes them and gives a node one mesh.
struct Expected {
    size_t meshes = 0, instances = 0;
};
Expected count_from_json(const nlohmann::json& g) {
    Expected e;
    std::set<std::string> used;
    auto primitives = [&](const nlohmann::json& mesh) { return mesh["primitives"].size(); };
    for (const auto& [key, node] : g["nodes"].items()) {
        (void)key;
        std::vector<std::string> placed;
        if (node.contains("meshes"))
            for (const auto& m : node["meshes"]) placed.push_back(m.get<std::string>());
        if (node.contains("mesh")) placed.push_back(std::to_string(node["mesh"].get<int>()));
        for (const std::string& m : placed) {
            const nlohmann::json& mesh =
                g["meshes"].is_array() ? g["meshes"][size_t(std::stoi(m))] : g["meshes"][m];
            e.instances += primitives(mesh);
            if (used.insert(m).second) e.meshes += primitives(mesh);
        }
    }
    return e;
}

// Rays from around `b` towards its middle (targets within `spread` of its half-extent), traced
// through both structures: {rays that hit, rays whose hit or t (1e-4) differ}.
template <class A, class B>
std::pair<int, int> compare_hits(const A& a, const B& b_bvh, const AABB& b, unsigned seed, int n,
                                 float spread) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    int hits = 0, differ = 0;
    for (int i = 0; i < n; ++i) {
        Ray r;
        r.org = b.center() + Vec3(u(rng), u(rng), u(rng)) * length(b.extent());
        const Vec3 e = b.extent();
        const Vec3 target = b.center() + Vec3(u(rng) * e.x, u(rng) * e.y, u(rng) * e.z) * spread;
        r.dir = normalize(target - r.org);
        const Hit x = trace_ray(a, r, HitQuery::Closest),
                  y = trace_ray(b_bvh, r, HitQuery::Closest);
        if (x.valid() != y.valid() ||
            (x.valid() && std::fabs(x.t - y.t) > 1e-4f * std::max(1.0f, y.t))) {
            ++differ;  // a ray through an edge the two roundings put on either side
            continue;
        }
        hits += x.valid();
    }
    return {hits, differ};
}

}  // namespace

TEST(GltfInstances, SharedMeshesAreOneBlasEachWithAnInstancePerNode) {
    ASSERT_TRUE(fs::exists(model("CesiumMilkTruck.gltf"))) << "run scripts/setup.sh";
    for (const char* name : {"CesiumMilkTruck.gltf", "2CylinderEngine.glb"}) {
        SCOPED_TRACE(name);
        const std::string path = model(name);
        const Expected want = count_from_json(gltf_json(path));
        InstancedScene inst;
        bool shared = false;
        const Scene empty = load_scene(path, &inst, &shared);
        ASSERT_TRUE(shared);
        EXPECT_TRUE(empty.triangles.empty());
        EXPECT_EQ(inst.meshes.size(), want.meshes);
        EXPECT_EQ(inst.instances.size(), want.instances);
        EXPECT_EQ(inst.name, name);
        EXPECT_LT(inst.unique_triangle_count(), inst.instanced_triangle_count());
        // The same file flattened: the same triangles, placed the same.
        bool flat_shared = false;
        const Scene flat = load_scene(path, nullptr, &flat_shared);
        EXPECT_TRUE(flat_shared);
        EXPECT_EQ(flat.triangles.size(), inst.instanced_triangle_count());
        AABB b;  // every instance's vertices, placed (InstancedScene::bounds is of boxes)
        for (const Instance& i : inst.instances)
            for (const Vec3& p : inst.meshes[i.mesh].vertices) b.grow(i.object_to_world.point(p));
        const AABB a = flat.bounds();
        const float tol = 1e-4f * length(a.extent());
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(a.lo[k], b.lo[k], tol);
            EXPECT_NEAR(a.hi[k], b.hi[k], tol);
        }
    }
    // A file without shared meshes stays one mesh.
    InstancedScene none;
    bool shared = true;
    const Scene bunny = load_scene(RTSIM_BUNNY_OBJ, &none, &shared);
    EXPECT_FALSE(shared);
    EXPECT_TRUE(none.instances.empty());
    EXPECT_GT(bunny.triangles.size(), 60000u);
}

// Rays through the engine (115 instances of 34 meshes) hit what they hit in the flattened file,
// at the same distance to float rounding of the two placements (a vertex moved by the node's
// matrix in the flattened file; a ray moved by its inverse in the instanced one).
TEST(GltfInstances, InstancedHitsMatchTheFlattenedFile) {
    ASSERT_TRUE(fs::exists(model("2CylinderEngine.glb"))) << "run scripts/setup.sh";
    InstancedScene inst;
    bool shared = false;
    load_scene(model("2CylinderEngine.glb"), &inst, &shared);
    const Scene flat = load_scene(model("2CylinderEngine.glb"));
    const TwoLevelBvh two = build_two_level(inst, BvhBuildOptions());
    const Bvh one = build_bvh(flat, BvhBuildOptions());
    const int n = 4000;
    const auto [hits, differ] = compare_hits(two, one, flat.bounds(), 3, n, 0.3f);
    EXPECT_GT(hits, n / 2);
    EXPECT_LE(differ, n / 500);
}

// Instanced files are never stored in the mesh cache (an entry holds one flattened mesh), so a
// later run reads the instances again instead of hitting a flattening of them.
TEST(GltfInstances, InstancedFilesBypassTheMeshCache) {
    ASSERT_TRUE(fs::exists(model("CesiumMilkTruck.gltf"))) << "run scripts/setup.sh";
    const fs::path dir = test::scratch_dir() / "gltf-mesh-cache";
    fs::remove_all(dir);
    fs::create_directories(dir);
    for (int run = 0; run < 2; ++run) {
        InstancedScene inst;
        MeshCacheStatus st;
        const Scene s = load_scene_cached(model("CesiumMilkTruck.gltf"), dir.string(), &st, &inst);
        EXPECT_TRUE(s.triangles.empty());
        EXPECT_EQ(inst.instances.size(), 5u);
        EXPECT_EQ(st.outcome, "instanced (not cached)");
    }
    // Flattened on request (no instances wanted): still not stored.
    MeshCacheStatus st;
    const Scene flat = load_scene_cached(model("CesiumMilkTruck.gltf"), dir.string(), &st);
    EXPECT_EQ(flat.triangles.size(), 3624u);
    EXPECT_TRUE(fs::is_empty(dir));
}

// A scene file naming a mesh file whose nodes share meshes places the file's instances as a
// whole: each copy of the entry is one instance per instance of the file, composed with the
// entry's placement. Checked on hits against the file flattened and copied by hand (each vertex
// moved by the copy's offset), and "flatten": true keeps the file one mesh.
TEST(GltfInstances, SceneFilesNestAFilesInstances) {
    ASSERT_TRUE(fs::exists(model("CesiumMilkTruck.gltf"))) << "run scripts/setup.sh";
    const fs::path dir = test::scratch_dir() / "gltf-nested";
    fs::create_directories(dir);
    const std::string truck = model("CesiumMilkTruck.gltf");
    auto write = [&](const std::string& name, const std::string& mesh_entry) {
        const fs::path p = dir / name;
        std::ofstream(p) << R"({"meshes": {"truck": )" << mesh_entry << R"(},
            "instances": [{"mesh": "truck", "translate": [0, 1, 0],
                           "grid": {"count": [3, 1, 1], "spacing": [7, 0, 0]}}]})";
        return p.string();
    };
    const InstancedScene nested = load_scene_file(write("nested.json", "\"" + truck + "\""));
    InstancedScene file;
    bool shared = false;
    load_scene(truck, &file, &shared);
    ASSERT_TRUE(shared);
    EXPECT_EQ(nested.meshes.size(), file.meshes.size());
    EXPECT_EQ(nested.instances.size(), 3 * file.instances.size());

    const InstancedScene flat_entry =
        load_scene_file(write("flat.json", "{\"file\": \"" + truck + "\", \"flatten\": true}"));
    EXPECT_EQ(flat_entry.meshes.size(), 1u);
    EXPECT_EQ(flat_entry.instances.size(), 3u);

    // The reference: the file flattened, three copies moved by hand into one mesh.
    const Scene one = load_scene(truck);
    Scene copies;
    copies.name = "copies";
    for (int k = 0; k < 3; ++k) {
        const auto base = uint32_t(copies.vertices.size());
        for (const Vec3& v : one.vertices)
            copies.vertices.push_back(v + Vec3(7.0f * float(k), 1.0f, 0.0f));
        for (const auto& t : one.triangles)
            copies.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
    }
    const TwoLevelBvh two = build_two_level(nested, BvhBuildOptions());
    const Bvh ref = build_bvh(copies, BvhBuildOptions());
    const int n = 3000;
    const auto [hits, differ] = compare_hits(two, ref, copies.bounds(), 11, n, 0.4f);
    EXPECT_GT(hits, n / 3);
    EXPECT_LE(differ, n / 500);
}

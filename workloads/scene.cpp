#include "workloads/scene.h"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <fmt/format.h>
#include <assimp/Importer.hpp>
#include <cctype>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <thread>

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

namespace {

// assimp cannot be stopped from outside, and some of its readers loop forever on a damaged file
// (fuzz_mesh found a 219-byte PLY header that hangs assimp 5.2.5's). While it reads, this
// watchdog ends the process with a one-line error past a deadline (RTSIM_IMPORT_TIMEOUT_S, or
// 30 s plus 3 s per MB: far beyond what a sound file takes), and at once on SIGINT or SIGTERM.
// Nothing has been written yet when a scene loads, so exiting leaves no partial output.
class ImportWatchdog {
  public:
    explicit ImportWatchdog(const std::string& spec) : spec_(spec) {
        double seconds = 30.0;
        std::error_code ec;
        const auto bytes = std::filesystem::file_size(spec, ec);
        if (!ec) seconds += 3.0 * double(bytes) / 1e6;
        if (const char* env = std::getenv("RTSIM_IMPORT_TIMEOUT_S")) seconds = std::atof(env);
        thread_ = std::thread([this, seconds] { watch(seconds); });
    }
    ~ImportWatchdog() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            done_ = true;
        }
        cv_.notify_all();
        thread_.join();
    }

  private:
    void watch(double seconds) {
        using clock = std::chrono::steady_clock;
        const auto deadline = clock::now() + std::chrono::duration_cast<clock::duration>(
                                                 std::chrono::duration<double>(seconds));
        std::unique_lock<std::mutex> lock(mutex_);
        while (!cv_.wait_for(lock, std::chrono::milliseconds(50), [this] { return done_; })) {
            const InterruptProbe probe = interrupt_probe();
            if (const int s = probe ? probe() : 0) {
                std::fprintf(stderr,
                             "rtsim: interrupted by %s while reading %s: no output written\n",
                             s == SIGINT    ? "SIGINT"
                             : s == SIGTERM ? "SIGTERM"
                                            : "a signal",
                             spec_.c_str());
                std::_Exit(128 + s);
            }
            if (clock::now() > deadline) {
                std::fprintf(stderr,
                             "rtsim: error: %s: the mesh reader (assimp) did not finish in %.0f s; "
                             "the file is likely damaged (RTSIM_IMPORT_TIMEOUT_S sets the limit)\n",
                             spec_.c_str(), seconds);
                std::_Exit(2);
            }
        }
    }

    const std::string spec_;
    std::mutex mutex_;
    std::condition_variable cv_;
    bool done_ = false;
    std::thread thread_;
};

}  // namespace

void read_with_assimp(const std::string& spec, Scene& scene) {
    Assimp::Importer importer;
    const ImportWatchdog watchdog(spec);
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

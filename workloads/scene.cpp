#include "workloads/scene.h"

#include <dlfcn.h>
#include <fmt/format.h>
#include <unistd.h>

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
#include <vector>

#include "workloads/assimp_reader.h"
#include "workloads/error.h"
#include "workloads/instances.h"

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

// Throws InputError ("FILE: MESH has a non-finite vertex coordinate") for a vertex with a NaN or
// infinite coordinate.
void require_finite_vertices(const Scene& mesh, const std::string& file, const std::string& what) {
    for (const Vec3& p : mesh.vertices)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw InputError(fmt::format("{}: {} has a non-finite vertex coordinate", file, what));
}

}  // namespace

Scene load_scene(const std::string& spec) {
    return load_scene(spec, nullptr, nullptr);
}

Scene load_scene(const std::string& spec, InstancedScene* instanced, bool* shared) {
    if (shared) *shared = false;
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
        bool nodes_share = false;
        read_with_assimp(spec, scene, instanced, &nodes_share);
        if (shared) *shared = nodes_share;
        if (nodes_share && instanced) {
            instanced->name = fs::path(spec).filename().string();
            instanced->source = spec;
            for (const Scene& m : instanced->meshes)
                require_finite_vertices(m, spec, fmt::format("mesh '{}'", m.name));
            instanced->validate();
            return scene;
        }
    }
    scene.name = fs::path(spec).filename().string();
    scene.source = spec;
    if (scene.triangles.empty()) throw InputError(fmt::format("{}: mesh has no triangles", spec));
    require_finite_vertices(scene, spec, "mesh");
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

// The assimp reader module, loaded at the first file that needs it: beside the executable (rtsim
// and its module are built into one folder), else in the build folder it was built in (the test
// and fuzz programs, one level down). A missing or broken module is a one-line error.
RtsimAssimpRead assimp_reader(const std::string& spec) {
#ifdef RTSIM_ASSIMP_LINKED
    (void)spec;
    return &rtsim_assimp_read;
#else
    static std::mutex mutex;
    static RtsimAssimpRead read = nullptr;
    std::lock_guard<std::mutex> lock(mutex);
    if (read) return read;
    std::vector<std::string> dirs;
    char exe[4096];
    const ssize_t n = ::readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n > 0) dirs.push_back(std::filesystem::path(std::string(exe, size_t(n))).parent_path());
    dirs.push_back(RTSIM_MODULE_DIR);
    std::string why;
    for (const std::string& dir : dirs) {
        const std::string path = (std::filesystem::path(dir) / kRtsimAssimpModule).string();
        if (void* module = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
            read = reinterpret_cast<RtsimAssimpRead>(::dlsym(module, "rtsim_assimp_read"));
            if (read) return read;
            why = fmt::format("{} has no rtsim_assimp_read", path);
        } else if (why.empty() || std::filesystem::exists(path)) {
            why = ::dlerror();
        }
    }
    throw InputError(
        fmt::format("{}: cannot read mesh: the assimp reader module ({}) did not load: {}", spec,
                    kRtsimAssimpModule, why));
#endif
}

}  // namespace

void read_with_assimp(const std::string& spec, Scene& scene, InstancedScene* instanced,
                      bool* shared) {
    const RtsimAssimpRead read = assimp_reader(spec);
    const ImportWatchdog watchdog(spec);
    std::string why;
    bool nodes_share = false;
    const bool ok = read(spec.c_str(), &scene, instanced, &nodes_share, &why);
    if (shared) *shared = nodes_share;
    if (!ok) {
        for (char& c : why)
            if (c == '\n' || c == '\r') c = ' ';
        throw InputError(
            fmt::format("{}: cannot read mesh: {}", spec, why.empty() ? "unknown format" : why));
    }
}

}  // namespace rtsim

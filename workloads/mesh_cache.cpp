#include "workloads/mesh_cache.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>

#include "workloads/cache_entry.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

namespace fs = std::filesystem;

namespace {

// 4: arrays on 64-byte boundaries, mapped on a hit.
constexpr char kMagic[8] = {'R', 'T', 'S', 'M', 'E', 'S', 'H', '5'};

// A 64-bit hash of the file's bytes, 8 at a time (FNV-1a's step on words: a few MB hash in a
// millisecond, where the byte-wise step takes several).
uint64_t hash_bytes(std::string_view bytes) {
    uint64_t h = kFnvOffset ^ bytes.size();
    size_t i = 0;
    for (; i + 8 <= bytes.size(); i += 8) {
        uint64_t w;
        std::memcpy(&w, bytes.data() + i, 8);
        h = (h ^ w) * 1099511628211ull;
        h ^= h >> 29;
    }
    for (; i < bytes.size(); ++i) h = (h ^ uint8_t(bytes[i])) * 1099511628211ull;
    return h;
}

std::string serialize(const Scene& s, uint64_t file_hash, uint64_t file_size, uint64_t scene_hash) {
    CacheEntryWriter w(kMagic);
    w.pod(file_hash);
    w.pod(file_size);
    w.pod(scene_hash);
    w.aligned_vec(s.vertices);
    w.aligned_vec(s.triangles);
    return w.finish();
}

// The scene's arrays are views of `bytes` while `keep` (their mapping) lives.
void deserialize(std::string_view bytes, uint64_t file_hash, uint64_t file_size, Scene& s,
                 uint64_t& scene_hash, const std::shared_ptr<const void>& keep) {
    CacheEntryReader r = open_cache_entry(bytes, kMagic, "not a mesh cache entry",
                                          "checksum mismatch (a damaged or truncated file)");
    if (r.pod<uint64_t>() != file_hash || r.pod<uint64_t>() != file_size)
        throw CacheEntryUnusable{"its key is not this file's"};
    scene_hash = r.pod<uint64_t>();
    r.view(s.vertices, keep);
    r.view(s.triangles, keep);
    if (!r.done()) throw CacheEntryUnusable{"trailing bytes"};
    // What load_scene guarantees of a parsed mesh, and indices the tracer can follow.
    if (s.triangles.empty()) throw CacheEntryUnusable{"no triangles"};
    for (const auto& t : s.triangles)
        for (uint32_t i : t)
            if (i >= s.vertices.size()) throw CacheEntryUnusable{"a vertex index out of range"};
    for (const Vec3& p : s.vertices)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw CacheEntryUnusable{"a non-finite vertex"};
}

}  // namespace

Scene load_scene_cached(const std::string& spec, const std::string& dir, MeshCacheStatus* status,
                        InstancedScene* instanced) {
    const auto t0 = std::chrono::steady_clock::now();
    MeshCacheStatus local;
    MeshCacheStatus& st = status ? *status : local;
    auto done = [&](Scene s) {
        st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        return s;
    };
    // The file is mapped to be hashed, not read into a buffer of its own (a 2.4 MB OBJ: about
    // 600 fresh pages at ~5 us each); a file that cannot be mapped (a pipe) is read.
    const bool builtin = spec.rfind("builtin:", 0) == 0;
    CacheEntryBytes mapped;
    std::optional<std::string> read;
    if (!builtin && !dir.empty() && fs::is_regular_file(spec) && !mapped.map(spec))
        read = read_file_text(spec);
    if (builtin || dir.empty() || (mapped.view().empty() && !read)) {
        // Built-in scenes are made, not read; an unreadable file gets load_scene's own error.
        st.outcome = builtin ? "builtin" : "off";
        return done(load_scene(spec, instanced, nullptr));
    }
    const std::string_view bytes = read ? std::string_view(*read) : mapped.view();
    const uint64_t hash = hash_bytes(bytes), size = bytes.size();
    // The format's revision in the name: an entry of an older one is never read (nor warned of).
    const std::string path =
        (fs::path(dir) / fmt::format("{:016x}-{}.mesh", hash, kMagic[7])).string();
    st.outcome = "built";
    auto entry = std::make_shared<CacheEntryBytes>();
    if (entry->map(path)) {
        try {
            Scene s;
            uint64_t scene_hash = 0;
            deserialize(entry->view(), hash, size, s, scene_hash, entry);
            s.name = fs::path(spec).filename().string();
            s.source = spec;
            st.outcome = "hit";
            st.scene_hash = scene_hash;
            return done(std::move(s));
        } catch (const CacheEntryUnusable& u) {
            st.outcome = "rebuilt: " + u.why;
            warn(fmt::format("{}: mesh cache entry unusable ({}); reading {} again", path, u.why,
                             spec));
        }
    }
    bool shared = false;
    Scene s = load_scene(spec, instanced, &shared);
    if (shared) {  // instances, or a flattening of them: not what an entry holds
        st.outcome = instanced ? "instanced (not cached)" : "off: nodes share meshes";
        return done(std::move(s));
    }
    st.scene_hash = s.content_hash();
    store_cache_entry(path, serialize(s, hash, size, *st.scene_hash), "mesh cache entry");
    return done(std::move(s));
}

}  // namespace rtsim

#include "workloads/bvh_cache.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <type_traits>

#include "workloads/cache_entry.h"
#include "workloads/error.h"
#include "workloads/memory_limit.h"

namespace rtsim {

namespace fs = std::filesystem;

namespace {

// Bump when the entry layout or anything in Bvh it stores changes: older entries then miss.
constexpr uint32_t kFormatVersion = 3;  // 2: XXH3-64 checksum; 3: arrays on 64-byte boundaries
constexpr char kMagic[8] = {'R', 'T', 'S', 'I', 'M', 'B', 'V', 'H'};

using Unusable = CacheEntryUnusable;
using Writer = CacheEntryWriter;
using Reader = CacheEntryReader;

// Calls f with every BvhBuildOptions field the build reads, in one order: the key hashes them,
// an entry stores them and a load compares them, so a new build setting is added here once. (The
// box datapath fields are not among them: they do not change the tree.)
template <class F>
void for_each_build_setting(const BvhBuildOptions& o, F&& f) {
    f(o.builder);
    f(o.node_format);
    f(o.restructure_passes);
    f(o.width);
    f(o.sah_buckets);
    f(o.max_leaf_size);
    f(o.treelet_bytes);
    f(o.traversal_cost);
    f(o.intersection_cost);
}

// Calls f with the node array of the tree's width (nodes2, nodes4 or nodes8).
template <class B, class F>
void with_nodes(B& b, int width, F&& f) {
    switch (width) {
        case 2:
            f(b.nodes2);
            break;
        case 4:
            f(b.nodes4);
            break;
        default:
            f(b.nodes8);
            break;
    }
}

// Every index a traversal follows stays inside its array: an entry that passed its checksum but
// was written by a faulty build would otherwise crash a run rather than be rebuilt.
template <int W>
void check_nodes(const MappableArray<WideNode<W>>& nodes, const Bvh& b) {
    const size_t tris = b.prim_order.size();
    for (const WideNode<W>& n : nodes) {
        if (n.num > W) throw Unusable{"a node with too many children"};
        for (int l = 0; l < n.num; ++l) {
            if (n.count[l] == 0) {
                if (n.child[l] >= nodes.size()) throw Unusable{"a child index out of range"};
            } else if (uint64_t(n.child[l]) + n.count[l] > tris ||
                       n.child[l] >= b.leaf_block.size() ||
                       b.leaf_block[n.child[l]] + (n.count[l] + 3u) / 4u > b.tri4.size()) {
                throw Unusable{"a leaf out of range"};
            }
        }
    }
}

std::string serialize(const Bvh& b, uint64_t key) {
    Writer w(kMagic);
    w.pod(kFormatVersion);
    w.pod(key);
    for_each_build_setting(b.options, [&](const auto& v) { w.pod(v); });
    const BvhLayout& L = b.layout;
    w.pod(L.node_base_addr);
    w.pod(L.node_size_bytes);
    w.pod(L.tri_base_addr);
    w.pod(L.tri_size_bytes);
    w.pod(L.inner_node_count);
    w.pod(L.triangle_count);
    w.pod(L.treelet_bytes);
    w.vec(L.treelet_node_start);
    w.vec(L.treelet_tri_start);
    w.pod(b.quality);
    w.pod(b.bounds_box);
    with_nodes(b, b.width(), [&](const auto& nodes) { w.aligned_vec(nodes); });
    w.aligned_vec(b.prim_order);
    w.aligned_vec(b.tri_verts);
    w.aligned_vec(b.tri4);
    w.aligned_vec(b.leaf_block);
    return w.finish();
}

// The tree's arrays are views of `bytes` while `keep` (their mapping) lives; copies without it.
Bvh deserialize(std::string_view bytes, uint64_t key, const BvhBuildOptions& want,
                const std::shared_ptr<const void>& keep) {
    Reader r = open_cache_entry(bytes, kMagic, "not a BVH cache entry",
                                "checksum mismatch (a damaged or truncated file)");
    if (r.pod<uint32_t>() != kFormatVersion) throw Unusable{"an older entry format"};
    if (r.pod<uint64_t>() != key) throw Unusable{"its key is not this build's"};
    Bvh b;
    b.options = want;
    // The stored settings must be the ones asked for (the key says so; this catches a collision).
    bool same = true;
    for_each_build_setting(
        want, [&](const auto& v) { same = r.pod<std::decay_t<decltype(v)>>() == v && same; });
    if (!same) throw Unusable{"its build settings are not this build's"};
    BvhLayout& L = b.layout;
    L.node_base_addr = r.pod<uint64_t>();
    L.node_size_bytes = r.pod<uint32_t>();
    L.tri_base_addr = r.pod<uint64_t>();
    L.tri_size_bytes = r.pod<uint32_t>();
    L.inner_node_count = r.pod<uint32_t>();
    L.triangle_count = r.pod<uint32_t>();
    L.treelet_bytes = r.pod<uint32_t>();
    r.vec(L.treelet_node_start);
    r.vec(L.treelet_tri_start);
    b.quality = r.pod<BvhQuality>();
    b.bounds_box = r.pod<AABB>();
    with_nodes(b, want.width, [&](auto& nodes) { r.view(nodes, keep); });
    r.view(b.prim_order, keep);
    r.view(b.tri_verts, keep);
    r.view(b.tri4, keep);
    r.view(b.leaf_block, keep);
    if (!r.done()) throw Unusable{"trailing bytes"};
    size_t nodes = 0;
    with_nodes(b, want.width, [&](const auto& v) { nodes = v.size(); });
    if (nodes != L.inner_node_count || b.prim_order.size() != L.triangle_count ||
        b.tri_verts.size() != L.triangle_count || b.leaf_block.size() != L.triangle_count ||
        nodes == 0 || !L.index_treelets())
        throw Unusable{"inconsistent record counts"};
    with_nodes(b, want.width, [&](const auto& v) { check_nodes(v, b); });
    return b;
}

}  // namespace

const char* bvh_cache_outcome_name(BvhCacheOutcome o) {
    switch (o) {
        case BvhCacheOutcome::Hit:
            return "hit";
        case BvhCacheOutcome::Built:
            return "built";
        case BvhCacheOutcome::Rebuilt:
            return "rebuilt";
        default:
            return "off";
    }
}

std::string default_bvh_cache_dir() {
    if (const char* env = std::getenv("RTSIM_BVH_CACHE"))
        return std::string(env) == "off" ? std::string() : std::string(env);
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
        return (fs::path(xdg) / "rtsim" / "bvh").string();
    if (const char* home = std::getenv("HOME"); home && *home)
        return (fs::path(home) / ".cache" / "rtsim" / "bvh").string();
    return {};
}

uint64_t bvh_cache_key(const Scene& scene, const BvhBuildOptions& o, const BvhLayout& L) {
    return bvh_cache_key(scene.content_hash(), scene, o, L);
}

uint64_t bvh_cache_key(uint64_t scene_hash, const Scene& scene, const BvhBuildOptions& o,
                       const BvhLayout& L) {
    uint64_t h = kFnvOffset;
    auto mix = [&h](const auto& v) { h = fnv1a(h, &v, sizeof v); };
    mix(kFormatVersion);
    mix(scene_hash);
    mix(uint64_t(scene.vertices.size()));
    mix(uint64_t(scene.triangles.size()));
    for_each_build_setting(o, mix);
    mix(L.node_base_addr);
    mix(L.node_size_bytes);
    mix(L.tri_size_bytes);
    return h;
}

Bvh build_bvh_cached(const Scene& scene, const BvhBuildOptions& options,
                     const BvhLayout& layout_sizes, const std::string& dir, BvhCacheStatus* status,
                     std::optional<uint64_t> scene_hash) {
    const auto t0 = std::chrono::steady_clock::now();
    BvhCacheStatus local;
    BvhCacheStatus& st = status ? *status : local;
    auto seconds = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    };
    // A build (not a hit) is what needs the memory: checked before each.
    auto build = [&] {
        check_prepare_memory(scene.source.empty() ? scene.name : scene.source,
                             scene.triangle_count(), 0);
        return build_bvh(scene, options, layout_sizes);
    };
    if (dir.empty()) {
        st.outcome = BvhCacheOutcome::Off;
        Bvh b = build();
        st.seconds = seconds();
        return b;
    }
    st.scene_hash = scene_hash ? *scene_hash : scene.content_hash();
    const uint64_t key = st.key = bvh_cache_key(st.scene_hash, scene, options, layout_sizes);
    st.path = (fs::path(dir) / fmt::format("{:016x}.bvh", key)).string();
    st.outcome = BvhCacheOutcome::Built;
    auto bytes = std::make_shared<CacheEntryBytes>();
    if (bytes->map(st.path)) {
        try {
            Bvh b = deserialize(bytes->view(), key, options, bytes);
            st.outcome = BvhCacheOutcome::Hit;
            st.seconds = seconds();
            b.quality.build_seconds = st.seconds;  // what this run spent to have the tree
            return b;
        } catch (const Unusable& u) {
            st.outcome = BvhCacheOutcome::Rebuilt;
            st.why = u.why;
            warn(fmt::format("{}: BVH cache entry unusable ({}); rebuilding it", st.path, u.why));
        }
    }
    Bvh b = build();
    store_cache_entry(st.path, serialize(b, key), "BVH cache entry");
    st.seconds = seconds();
    return b;
}

std::string CacheEntryWriter::finish() {
    pod(uint64_t(XXH3_64bits(out_.data(), out_.size())));
    return std::move(out_);
}

CacheEntryReader open_cache_entry(std::string_view bytes, const char (&magic)[8],
                                  const char* not_entry, const char* bad_checksum) {
    uint64_t sum;
    if (bytes.size() < sizeof magic + sizeof sum ||
        std::memcmp(bytes.data(), magic, sizeof magic) != 0)
        throw CacheEntryUnusable{not_entry};
    std::memcpy(&sum, bytes.data() + bytes.size() - sizeof sum, sizeof sum);
    if (XXH3_64bits(bytes.data(), bytes.size() - sizeof sum) != sum)
        throw CacheEntryUnusable{bad_checksum};
    return CacheEntryReader(bytes.data(), bytes.data() + sizeof magic,
                            bytes.size() - sizeof magic - sizeof sum);
}

void store_cache_entry(const std::string& path, const std::string& bytes, const char* what) {
    std::error_code ec;
    fs::create_directories(fs::path(path).parent_path(), ec);
    const std::string tmp = fmt::format("{}.tmp.{}", path, getpid());
    bool written;
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        out.write(bytes.data(), std::streamsize(bytes.size()));
        written = bool(out);
    }
    if (written) fs::rename(tmp, path, ec);
    if (!written || ec) {
        fs::remove(tmp, ec);
        warn(fmt::format("{}: cannot write the {} (the run goes on)", path, what));
    }
}

bool CacheEntryBytes::map(const std::string& path) {
    unmap();
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return false;
    struct stat st;
    bool ok = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
    if (ok && st.st_size > 0) {
        void* p = ::mmap(nullptr, size_t(st.st_size), PROT_READ, MAP_PRIVATE, fd, 0);
        ok = p != MAP_FAILED;
        if (ok) {
            data_ = static_cast<const char*>(p);
            size_ = size_t(st.st_size);
            mapped_ = true;
        }
    }
    ::close(fd);
    return ok;
}

void CacheEntryBytes::unmap() {
    if (mapped_) ::munmap(const_cast<char*>(data_), size_);
    data_ = nullptr;
    size_ = 0;
    mapped_ = false;
}

}  // namespace rtsim

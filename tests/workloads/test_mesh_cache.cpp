// The mesh cache: a hit gives the very scene the file's reader gives; an edited file misses; an
// entry that is damaged, truncated or holds an index past its vertices (with a valid checksum)
// is refused and the file read again, never used.
#include <gtest/gtest.h>
#include <xxhash.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "support/file_bytes.h"
#include "support/scratch_dir.h"
#include "workloads/mesh_cache.h"

using namespace rtsim;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const char* name) {
    const fs::path d = test::scratch_dir() / name;
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

// Two triangles of a unit square, then a third whose first vertex is `x`.
void write_obj(const fs::path& path, float x) {
    std::ofstream out(path);
    out << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv " << x << " 0 1\n"
        << "f 1 2 3\nf 1 3 4\nf 5 2 3\n";
}

using test::read_file_bytes;
using test::write_file_bytes;

fs::path only_entry(const fs::path& dir) {
    fs::path found;
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().extension() == ".mesh") {
            found = e.path();
            ++n;
        }
    EXPECT_EQ(n, 1);
    return found;
}

void expect_same_scene(const Scene& a, const Scene& b) {
    ASSERT_EQ(a.vertices.size(), b.vertices.size());
    ASSERT_EQ(a.triangles, b.triangles);
    for (size_t i = 0; i < a.vertices.size(); ++i) {
        EXPECT_EQ(a.vertices[i].x, b.vertices[i].x);
        EXPECT_EQ(a.vertices[i].y, b.vertices[i].y);
        EXPECT_EQ(a.vertices[i].z, b.vertices[i].z);
    }
    EXPECT_EQ(a.content_hash(), b.content_hash());
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.source, b.source);
}

}  // namespace

TEST(MeshCache, HitGivesTheParsedSceneAndAnEditedFileMisses) {
    const fs::path dir = fresh_dir("mesh_cache_hit"), cache = dir / "cache";
    const fs::path obj = dir / "quad.obj";
    write_obj(obj, 0.5f);
    MeshCacheStatus st;
    const Scene built = load_scene_cached(obj.string(), cache.string(), &st);
    EXPECT_EQ(st.outcome, "built");
    const Scene parsed = load_scene(obj.string());
    expect_same_scene(built, parsed);
    const Scene hit = load_scene_cached(obj.string(), cache.string(), &st);
    EXPECT_EQ(st.outcome, "hit");
    expect_same_scene(hit, parsed);
    // A hit maps the entry's arrays rather than copying them.
    EXPECT_TRUE(hit.vertices.is_view());
    EXPECT_TRUE(hit.triangles.is_view());
    // The entry's stored content hash is the parsed scene's, hashed here.
    ASSERT_TRUE(st.scene_hash.has_value());
    EXPECT_EQ(*st.scene_hash, parsed.content_hash());

    // The same bytes under another name hit, and keep their own name.
    const fs::path copy = dir / "copy.obj";
    fs::copy_file(obj, copy);
    const Scene renamed = load_scene_cached(copy.string(), cache.string(), &st);
    EXPECT_EQ(st.outcome, "hit");
    EXPECT_EQ(renamed.name, "copy.obj");
    EXPECT_EQ(renamed.content_hash(), parsed.content_hash());

    // One coordinate changed: another entry, the new geometry.
    write_obj(obj, 0.25f);
    const Scene edited = load_scene_cached(obj.string(), cache.string(), &st);
    EXPECT_EQ(st.outcome, "built");
    ASSERT_TRUE(st.scene_hash.has_value());
    EXPECT_NE(*st.scene_hash, parsed.content_hash());
    auto has_x = [&](float x) {
        return std::any_of(edited.vertices.begin(), edited.vertices.end(),
                           [x](const Vec3& v) { return v.x == x; });
    };
    EXPECT_TRUE(has_x(0.25f));
    EXPECT_FALSE(has_x(0.5f));
    expect_same_scene(edited, load_scene(obj.string()));
}

TEST(MeshCache, DamagedOrInconsistentEntriesAreReadAgain) {
    const fs::path dir = fresh_dir("mesh_cache_damaged"), cache = dir / "cache";
    const fs::path obj = dir / "quad.obj";
    write_obj(obj, 0.5f);
    const Scene parsed = load_scene(obj.string());
    MeshCacheStatus st;
    load_scene_cached(obj.string(), cache.string(), &st);
    const fs::path entry = only_entry(cache);
    const std::string good = read_file_bytes(entry);

    auto reload = [&](const std::string& bytes) {
        write_file_bytes(entry, bytes);
        const Scene s = load_scene_cached(obj.string(), cache.string(), &st);
        expect_same_scene(s, parsed);
        // Stored over: the next load hits.
        EXPECT_EQ(read_file_bytes(entry), good);
        return st.outcome;
    };
    std::string flipped = good;
    flipped[good.size() / 2] ^= 0x10;
    EXPECT_EQ(reload(flipped), "rebuilt: checksum mismatch (a damaged or truncated file)");
    EXPECT_EQ(reload(good.substr(0, good.size() - 9)),
              "rebuilt: checksum mismatch (a damaged or truncated file)");
    EXPECT_EQ(reload("RTSBVH00 something else"), "rebuilt: not a mesh cache entry");

    // A checksum that holds over an index past the vertices: the layout is magic, file hash,
    // file size, scene hash, the vertices (count, 12 bytes each), the triangles (count, 12 bytes
    // each), the 8-byte checksum.
    std::string bad = good;
    const size_t last_index = bad.size() - 8 - 4;  // the last triangle's third index
    const uint32_t past = 1000;
    std::memcpy(&bad[last_index], &past, 4);
    const uint64_t sum = XXH3_64bits(bad.data(), bad.size() - 8);
    std::memcpy(&bad[bad.size() - 8], &sum, 8);
    EXPECT_EQ(reload(bad), "rebuilt: a vertex index out of range");
    EXPECT_EQ(load_scene_cached(obj.string(), cache.string(), &st).triangles, parsed.triangles);
    EXPECT_EQ(st.outcome, "hit");
}

TEST(MeshCache, BuiltinScenesAndNoFolderBypassIt) {
    MeshCacheStatus st;
    const Scene b = load_scene_cached("builtin:cornell", "unused-folder", &st);
    EXPECT_EQ(st.outcome, "builtin");
    EXPECT_FALSE(st.scene_hash.has_value());
    EXPECT_EQ(b.content_hash(), load_scene("builtin:cornell").content_hash());
    EXPECT_FALSE(fs::exists("unused-folder"));
    const fs::path dir = fresh_dir("mesh_cache_off");
    write_obj(dir / "quad.obj", 0.5f);
    load_scene_cached((dir / "quad.obj").string(), "", &st);
    EXPECT_EQ(st.outcome, "off");
    // A missing file keeps load_scene's own error.
    EXPECT_THROW(load_scene_cached((dir / "none.obj").string(), (dir / "c").string()),
                 std::exception);
}

// What the on-disk caches (built BVHs, workloads/bvh_cache.h; frame profiles,
// sim/sampling/frame_profile.h) share: an entry framed by its format's 8-byte magic and an XXH3-64
// checksum of everything before it (CRC-32 at 1-2 GB/s was 8% of a 1-in-100 sampled run that reads
// 20 MB of entries), its bytes written and read back field by field, a read past the end refused,
// and an entry stored through a temporary file and a rename.
#pragma once

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "workloads/mappable_array.h"

namespace rtsim {

// An entry found unusable, and why (it is then rebuilt and stored over).
struct CacheEntryUnusable {
    std::string why;
};

// Bytes of padding from `offset` (from an entry's start) to its next record boundary.
inline size_t pad_to_record_alignment(size_t offset) {
    return (64 - offset % 64) % 64;
}

class CacheEntryWriter {
  public:
    explicit CacheEntryWriter(const char (&magic)[8]) : out_(magic, sizeof magic) {}
    template <class T>
    void pod(const T& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        out_.append(reinterpret_cast<const char*>(&v), sizeof v);
    }
    template <class T>
    void vec(const std::vector<T>& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        pod(uint64_t(v.size()));
        if (!v.empty()) out_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
    }
    // An array a reader may map rather than copy (CacheEntryReader::view): its records start on a
    // 64-byte boundary of the entry (a mapping starts on a page, so they are aligned in memory).
    template <class A>
    void aligned_vec(const A& v) {
        using T = typename A::value_type;
        static_assert(std::is_trivially_copyable_v<T>);
        pod(uint64_t(v.size()));
        out_.append(pad_to_record_alignment(out_.size()), '\0');
        if (!v.empty()) out_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
    }
    // A text key, stored first: CacheEntryReader::expect_key reads it back.
    void key(const std::string& k) { vec(std::vector<char>(k.begin(), k.end())); }
    // The entry: the fields written, then their checksum.
    std::string finish();

  private:
    std::string out_;
};

class CacheEntryReader {
  public:
    // The fields at [data, data + size) of an entry that starts at `entry`.
    CacheEntryReader(const char* entry, const char* data, size_t size)
        : entry_(entry), p_(data), end_(data + size) {}
    template <class T>
    T pod() {
        T v;
        take(&v, sizeof v);
        return v;
    }
    template <class T>
    void vec(std::vector<T>& v) {
        const uint64_t n = pod<uint64_t>();
        if (n > uint64_t(end_ - p_) / sizeof(T)) throw CacheEntryUnusable{"truncated"};
        v.resize(size_t(n));
        take(v.data(), size_t(n) * sizeof(T));
    }
    // An array CacheEntryWriter::aligned_vec stored: a view of the entry's bytes while `keep`
    // (their mapping) lives, or a copy when it is empty or the bytes are not aligned in memory.
    template <class T>
    void view(MappableArray<T>& out, const std::shared_ptr<const void>& keep) {
        const uint64_t n = pod<uint64_t>();
        const size_t pad = pad_to_record_alignment(size_t(p_ - entry_));
        if (pad > size_t(end_ - p_)) throw CacheEntryUnusable{"truncated"};
        p_ += pad;
        if (n > uint64_t(end_ - p_) / sizeof(T)) throw CacheEntryUnusable{"truncated"};
        if (keep && reinterpret_cast<uintptr_t>(p_) % alignof(T) == 0) {
            out.view(reinterpret_cast<const T*>(p_), size_t(n), keep);
            p_ += size_t(n) * sizeof(T);
        } else {
            std::vector<T> v(static_cast<size_t>(n));
            take(v.data(), size_t(n) * sizeof(T));
            out = std::move(v);
        }
    }
    // The text key CacheEntryWriter::key stored; throws "key mismatch" if it is not `k` (another
    // key's entry under this one's name).
    void expect_key(const std::string& k) {
        std::vector<char> stored;
        vec(stored);
        if (std::string(stored.begin(), stored.end()) != k)
            throw CacheEntryUnusable{"key mismatch"};
    }
    bool done() const { return p_ == end_; }

  private:
    void take(void* dst, size_t n) {
        if (n > size_t(end_ - p_)) throw CacheEntryUnusable{"truncated"};
        if (n) std::memcpy(dst, p_, n);
        p_ += n;
    }
    const char* entry_;
    const char* p_;
    const char* end_;
};

// The fields of an entry framed by `magic` and its checksum; throws CacheEntryUnusable with
// `not_entry` for bytes of another kind (or too few) and `bad_checksum` for a damaged entry.
CacheEntryReader open_cache_entry(std::string_view bytes, const char (&magic)[8],
                                  const char* not_entry, const char* bad_checksum);

// FNV-1a over bytes, continuing from h.
inline uint64_t fnv1a(uint64_t h, const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}
constexpr uint64_t kFnvOffset = 1469598103934665603ull;

// Writes through a temporary file and a rename, so a concurrent reader (another sweep point)
// sees the old entry, no entry or the whole new one. A folder that cannot be written only costs
// the store: a one-line warning naming `what`, and the run goes on.
void store_cache_entry(const std::string& path, const std::string& bytes, const char* what);

// A cache entry's bytes, mapped read-only rather than read: a buffer of its own (zeroed, then
// filled by read) cost a sampled run of a 1080p bunny frame two passes over its 11 MB BVH for
// nothing, and a hit's arrays may stay views of the mapping (MappableArray). Entries are replaced
// through a rename, never rewritten in place, so the mapped file cannot change under it. Other
// files read once are mapped through it too: a mesh file hashed for its cache key, and an
// every-unit run's stats.json and table (sim/sampling/reference.cpp).
class CacheEntryBytes {
  public:
    CacheEntryBytes() = default;
    CacheEntryBytes(const CacheEntryBytes&) = delete;
    CacheEntryBytes& operator=(const CacheEntryBytes&) = delete;
    ~CacheEntryBytes() { unmap(); }
    // Maps the file at `path`; false if it cannot be opened or mapped.
    bool map(const std::string& path);
    std::string_view view() const { return {data_, size_}; }

  private:
    void unmap();
    const char* data_ = nullptr;
    size_t size_ = 0;
    bool mapped_ = false;
};

// A value through an on-disk cache entry at `path`: `load(bytes, keep)` turns a stored entry into
// the value (throwing CacheEntryUnusable for one that cannot be used; arrays it maps keep `keep`,
// the mapping, alive), `build()` makes it afresh and
// `serialize(value)` makes its entry, stored over the old one (`what` names it in a warning when
// the folder cannot be written). `outcome` gets "hit", "built" or "rebuilt: why".
template <class Load, class Build, class Serialize>
auto through_cache_entry(const std::string& path, Load&& load, Build&& build, Serialize&& serialize,
                         const char* what, std::string& outcome) -> decltype(build()) {
    outcome = "built";
    {
        auto bytes = std::make_shared<CacheEntryBytes>();
        if (bytes->map(path)) {
            try {
                auto value = load(bytes->view(), std::shared_ptr<const void>(bytes));
                outcome = "hit";
                return value;
            } catch (const CacheEntryUnusable& u) {
                outcome = "rebuilt: " + u.why;
            }
        }
    }
    auto value = build();
    store_cache_entry(path, serialize(value), what);
    return value;
}

}  // namespace rtsim

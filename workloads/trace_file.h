// RTSim trace files (.rtt): the per-ray step streams of a frame, recorded once and replayed
// against many architecture configs. Streamed in both directions (neither side holds the whole
// trace), compressed with zstd per chunk, every part checksummed (CRC-32), and indexed, so a
// reader can seek to chunk k for sampling or parallel reading. docs/trace-format.md specifies
// the bytes; scripts/rtt_reader.py decodes them.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "workloads/bvh.h"
#include "workloads/geometry.h"
#include "workloads/output_file.h"
#include "workloads/step.h"

namespace rtsim {

// Version written. Version 1 (a step byte of 1 kind bit and 7 count bits), version 2 (no
// stack byte per step: such traces read with Step::stack 0) and version 3 (no instance per hit:
// two-level traces read with TraceRecord::instance none) are still read.
constexpr uint32_t kTraceVersion = 4;
constexpr uint32_t kOldestTraceVersion = 1;
// Step kinds version 2's 4-bit kind field can hold (this build knows kStepKinds of them).
constexpr int kTraceStepKinds = 16;

// One ray as recorded: what it did and what it hit.
struct TraceRecord {
    uint32_t ray_id = 0;
    RayKind kind = RayKind::Primary;
    std::vector<Step> steps;  // addresses and sizes come from the layout in the header
    uint32_t prim = kInvalidPrim;
    float t = 0.0f;
    // The instance hit, in a trace of a two-level scene (version 4 on); else none.
    uint32_t instance = kInvalidPrim;
};

uint32_t crc32(const void* data, size_t size, uint32_t crc = 0);

class TraceWriter {
  public:
    // metadata_json: the header's JSON (scene, BVH layout, ray settings). rays_per_chunk bounds
    // the memory of a chunk. The file appears at `path` only when finish() succeeds.
    // `instances`: the trace is of a two-level scene, and each hit records its instance.
    TraceWriter(const std::string& path, const std::string& metadata_json,
                uint32_t rays_per_chunk = 4096, int zstd_level = 3, bool instances = false);
    void add(const TraceRecord& record);
    void finish();

    uint64_t rays() const { return total_rays_; }
    uint64_t steps() const { return total_steps_; }
    uint64_t raw_bytes() const { return raw_total_; }
    uint64_t file_bytes() const { return offset_; }

  private:
    void flush_chunk();
    void write(const void* data, size_t size);

    AtomicOutputFile out_;
    uint32_t rays_per_chunk_;
    int level_;
    bool instances_;
    std::string raw_;  // encoded records of the open chunk
    uint32_t chunk_rays_ = 0;
    uint32_t last_ray_id_ = 0;
    struct IndexEntry {
        uint64_t offset;
        uint32_t rays;
    };
    std::vector<IndexEntry> index_;
    uint64_t offset_ = 0, total_rays_ = 0, total_steps_ = 0, raw_total_ = 0;
};

class TraceReader {
  public:
    // Opens and validates the header, footer and index. Throws InputError naming the file and
    // the byte offset or chunk of any damage.
    explicit TraceReader(const std::string& path);
    ~TraceReader();
    TraceReader(const TraceReader&) = delete;
    TraceReader& operator=(const TraceReader&) = delete;

    const std::string& metadata_json() const { return metadata_; }
    // The metadata parsed once (a discarded value when it is not JSON).
    const nlohmann::json& metadata() const { return meta_; }
    uint32_t version() const { return version_; }
    size_t chunk_count() const { return index_.size(); }
    uint64_t rays() const { return total_rays_; }
    uint64_t steps() const { return total_steps_; }
    uint64_t file_bytes() const { return file_size_; }
    // Step addresses and sizes are derived from this layout: the header's bvh.layout when the
    // metadata has one (an RTSim trace), else whatever set_layout gives.
    void set_layout(const BvhLayout& layout) { layout_ = layout; }
    const BvhLayout& layout() const { return layout_; }

    // Decodes chunk k into out, replacing its records (their step vectors' memory is reused).
    // Throws InputError on damage, leaving out's contents unspecified.
    void read_chunk(size_t k, std::vector<TraceRecord>& out);
    // The same in pieces, so that a reader of big chunks holds only a few rays' steps at a
    // time: open_chunk reads, checks and decompresses chunk k; each read_records then decodes
    // up to `max_rays` more of its records into out (as read_chunk does) and returns how many;
    // chunk_rays_left tells how many remain. Throw InputError on damage.
    void open_chunk(size_t k);
    size_t read_records(size_t max_rays, std::vector<TraceRecord>& out);
    uint64_t chunk_rays_left() const { return chunk_rays_left_; }

  private:
    void read_header_and_index();  // the constructor's checks, after the file is open
    [[noreturn]] void chunk_fail(const std::string& what) const;
    [[noreturn]] void fail(uint64_t offset, const std::string& what) const;
    void read_at(uint64_t offset, void* data, size_t size, const char* what);

    std::string path_;
    std::FILE* f_ = nullptr;
    uint64_t file_size_ = 0, header_end_ = 0, index_offset_ = 0;
    uint32_t version_ = 0;
    std::string metadata_;
    nlohmann::json meta_;
    struct IndexEntry {
        uint64_t offset;
        uint32_t rays;
    };
    std::vector<IndexEntry> index_;
    uint64_t total_rays_ = 0, total_steps_ = 0;
    BvhLayout layout_;
    std::vector<char> compressed_, raw_;
    // The open chunk: its number and byte offset (for messages), where its next record starts
    // in raw_, its records read and left, and the last ray id (ids are delta coded).
    size_t chunk_ = 0;
    uint64_t chunk_at_ = 0;
    size_t chunk_pos_ = 0;
    uint64_t chunk_rays_read_ = 0, chunk_rays_left_ = 0;
    int64_t chunk_last_id_ = 0;
};

}  // namespace rtsim

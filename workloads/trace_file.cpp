#include "workloads/trace_file.h"

#include "workloads/bvh_summary.h"

#include <zlib.h>
#include <zstd.h>

#include <fmt/format.h>
#include <algorithm>
#include <array>
#include <cstring>
#include <limits>

#include "workloads/error.h"

namespace rtsim {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "trace files are little-endian");

namespace {

constexpr char kHeaderMagic[8] = {'R', 'T', 'S', 'I', 'M', 'T', 'R', 'C'};
constexpr char kFooterMagic[8] = {'R', 'T', 'S', 'I', 'M', 'E', 'N', 'D'};
constexpr char kChunkMagic[4] = {'C', 'H', 'N', 'K'};
constexpr char kIndexMagic[4] = {'I', 'N', 'D', 'X'};
constexpr size_t kChunkHeaderBytes = 24;
constexpr size_t kFooterBytes = 16;
constexpr uint32_t kMaxStepsPerRay = 1u << 24;

void put_u32(std::string& s, uint32_t v) {
    s.append(reinterpret_cast<const char*>(&v), 4);
}
void put_u64(std::string& s, uint64_t v) {
    s.append(reinterpret_cast<const char*>(&v), 8);
}
void put_varint(std::string& s, uint64_t v) {
    while (v >= 0x80) {
        s.push_back(char(uint8_t(v) | 0x80));
        v >>= 7;
    }
    s.push_back(char(v));
}
uint64_t zigzag(int64_t v) {
    return (uint64_t(v) << 1) ^ uint64_t(v >> 63);
}
int64_t unzigzag(uint64_t v) {
    return int64_t(v >> 1) ^ -int64_t(v & 1);
}

template <class T>
T get(const char* p) {
    T v;
    std::memcpy(&v, p, sizeof v);
    return v;
}

}  // namespace

uint32_t crc32(const void* data, size_t size, uint32_t crc) {
    // zlib's CRC-32 (the IEEE polynomial, as the format states), computed several bytes at a
    // time; it chains like this function's `crc` argument. Sizes are chunk sizes, far below
    // uInt's range, but fed in pieces anyway.
    const auto* p = static_cast<const Bytef*>(data);
    uLong c = crc;
    while (size > 0) {
        const auto piece = uInt(std::min<size_t>(size, size_t(1) << 30));
        c = ::crc32(c, p, piece);
        p += piece;
        size -= piece;
    }
    return uint32_t(c);
}

// ---------------------------------------------------------------------------------------------
// Writer

TraceWriter::TraceWriter(const std::string& path, const std::string& metadata_json,
                         uint32_t rays_per_chunk, int zstd_level, bool instances)
    : out_(path),
      rays_per_chunk_(std::max(1u, rays_per_chunk)),
      level_(zstd_level),
      instances_(instances) {
    std::string h(kHeaderMagic, 8);
    put_u32(h, kTraceVersion);
    put_u32(h, 0);  // flags, none defined yet
    put_u32(h, uint32_t(metadata_json.size()));
    h += metadata_json;
    put_u32(h, crc32(metadata_json.data(), metadata_json.size()));
    write(h.data(), h.size());
}

void TraceWriter::write(const void* data, size_t size) {
    out_.write(std::string(static_cast<const char*>(data), size));
    offset_ += size;
}

void TraceWriter::add(const TraceRecord& r) {
    put_varint(raw_, zigzag(int64_t(r.ray_id) - int64_t(last_ray_id_)));
    last_ray_id_ = r.ray_id;
    raw_.push_back(char(r.kind));
    put_varint(raw_, r.steps.size());
    // Per step kind the format can hold, reset per ray: a ray starts at the root.
    int64_t prev[kTraceStepKinds] = {};
    int64_t prev_depth = 0;
    for (const Step& s : r.steps) {
        if (int(s.kind) >= kTraceStepKinds)
            throw std::logic_error("trace: a step kind above 15 does not fit the format");
        // Version 2's step byte: the kind in the low 4 bits, the count in the high 4 (15: 15 or
        // more, the rest in a varint that follows).
        const int k = int(s.kind);
        const unsigned count_field = std::min<unsigned>(s.count, 15);
        raw_.push_back(char(uint8_t(k) | uint8_t(count_field << 4)));
        if (count_field == 15) put_varint(raw_, s.count - 15u);
        put_varint(raw_, zigzag(int64_t(s.id) - prev[k]));
        prev[k] = s.id;
        // Version 3: the stack's change of depth since the last step, and the pop bit.
        const int64_t depth = int64_t(stack_depth(s));
        put_varint(raw_, zigzag(depth - prev_depth) << 1 | (stack_popped(s) ? 1 : 0));
        prev_depth = depth;
    }
    if (r.prim == kInvalidPrim) {
        put_varint(raw_, 0);
    } else {
        put_varint(raw_, uint64_t(r.prim) + 1);
        raw_.append(reinterpret_cast<const char*>(&r.t), 4);
        // Version 4, two-level scenes: the instance hit, plus one (0: none).
        if (instances_) put_varint(raw_, r.instance == kInvalidPrim ? 0 : uint64_t(r.instance) + 1);
    }
    total_steps_ += r.steps.size();
    ++total_rays_;
    if (++chunk_rays_ == rays_per_chunk_) flush_chunk();
}

void TraceWriter::flush_chunk() {
    if (chunk_rays_ == 0) return;
    std::string payload(ZSTD_compressBound(raw_.size()), '\0');
    const size_t n =
        ZSTD_compress(payload.data(), payload.size(), raw_.data(), raw_.size(), level_);
    if (ZSTD_isError(n)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(n));
    payload.resize(n);
    std::string h(kChunkMagic, 4);
    put_u32(h, uint32_t(index_.size()));
    put_u32(h, chunk_rays_);
    put_u32(h, uint32_t(raw_.size()));
    put_u32(h, uint32_t(payload.size()));
    put_u32(h, crc32(payload.data(), payload.size()));
    index_.push_back({offset_, chunk_rays_});
    write(h.data(), h.size());
    write(payload.data(), payload.size());
    raw_total_ += raw_.size();
    raw_.clear();
    chunk_rays_ = 0;
    last_ray_id_ = 0;
}

void TraceWriter::finish() {
    flush_chunk();
    const uint64_t index_offset = offset_;
    std::string body;
    put_u32(body, uint32_t(index_.size()));
    put_u64(body, total_rays_);
    put_u64(body, total_steps_);
    for (const IndexEntry& e : index_) {
        put_u64(body, e.offset);
        put_u32(body, e.rays);
        put_u32(body, 0);
    }
    std::string idx(kIndexMagic, 4);
    idx += body;
    put_u32(idx, crc32(body.data(), body.size()));
    put_u64(idx, index_offset);
    idx.append(kFooterMagic, 8);
    write(idx.data(), idx.size());
    out_.commit();
}

// ---------------------------------------------------------------------------------------------
// Reader

void TraceReader::fail(uint64_t offset, const std::string& what) const {
    throw InputError(fmt::format("{}: byte {}: {}", path_, offset, what));
}

void TraceReader::read_at(uint64_t offset, void* data, size_t size, const char* what) {
    if (offset > file_size_ || size > file_size_ - offset)
        fail(offset, fmt::format("{} runs past the end of the file ({} bytes)", what, file_size_));
    if (std::fseek(f_, long(offset), SEEK_SET) != 0 || std::fread(data, 1, size, f_) != size)
        fail(offset, fmt::format("cannot read {}", what));
}

TraceReader::TraceReader(const std::string& path) : path_(path) {
    f_ = std::fopen(path.c_str(), "rb");
    if (!f_) throw InputError(fmt::format("{}: cannot open trace file", path));
    // A constructor that throws runs no destructor: close the file here (found by fuzzing, a
    // reader of many damaged traces ran out of file descriptors).
    try {
        read_header_and_index();
    } catch (...) {
        std::fclose(f_);
        f_ = nullptr;
        throw;
    }
}

void TraceReader::read_header_and_index() {
    std::fseek(f_, 0, SEEK_END);
    const long size = std::ftell(f_);
    file_size_ = size < 0 ? 0 : uint64_t(size);

    char head[20];
    if (file_size_ < sizeof head)
        fail(0, fmt::format("too short for a trace header ({} bytes)", file_size_));
    read_at(0, head, sizeof head, "header");
    if (std::memcmp(head, kHeaderMagic, 8) != 0) fail(0, "not an RTSim trace (wrong magic)");
    version_ = get<uint32_t>(head + 8);
    if (version_ < kOldestTraceVersion || version_ > kTraceVersion)
        fail(8, fmt::format("unknown trace format version {} (this build reads versions {} to {})",
                            version_, kOldestTraceVersion, kTraceVersion));
    if (get<uint32_t>(head + 12) != 0)
        fail(12, fmt::format("unknown header flags {:#x} (this build knows none)",
                             get<uint32_t>(head + 12)));
    const uint32_t meta_len = get<uint32_t>(head + 16);
    if (24 + uint64_t(meta_len) > file_size_)
        fail(16,
             fmt::format("header metadata of {} bytes runs past the end of the file", meta_len));
    metadata_.resize(meta_len);
    read_at(20, metadata_.data(), meta_len, "header metadata");
    uint32_t meta_crc;
    read_at(20 + uint64_t(meta_len), &meta_crc, 4, "header checksum");
    if (crc32(metadata_.data(), metadata_.size()) != meta_crc)
        fail(20, "header metadata checksum mismatch");
    header_end_ = 24 + uint64_t(meta_len);
    // An RTSim trace's header describes the BVH layout its steps' ids map through: the reader
    // sets it up itself (other writers' metadata, as in tests, leave it to set_layout).
    meta_ = nlohmann::json::parse(metadata_, nullptr, false);
    if (meta_.is_object() && meta_.contains("bvh") && meta_["bvh"].is_object())
        layout_ = layout_from_summary(meta_["bvh"], path_);

    if (file_size_ < header_end_ + kFooterBytes)
        fail(header_end_, "file ends before the footer (truncated)");
    char foot[kFooterBytes];
    read_at(file_size_ - kFooterBytes, foot, kFooterBytes, "footer");
    if (std::memcmp(foot + 8, kFooterMagic, 8) != 0)
        fail(file_size_ - kFooterBytes, "footer missing (truncated or damaged file)");
    index_offset_ = get<uint64_t>(foot);
    const uint64_t index_limit = file_size_ - kFooterBytes;
    if (index_offset_ < header_end_ || index_offset_ + 28 > index_limit)
        fail(file_size_ - kFooterBytes,
             fmt::format("index offset {} past the end of the data", index_offset_));
    char ih[24];
    read_at(index_offset_, ih, sizeof ih, "index header");
    if (std::memcmp(ih, kIndexMagic, 4) != 0) fail(index_offset_, "index missing (wrong magic)");
    const uint32_t chunks = get<uint32_t>(ih + 4);
    const uint64_t body_size = 20 + uint64_t(chunks) * 16;
    if (index_offset_ + 4 + body_size + 4 != index_limit)
        fail(index_offset_,
             fmt::format("index of {} chunks does not fit before the footer", chunks));
    std::vector<char> body(body_size);
    read_at(index_offset_ + 4, body.data(), body.size(), "index");
    uint32_t index_crc;
    read_at(index_offset_ + 4 + body_size, &index_crc, 4, "index checksum");
    if (crc32(body.data(), body.size()) != index_crc)
        fail(index_offset_, "index checksum mismatch");
    total_rays_ = get<uint64_t>(body.data() + 4);
    total_steps_ = get<uint64_t>(body.data() + 12);
    uint64_t rays = 0;
    index_.resize(chunks);
    for (uint32_t k = 0; k < chunks; ++k) {
        const char* e = body.data() + 20 + 16 * size_t(k);
        index_[k] = {get<uint64_t>(e), get<uint32_t>(e + 8)};
        if (index_[k].offset < header_end_ || index_[k].offset + kChunkHeaderBytes > index_offset_)
            fail(index_offset_,
                 fmt::format("index entry {} points to byte {}, outside the chunk area", k,
                             index_[k].offset));
        rays += index_[k].rays;
    }
    if (rays != total_rays_)
        fail(index_offset_,
             fmt::format("index chunks hold {} rays, the total says {}", rays, total_rays_));
}

TraceReader::~TraceReader() {
    if (f_) std::fclose(f_);
}

void TraceReader::read_chunk(size_t k, std::vector<TraceRecord>& out) {
    open_chunk(k);
    read_records(std::numeric_limits<size_t>::max(), out);
}

[[noreturn]] void TraceReader::chunk_fail(const std::string& what) const {
    throw InputError(fmt::format("{}: chunk {} (byte {}): {}", path_, chunk_, chunk_at_, what));
}

void TraceReader::open_chunk(size_t k) {
    chunk_rays_left_ = 0;
    if (k >= index_.size())
        throw InputError(
            fmt::format("{}: chunk {} past the last chunk ({})", path_, k, index_.size()));
    chunk_ = k;
    chunk_at_ = index_[k].offset;
    const uint64_t at = chunk_at_;
    char h[kChunkHeaderBytes];
    read_at(at, h, sizeof h, "chunk header");
    if (std::memcmp(h, kChunkMagic, 4) != 0) chunk_fail("wrong chunk magic");
    const uint32_t number = get<uint32_t>(h + 4), rays = get<uint32_t>(h + 8),
                   raw_size = get<uint32_t>(h + 12), comp_size = get<uint32_t>(h + 16),
                   crc = get<uint32_t>(h + 20);
    if (number != k || rays != index_[k].rays) chunk_fail("chunk header disagrees with the index");
    if (at + kChunkHeaderBytes + comp_size > index_offset_)
        chunk_fail("compressed data runs into the index");
    compressed_.resize(comp_size);
    read_at(at + kChunkHeaderBytes, compressed_.data(), comp_size, "chunk data");
    if (crc32(compressed_.data(), comp_size) != crc) chunk_fail("checksum mismatch (damaged data)");
    // The zstd frame states its content size; memory is allocated only for a size both agree on.
    const unsigned long long frame_size = ZSTD_getFrameContentSize(compressed_.data(), comp_size);
    if (frame_size != raw_size) chunk_fail("decompressed size disagrees with the chunk header");
    raw_.resize(raw_size);
    const size_t n = ZSTD_decompress(raw_.data(), raw_.size(), compressed_.data(), comp_size);
    if (ZSTD_isError(n) || n != raw_size) chunk_fail("cannot decompress");
    // Every ray takes at least 3 bytes and every step 2: no size claim can allocate beyond that.
    if (uint64_t(rays) * 3 > raw_size)
        chunk_fail(fmt::format("{} rays cannot fit in {} bytes", rays, raw_size));
    chunk_pos_ = 0;
    chunk_rays_read_ = 0;
    chunk_rays_left_ = rays;
    chunk_last_id_ = 0;
}

size_t TraceReader::read_records(size_t max_rays, std::vector<TraceRecord>& out) {
    // `out`'s records are overwritten, not cleared first: their step vectors keep their memory
    // (a reader of many chunks allocates only while rays grow longer than before).
    const char* p = raw_.data() + chunk_pos_;
    const char* const end = raw_.data() + raw_.size();
    auto varint = [&]() -> uint64_t {
        uint64_t v = 0;
        for (int shift = 0; shift < 64; shift += 7) {
            if (p == end) chunk_fail(fmt::format("record truncated at offset {}", p - raw_.data()));
            const uint8_t b = uint8_t(*p++);
            v |= uint64_t(b & 0x7F) << shift;
            if (!(b & 0x80)) return v;
        }
        chunk_fail("bad varint");
    };
    auto byte = [&]() -> uint8_t {
        if (p == end) chunk_fail(fmt::format("record truncated at offset {}", p - raw_.data()));
        return uint8_t(*p++);
    };
    // A varint known to have its bytes in the chunk when it has one or two (most step deltas):
    // decoded without a branch on its length, which varies unpredictably; longer ones go the
    // checked way. Needs two readable bytes at p.
    auto short_varint = [&]() -> uint64_t {
        const uint64_t b0 = uint8_t(p[0]), b1 = uint8_t(p[1]);
        if ((b0 & b1 & 0x80) != 0) return varint();
        const uint64_t two = b0 >> 7;
        p += 1 + two;
        return (b0 & 0x7F) | ((b1 & 0x7F) << 7 & -two);
    };
    // Per step kind, its records: picked by index, not by a branch on the kind, which
    // alternates unpredictably.
    BvhLayout::Records kinds[kStepKinds];
    for (int k = 0; k < kStepKinds; ++k) kinds[k] = layout_.records(StepKind(k));
    // Version 1's step byte: bit 0 the kind (node or triangle), bits 1-7 a node's children.
    const bool v1 = version_ == 1;
    const bool has_stack = version_ >= 3;
    const bool has_instances = version_ >= 4 && layout_.instance_count > 0;
    const size_t rays = size_t(std::min<uint64_t>(max_rays, chunk_rays_left_));
    out.resize(rays);
    int64_t last_id = chunk_last_id_;
    for (size_t j = 0; j < rays; ++j) {
        const uint64_t r = chunk_rays_read_ + j;  // the ray's place in its chunk, for messages
        TraceRecord& rec = out[j];
        last_id += unzigzag(varint());
        rec.ray_id = uint32_t(last_id);
        const uint8_t kind = byte();
        if (kind >= kRayKindCount) chunk_fail(fmt::format("ray {} has unknown kind {}", r, kind));
        rec.kind = RayKind(kind);
        const uint64_t count = varint();
        if (count > kMaxStepsPerRay || count * 2 > uint64_t(end - p))
            chunk_fail(fmt::format("ray {} claims {} steps, more than its chunk holds", r, count));
        rec.steps.resize(count);
        Step* step = rec.steps.data();
        int64_t prev[kStepKinds] = {};
        int64_t depth = 0;
        for (uint64_t i = 0; i < count; ++i) {
            const uint8_t b = byte();
            int sk;
            uint64_t items;
            if (v1) {
                sk = b & 1;
                items = ((b >> 1) & (sk - 1)) | sk;  // a triangle tests one
            } else {
                sk = b & 15;
                items = b >> 4;
                if (sk >= kStepKinds)
                    chunk_fail(fmt::format("ray {} step {} has unknown kind {}", r, i, sk));
                if (items == 15) {  // 15 or more: the rest follows
                    items += varint();
                    if (items > 255)
                        chunk_fail(
                            fmt::format("ray {} step {} has count {}, above 255", r, i, items));
                }
            }
            prev[sk] += unzigzag(end - p >= 2 ? short_varint() : varint());
            const BvhLayout::Records& K = kinds[sk];
            if (uint64_t(prev[sk]) >= K.count)  // negative ones too
                chunk_fail(fmt::format("ray {} step {} references {} {} outside the layout ({})", r,
                                       i, step_kind_info(sk).name, prev[sk], K.count));
            step[i] = BvhLayout::step(K, StepKind(sk), uint32_t(prev[sk]), uint8_t(items));
            if (has_stack) {
                const uint64_t v = end - p >= 2 ? short_varint() : varint();
                depth += unzigzag(v >> 1);
                if (depth < 0 || depth > int64_t(kStackDepthMax))
                    chunk_fail(fmt::format("ray {} step {} has stack depth {}, outside 0..{}", r, i,
                                           depth, kStackDepthMax));
                step[i].stack = stack_byte(unsigned(depth), (v & 1) != 0);
            }
        }
        rec.instance = kInvalidPrim;
        const uint64_t prim = varint();
        if (prim == 0) {
            rec.prim = kInvalidPrim;
            rec.t = std::numeric_limits<float>::infinity();
        } else {
            rec.prim = uint32_t(prim - 1);
            if (end - p < 4) chunk_fail("record truncated in its hit");
            std::memcpy(&rec.t, p, 4);
            p += 4;
            if (has_instances) {
                const uint64_t inst = varint();
                if (inst > layout_.instance_count)
                    chunk_fail(fmt::format("ray {} hit instance {}, of {}", r, inst - 1,
                                           layout_.instance_count));
                rec.instance = inst == 0 ? kInvalidPrim : uint32_t(inst - 1);
            }
        }
    }
    chunk_pos_ = size_t(p - raw_.data());
    chunk_rays_read_ += rays;
    chunk_rays_left_ -= rays;
    chunk_last_id_ = last_id;
    if (chunk_rays_left_ == 0 && p != end)
        chunk_fail(fmt::format("{} bytes left after the last record", end - p));
    return rays;
}

}  // namespace rtsim

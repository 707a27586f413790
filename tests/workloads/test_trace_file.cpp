#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "support/input_error.h"
#include "support/scratch_dir.h"

#include <sys/resource.h>

#include <algorithm>
#include "workloads/error.h"
#include "workloads/trace_file.h"

using namespace rtsim;
namespace fs = std::filesystem;

namespace {

BvhLayout test_layout() {
    BvhLayout L;
    L.node_size_bytes = 64;
    L.inner_node_count = 5000;
    L.triangle_count = 9000;
    L.tri_base_addr = 0x20000000;
    return L;
}

std::vector<TraceRecord> random_records(int n, uint32_t seed) {
    std::mt19937 rng(seed);
    const BvhLayout L = test_layout();
    std::vector<TraceRecord> out(n);
    for (int i = 0; i < n; ++i) {
        TraceRecord& r = out[i];
        r.ray_id = uint32_t(i * 3 + (i % 5 == 0 ? 1000 : 0));  // gaps and jumps in ids
        r.kind = RayKind(rng() % kRayKindCount);
        const int steps = int(rng() % 40);
        for (int k = 0; k < steps; ++k) {
            Step s{};
            s.kind = (rng() % 3 == 0) ? StepKind::Triangle : StepKind::Node;
            s.id = s.kind == StepKind::Node ? rng() % L.inner_node_count : rng() % L.triangle_count;
            s.count = s.kind == StepKind::Node ? uint8_t(2 + rng() % 7) : 1;
            s.addr = s.kind == StepKind::Node ? L.node_addr(s.id) : L.tri_addr(s.id);
            s.size_bytes =
                uint16_t(s.kind == StepKind::Node ? L.node_size_bytes : L.tri_size_bytes);
            // Stack depths in their whole range (jumps included), popped or not.
            s.stack = stack_byte(unsigned(rng() % 5 == 0 ? rng() % 128 : k % 9), rng() % 2 == 0);
            r.steps.push_back(s);
        }
        if (rng() % 2) {
            r.prim = rng() % L.triangle_count;
            r.t = float(rng() % 1000) / 7.0f;
        }
    }
    return out;
}

std::string temp_path(const std::string& name) {
    return (test::scratch_dir() / name).string();
}

std::string write_trace(const std::string& name, const std::vector<TraceRecord>& recs,
                        uint32_t chunk_rays) {
    const std::string path = temp_path(name);
    TraceWriter w(path, R"({"test": true})", chunk_rays);
    for (const auto& r : recs) w.add(r);
    w.finish();
    return path;
}

std::vector<TraceRecord> read_all(const std::string& path) {
    TraceReader r(path);
    r.set_layout(test_layout());
    std::vector<TraceRecord> all, chunk;
    for (size_t k = 0; k < r.chunk_count(); ++k) {
        r.read_chunk(k, chunk);
        all.insert(all.end(), chunk.begin(), chunk.end());
    }
    return all;
}

void expect_same(const std::vector<TraceRecord>& a, const std::vector<TraceRecord>& b) {
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a[i].ray_id, b[i].ray_id) << i;
        ASSERT_EQ(a[i].kind, b[i].kind) << i;
        ASSERT_EQ(a[i].prim, b[i].prim) << i;
        if (a[i].prim != kInvalidPrim) {
            ASSERT_EQ(a[i].t, b[i].t) << i;
        }
        ASSERT_EQ(a[i].steps.size(), b[i].steps.size()) << i;
        for (size_t k = 0; k < a[i].steps.size(); ++k) {
            const Step &x = a[i].steps[k], &y = b[i].steps[k];
            ASSERT_EQ(x.kind, y.kind);
            ASSERT_EQ(x.id, y.id);
            ASSERT_EQ(x.count, y.count);
            ASSERT_EQ(x.addr, y.addr);
            ASSERT_EQ(x.size_bytes, y.size_bytes);
            ASSERT_EQ(x.stack, y.stack);
        }
    }
}

std::string slurp(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

void spit(const std::string& p, const std::string& bytes) {
    std::ofstream(p, std::ios::binary) << bytes;
}

// Reading must fail with one line naming the file and containing `fragment`.
void expect_damage(const std::string& path, const std::string& fragment) {
    test::expect_input_error([&] { read_all(path); }, path, fragment);
}

}  // namespace

TEST(TraceFile, RoundTripAcrossChunks) {
    const auto recs = random_records(1000, 1);
    const std::string path = write_trace("rt.rtt", recs, 64);
    TraceReader r(path);
    EXPECT_EQ(r.chunk_count(), 16u);  // 1000 rays in chunks of 64
    EXPECT_EQ(r.rays(), 1000u);
    EXPECT_EQ(r.metadata_json(), R"({"test": true})");
    uint64_t steps = 0;
    for (const auto& x : recs) steps += x.steps.size();
    EXPECT_EQ(r.steps(), steps);
    expect_same(recs, read_all(path));
}

// Version 2 widened the step byte: counts of 15 and more take a varint after it, and a kind
// this build does not know is refused with the ray and step.
TEST(TraceFile, WideCountsRoundTripAndUnknownStepKindsAreRefused) {
    auto recs = random_records(50, 11);
    for (auto& r : recs)
        for (auto& s : r.steps)
            if (s.kind == StepKind::Node)
                s.count = uint8_t(s.id % 3 == 0 ? 15 + s.id % 241 : s.count);
    expect_same(recs, read_all(write_trace("wide.rtt", recs, 16)));

    // The format has room for 16 kinds; this build knows kStepKinds of them.
    TraceRecord one;
    one.ray_id = 7;
    Step st{};
    st.kind = StepKind(9);
    st.count = 1;
    one.steps.push_back(st);
    const std::string path = write_trace("kind.rtt", {one}, 4);
    test::expect_input_error([&] { read_all(path); }, path, "ray 0 step 0 has unknown kind 9");
}

TEST(TraceFile, SeeksToAnyChunk) {
    const auto recs = random_records(300, 2);
    const std::string path = write_trace("seek.rtt", recs, 50);
    TraceReader r(path);
    r.set_layout(test_layout());
    std::vector<TraceRecord> chunk;
    for (size_t k : {5u, 0u, 3u}) {
        r.read_chunk(k, chunk);
        ASSERT_EQ(chunk.size(), 50u);
        expect_same(std::vector<TraceRecord>(recs.begin() + 50 * k, recs.begin() + 50 * (k + 1)),
                    chunk);
    }
    EXPECT_THROW(r.read_chunk(6, chunk), InputError);
}

TEST(TraceFile, ChunksDecodeInPiecesAsWhole) {
    // Pieces of 7 records (uneven against chunks of 50), the records' vectors reused piece to
    // piece as a replay reuses them: the same records as read_chunk gives, in order.
    const auto recs = random_records(300, 6);
    const std::string path = write_trace("pieces.rtt", recs, 50);
    TraceReader r(path);
    r.set_layout(test_layout());
    std::vector<TraceRecord> all, piece;
    for (size_t k = 0; k < r.chunk_count(); ++k) {
        r.open_chunk(k);
        EXPECT_EQ(r.chunk_rays_left(), 50u);
        while (r.chunk_rays_left() > 0) {
            const size_t n = r.read_records(7, piece);
            ASSERT_EQ(n, piece.size());
            ASSERT_LE(n, 7u);
            all.insert(all.end(), piece.begin(), piece.end());
        }
        EXPECT_EQ(r.read_records(7, piece), 0u);
    }
    expect_same(recs, all);
    // Damage past the first piece is still found, naming the chunk.
    std::string bytes = slurp(path);
    bytes[bytes.size() / 2] ^= 0x21;
    const std::string bad = temp_path("pieces-bad.rtt");
    spit(bad, bytes);
    test::expect_input_error(
        [&] {
            TraceReader b(bad);
            b.set_layout(test_layout());
            for (size_t k = 0; k < b.chunk_count(); ++k)
                for (b.open_chunk(k); b.chunk_rays_left() > 0;) b.read_records(7, piece);
        },
        bad, "chunk");
}

TEST(TraceFile, EmptyTraceIsValid) {
    const std::string path = write_trace("empty.rtt", {}, 16);
    TraceReader r(path);
    EXPECT_EQ(r.chunk_count(), 0u);
    EXPECT_EQ(r.rays(), 0u);
}

TEST(TraceFile, NamedDamageIsRefused) {
    const std::string good = write_trace("good.rtt", random_records(200, 3), 40);
    const std::string bytes = slurp(good);
    const std::string p = temp_path("bad.rtt");
    auto with = [&](std::string b) {
        spit(p, b);
        return p;
    };
    expect_damage(with("NOTATRACE-------------------------"), "wrong magic");
    std::string v = bytes;
    v[8] = 99;
    expect_damage(with(v), "unknown trace format version 99");
    expect_damage(with(bytes.substr(0, bytes.size() / 2)), "footer missing");
    expect_damage(with(bytes.substr(0, 10)), "too short");
    std::string meta = bytes;
    meta[22] ^= 0x10;
    expect_damage(with(meta), "header metadata checksum");
    // The first chunk's payload starts after the header (24 + metadata) and its 24-byte header.
    std::string payload = bytes;
    payload[24 + 14 + 24 + 5] ^= 0x01;
    expect_damage(with(payload), "chunk 0");
    std::string index = bytes;
    const size_t footer = bytes.size() - 16;
    uint64_t index_offset;
    std::memcpy(&index_offset, bytes.data() + footer, 8);
    index[index_offset + 10] ^= 0x40;
    expect_damage(with(index), "index checksum mismatch");
    std::string past = bytes;
    const uint64_t far = bytes.size() * 4;
    std::memcpy(past.data() + footer, &far, 8);
    expect_damage(with(past), "past the end");
    expect_damage(temp_path("missing.rtt"), "cannot open");
}

TEST(TraceFile, EverySingleByteCorruptionIsCaught) {
    // Every byte is covered by a checksum, a magic number or a cross-check, so flipping any one
    // byte must give an InputError: never a crash, a hang, or silently different data.
    const std::string good = write_trace("flip.rtt", random_records(40, 4), 8);
    const std::string bytes = slurp(good);
    const std::string p = temp_path("flipped.rtt");
    int caught = 0;
    for (size_t i = 0; i < bytes.size(); ++i) {
        std::string b = bytes;
        b[i] = char(b[i] ^ 0x5A);
        spit(p, b);
        try {
            read_all(p);
            ADD_FAILURE() << "corruption at byte " << i << " of " << bytes.size()
                          << " went unnoticed";
        } catch (const InputError&) {
            ++caught;
        }
    }
    EXPECT_EQ(caught, int(bytes.size()));
}

TEST(TraceFile, StepsOutsideTheLayoutAreRefused) {
    const std::string path = write_trace("layout.rtt", random_records(50, 5), 16);
    TraceReader r(path);
    BvhLayout small = test_layout();
    small.inner_node_count = 10;  // far fewer nodes than the trace references
    r.set_layout(small);
    std::vector<TraceRecord> chunk;
    try {
        r.read_chunk(0, chunk);
        FAIL() << "accepted node ids beyond the layout";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("outside the layout"), std::string::npos) << e.what();
    }
}

TEST(TraceFile, Crc32MatchesTheStandardCheckValue) {
    EXPECT_EQ(crc32("123456789", 9), 0xCBF43926u);  // CRC-32/ISO-HDLC check value, as zlib's
}

// Found by fuzzing (scripts/fuzz.sh, fuzz_trace): a reader refusing a damaged trace in its
// constructor kept the file open, so a process checking many traces ran out of descriptors.
// More damaged traces than a process may hold open must each be refused for their damage.
TEST(TraceFile, RefusedTracesReleaseTheirFiles) {
    const std::string bytes = slurp(write_trace("good_fd.rtt", random_records(20, 5), 10));
    const std::string p = temp_path("truncated_fd.rtt");
    spit(p, bytes.substr(0, bytes.size() / 2));
    // Few descriptors for the duration, so a leak shows within the loop.
    rlimit saved{};
    getrlimit(RLIMIT_NOFILE, &saved);
    rlimit few = saved;
    few.rlim_cur = std::min<rlim_t>(saved.rlim_cur, 256);
    setrlimit(RLIMIT_NOFILE, &few);
    struct Restore {
        rlimit limit;
        ~Restore() { setrlimit(RLIMIT_NOFILE, &limit); }
    } restore{saved};
    for (int i = 0; i < 1000; ++i) {
        try {
            TraceReader r(p);
            ADD_FAILURE() << "a truncated trace was accepted";
            return;
        } catch (const InputError& e) {
            if (std::string(e.what()).find("footer missing") == std::string::npos) {
                ADD_FAILURE() << "attempt " << i << ": " << e.what();
                return;
            }
        }
    }
}

// Version 4: a trace of a two-level scene records each hit's instance, and reads it back; an
// instance beyond the layout's instance records is damage, named as such.
TEST(TraceFile, TwoLevelHitsKeepTheirInstance) {
    std::vector<TraceRecord> recs = random_records(700, 29);
    std::mt19937 rng(5);
    for (TraceRecord& r : recs)
        if (r.prim != kInvalidPrim) r.instance = rng() % 50;
    const std::string path = temp_path("instances.rtt");
    {
        TraceWriter w(path, R"({"test": true})", 128, 3, /*instances=*/true);
        for (const auto& r : recs) w.add(r);
        w.finish();
    }
    BvhLayout L = test_layout();
    L.instance_count = 50;
    TraceReader reader(path);
    reader.set_layout(L);
    std::vector<TraceRecord> all, chunk;
    for (size_t k = 0; k < reader.chunk_count(); ++k) {
        reader.read_chunk(k, chunk);
        all.insert(all.end(), chunk.begin(), chunk.end());
    }
    expect_same(recs, all);
    size_t hits = 0;
    for (size_t i = 0; i < recs.size(); ++i) {
        EXPECT_EQ(all[i].instance, recs[i].instance) << i;
        hits += recs[i].prim != kInvalidPrim;
    }
    EXPECT_GT(hits, 300u);
    L.instance_count = 10;
    TraceReader small(path);
    small.set_layout(L);
    test::expect_input_error([&] { small.read_chunk(0, chunk); }, path, "hit instance");
}

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "support/input_error.h"
#include "support/scratch_dir.h"
#include "workloads/error.h"
#include "workloads/ray_file.h"

using namespace rtsim;
namespace fs = std::filesystem;

namespace {

std::string write_bytes(const std::string& name, const std::string& bytes) {
    const fs::path p = test::scratch_dir() / name;
    std::ofstream(p, std::ios::binary) << bytes;
    return p.string();
}

std::string records(std::initializer_list<std::array<float, 8>> recs) {
    std::string s;
    for (const auto& r : recs) s.append(reinterpret_cast<const char*>(r.data()), 32);
    return s;
}

void expect_error(const std::string& path, const std::string& fragment) {
    test::expect_input_error(
        [&] {
            RayFileReader r(path);
            std::vector<Ray> rays;
            while (r.read(rays, 2)) {
            }
        },
        path, fragment);
}

const float kInf = std::numeric_limits<float>::infinity();
const float kNaN = std::numeric_limits<float>::quiet_NaN();

}  // namespace

TEST(RayFile, RoundTripInBlocks) {
    std::vector<Ray> rays(5);
    for (int i = 0; i < 5; ++i) {
        rays[i].org = Vec3(float(i), 2.0f, -3.5f);
        rays[i].dir = Vec3(0.0f, 0.0f, 1.0f + i);
        rays[i].tmin = 0.25f * i;
        rays[i].tmax = i == 4 ? kInf : 10.0f * i;
    }
    std::string bytes;
    append_ray_records(rays, bytes);
    ASSERT_EQ(bytes.size(), 5 * kRayRecordBytes);
    RayFileReader r(write_bytes("rt.bin", bytes));
    EXPECT_EQ(r.ray_count(), 5u);
    std::vector<Ray> block, all;
    while (r.read(block, 2)) all.insert(all.end(), block.begin(), block.end());
    ASSERT_EQ(all.size(), 5u);
    for (int i = 0; i < 5; ++i) {
        EXPECT_EQ(all[i].org.x, rays[i].org.x);
        EXPECT_EQ(all[i].dir.z, rays[i].dir.z);
        EXPECT_EQ(all[i].tmin, rays[i].tmin);
        EXPECT_EQ(all[i].tmax, rays[i].tmax);
    }
}

TEST(RayFile, BadFilesNameTheRecord) {
    const std::array<float, 8> good = {0, 0, 0, 0, 0, 0, 1, kInf};
    expect_error(write_bytes("trunc.bin", records({good, good}).substr(0, 50)),
                 "truncated at byte 32");
    expect_error(write_bytes("nan.bin", records({good, {0, kNaN, 0, 0, 0, 0, 1, 1}})),
                 "ray 1 (byte 32)");
    expect_error(write_bytes("inf.bin", records({good, good, {kInf, 0, 0, 0, 0, 0, 1, 1}})),
                 "ray 2 (byte 64)");
    expect_error(write_bytes("infdir.bin", records({{0, 0, 0, 0, 0, -kInf, 0, 1}})), "finite");
    expect_error(write_bytes("zero.bin", records({{0, 0, 0, 0, 0, 0, 0, 1}})), "zero direction");
    expect_error(write_bytes("tmaxnan.bin", records({{0, 0, 0, 0, 1, 0, 0, kNaN}})), "tmax is NaN");
    expect_error(write_bytes("tmin.bin", records({{0, 0, 0, -1, 1, 0, 0, 1}})), "negative tmin");
    expect_error("/no/such/rays.bin", "cannot open");
}

TEST(RayFile, EmptyFileHasNoRays) {
    RayFileReader r(write_bytes("empty.bin", ""));
    std::vector<Ray> rays;
    EXPECT_FALSE(r.read(rays, 10));
    EXPECT_EQ(r.ray_count(), 0u);
}

TEST(HitFile, CsvAndBinaryRecords) {
    Hit h;
    h.t = 1.5f;
    h.prim = 7;
    h.u = 0.25f;
    h.v = 0.5f;
    std::string csv;
    append_hit_csv(3, h, csv);
    append_hit_csv(4, Hit(), csv);
    EXPECT_EQ(csv, "3,1.5,7,0.25,0.5\n4,inf,-1,0,0\n");
    std::string bin;
    append_hit_binary(4, Hit(), bin);
    ASSERT_EQ(bin.size(), kHitRecordBytes);
    uint32_t id;
    float t;
    int32_t prim;
    std::memcpy(&id, bin.data(), 4);
    std::memcpy(&t, bin.data() + 4, 4);
    std::memcpy(&prim, bin.data() + 8, 4);
    EXPECT_EQ(id, 4u);
    EXPECT_TRUE(std::isinf(t));
    EXPECT_EQ(prim, -1);
}

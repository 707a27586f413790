#include "workloads/ray_file.h"

#include <fmt/format.h>
#include <cmath>
#include <cstring>

#include "workloads/error.h"

namespace rtsim {

static_assert(sizeof(float) == 4 && sizeof(uint32_t) == 4, "record layout assumes 32-bit floats");
// Records are little-endian; this build reads and writes them as host floats, so require that.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "ray files are little-endian");

RayFileReader::RayFileReader(const std::string& path) : path_(path) {
    f_ = std::fopen(path.c_str(), "rb");
    if (!f_) throw InputError(fmt::format("{}: cannot open ray file", path));
    std::fseek(f_, 0, SEEK_END);
    const long size = std::ftell(f_);
    std::fseek(f_, 0, SEEK_SET);
    if (size < 0) {
        std::fclose(f_);
        f_ = nullptr;
        throw InputError(fmt::format("{}: cannot read ray file", path));
    }
    if (size % kRayRecordBytes != 0) {
        std::fclose(f_);
        f_ = nullptr;
        throw InputError(
            fmt::format("{}: size {} bytes is not a whole number of 32-byte ray records "
                        "(truncated at byte {})",
                        path, size, size - size % kRayRecordBytes));
    }
    total_rays_ = uint64_t(size) / kRayRecordBytes;
}

RayFileReader::~RayFileReader() {
    if (f_) std::fclose(f_);
}

bool RayFileReader::read(std::vector<Ray>& out, size_t max_rays) {
    out.clear();
    if (next_ray_ >= total_rays_) return false;
    const size_t n = size_t(std::min<uint64_t>(max_rays, total_rays_ - next_ray_));
    std::vector<float> buf(n * 8);
    if (std::fread(buf.data(), kRayRecordBytes, n, f_) != n)
        throw InputError(
            fmt::format("{}: read failed at byte {}", path_, next_ray_ * kRayRecordBytes));
    out.resize(n);
    for (size_t i = 0; i < n; ++i) {
        const float* r = &buf[i * 8];
        const uint64_t index = next_ray_ + i;
        auto bad = [&](const char* what) {
            return InputError(fmt::format("{}: ray {} (byte {}): {}", path_, index,
                                          index * kRayRecordBytes, what));
        };
        for (int k : {0, 1, 2, 3, 4, 5, 6})
            if (!std::isfinite(r[k])) throw bad("origin, direction and tmin must be finite");
        if (std::isnan(r[7])) throw bad("tmax is NaN");
        if (r[4] == 0.0f && r[5] == 0.0f && r[6] == 0.0f) throw bad("zero direction");
        if (r[3] < 0.0f) throw bad("negative tmin");
        Ray& ray = out[i];
        ray.org = Vec3(r[0], r[1], r[2]);
        ray.tmin = r[3];
        ray.dir = Vec3(r[4], r[5], r[6]);
        ray.tmax = r[7];
    }
    next_ray_ += n;
    return true;
}

void append_ray_records(const std::vector<Ray>& rays, std::string& out) {
    for (const Ray& r : rays) {
        const float rec[8] = {r.org.x, r.org.y, r.org.z, r.tmin, r.dir.x, r.dir.y, r.dir.z, r.tmax};
        out.append(reinterpret_cast<const char*>(rec), sizeof rec);
    }
}

void append_hit_csv(uint64_t ray, const Hit& h, std::string& out, bool with_instance) {
    if (h.valid())
        out += fmt::format("{},{},{},{},{}", ray, h.t, h.prim, h.u, h.v);
    else
        out += fmt::format("{},inf,-1,0,0", ray);
    if (with_instance) out += h.valid() ? fmt::format(",{}", h.instance) : std::string(",-1");
    out += '\n';
}

void append_hit_binary(uint64_t ray, const Hit& h, std::string& out) {
    const uint32_t id = uint32_t(ray);
    const float t = h.valid() ? h.t : std::numeric_limits<float>::infinity();
    const int32_t prim = h.valid() ? int32_t(h.prim) : -1;
    const float u = h.valid() ? h.u : 0.0f, v = h.valid() ? h.v : 0.0f;
    char rec[kHitRecordBytes];
    std::memcpy(rec, &id, 4);
    std::memcpy(rec + 4, &t, 4);
    std::memcpy(rec + 8, &prim, 4);
    std::memcpy(rec + 12, &u, 4);
    std::memcpy(rec + 16, &v, 4);
    out.append(rec, sizeof rec);
}

}  // namespace rtsim

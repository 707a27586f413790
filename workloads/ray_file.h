// External ray and hit files, so rays from any renderer can be traced and compared.
//
// Ray file: a sequence of 32-byte little-endian records, float32 ox oy oz tmin dx dy dz tmax.
// Directions need not be normalised (t is in units of the given direction, as in Embree).
// Rejected, with the record index and byte offset: a size that is not a multiple of 32, NaN or
// infinite origin, direction or tmin, a NaN tmax, a zero direction, a negative tmin. Accepted:
// tmax = +inf (unbounded), and tmin > tmax (a ray that can hit nothing: it misses).
//
// Hit files: CSV with header `ray,t,prim,u,v`, or 20-byte little-endian binary records
// uint32 ray, float32 t, int32 prim, float32 u, float32 v. A miss has t = inf, prim = -1, u = v =
// 0.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "workloads/geometry.h"

namespace rtsim {

constexpr size_t kRayRecordBytes = 32;
constexpr size_t kHitRecordBytes = 20;

// Streams rays from a file in blocks; never holds the whole file.
class RayFileReader {
  public:
    explicit RayFileReader(const std::string& path);  // throws InputError
    ~RayFileReader();
    RayFileReader(const RayFileReader&) = delete;
    RayFileReader& operator=(const RayFileReader&) = delete;
    // Reads up to `max_rays` rays into out (cleared first); false at the end of the file.
    // Throws InputError naming the file, ray index and byte offset of a bad record.
    bool read(std::vector<Ray>& out, size_t max_rays);
    uint64_t ray_count() const { return total_rays_; }

  private:
    std::string path_;
    std::FILE* f_ = nullptr;
    uint64_t total_rays_ = 0, next_ray_ = 0;
};

// Writes rays in the ray-file format.
void append_ray_records(const std::vector<Ray>& rays, std::string& out);

// Hit output in both formats.
// with_instance: a sixth column, the instance hit (-1 on a miss), for two-level scenes.
void append_hit_csv(uint64_t ray, const Hit& h, std::string& out, bool with_instance = false);
void append_hit_binary(uint64_t ray, const Hit& h, std::string& out);
constexpr const char* kHitCsvHeader = "ray,t,prim,u,v\n";
constexpr const char* kInstancedHitCsvHeader = "ray,t,prim,u,v,instance\n";

}  // namespace rtsim

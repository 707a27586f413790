// Ray generation: an auto-framed pinhole camera and secondary rays from primary hits, streamed
// tile by tile so memory stays bounded at any resolution.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "workloads/bvh.h"
#include "workloads/scene.h"
#include "workloads/step.h"
#include "workloads/tracer.h"

namespace rtsim {

struct RayGenOptions {
    int width = 256, height = 256;
    std::array<bool, kRayKindCount> kinds{{true, false, false}};  // indexed by RayKind
    int ao_samples = 2;                                           // AO rays per primary hit
    float ao_length_fraction = 0.1f;  // AO ray length, as a fraction of the scene's diagonal
    uint64_t seed = 1;
    int tile_size = 8;  // pixels per tile edge; rays are emitted tile by tile

    bool wants(RayKind k) const { return kinds[static_cast<int>(k)]; }
};

// Parses "primary,ao,shadow". Throws InputError naming `what` (e.g. "--rays").
std::array<bool, kRayKindCount> parse_ray_kinds(const std::string& list, const std::string& what);
std::string ray_kinds_to_string(const std::array<bool, kRayKindCount>& kinds);

struct Camera {
    Vec3 eye, forward, right, up;
    float tan_half_fov_y = 0.41421356f;  // 45 degrees
    float aspect = 1.0f;
    // Frames the whole of `bounds`, looking slightly down at it from +z.
    static Camera frame(const AABB& bounds, int width, int height);
    Ray generate(float px, float py, int width, int height) const;
};

// Moves a surface point off the surface along the geometric normal by an amount scaled to the
// point's magnitude (Wächter & Binder, Ray Tracing Gems ch. 6), so secondary rays do not
// re-hit the surface they start on. `n` points to the side the new ray leaves from.
Vec3 offset_ray_origin(Vec3 p, Vec3 n);

struct GeneratedRay {
    Ray ray;
    uint32_t id;
    RayKind kind;
    HitQuery query;
};

class RayGenerator {
  public:
    RayGenerator(const Scene& scene, const Bvh& bvh, const RayGenOptions& options);
    // Appends the next tile's rays (primaries, then shadow, then AO) to out; false when done.
    bool next_tile(std::vector<GeneratedRay>& out);
    const Camera& camera() const { return camera_; }
    Vec3 light_position() const { return light_; }
    float ao_length() const { return ao_length_; }

  private:
    const Scene& scene_;
    const Bvh& bvh_;
    RayGenOptions opt_;
    Camera camera_;
    Vec3 light_;
    float ao_length_;
    int tiles_x_, tiles_y_, next_tile_ = 0;
    uint32_t next_id_ = 0;
};

}  // namespace rtsim

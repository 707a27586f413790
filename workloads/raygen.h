// Ray generation: an auto-framed pinhole camera and secondary rays from surface hits, streamed
// tile by tile so memory stays bounded at any resolution.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "workloads/bvh.h"
#include "workloads/instances.h"
#include "workloads/scene.h"
#include "workloads/step.h"
#include "workloads/tracer.h"

namespace rtsim {

enum class LightKind : uint8_t { Point, Area };

struct RayGenOptions {
    int width = 128, height = 128;
    int spp = 1;  // primary samples per pixel: 1 is the pixel centre, more are jittered
    std::array<bool, kRayKindCount> kinds{{true, false, false, false, false}};  // by RayKind
    int ao_samples = 2;               // AO rays per primary hit
    float ao_length_fraction = 0.1f;  // AO ray length, as a fraction of the scene's diagonal
    int diffuse_depth = 2;            // diffuse bounces per primary hit
    LightKind light = LightKind::Point;
    uint64_t seed = 1;
    int tile_size = 8;  // pixels per tile edge; rays are emitted tile by tile

    bool wants(RayKind k) const { return kinds[static_cast<int>(k)]; }
    // Throws InputError naming the command-line option of a bad value.
    void validate() const;
};

// Parses "primary,ao,shadow". Throws InputError naming `what` (e.g. "--rays").
std::array<bool, kRayKindCount> parse_ray_kinds(const std::string& list, const std::string& what);
std::string ray_kinds_to_string(const std::array<bool, kRayKindCount>& kinds);
LightKind parse_light_kind(const std::string& text, const std::string& what);
const char* light_kind_name(LightKind k);

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
// `scene_scale` is the scene's largest coordinate magnitude: near the origin, where a point's
// own ulps are far finer than the rounding of the vertices it was interpolated from, the move
// is a fixed fraction of it (1/65536) instead of the paper's constant for scenes of size ~1,
// which moved points of a 1e-6-sized scene 15 times its size away.
Vec3 offset_ray_origin(Vec3 p, Vec3 n, float scene_scale = 1.0f);

// The scenes whose guarantees (watertight traversal, hit distances to double precision,
// secondary rays that neither re-hit nor escape their surface) the stress suite checks
// (tests/workloads/test_numerics.cpp, bench/results/stress_numerics.txt).
constexpr float kMinSceneExtent = 1e-9f, kMaxSceneExtent = 1e12f;
constexpr float kMaxOffsetOverExtent = 1e2f;  // coordinates up to this many extents from 0

// Holds a scene's bounds to that range, the same for every command that traces it (a generated
// frame or a rays file): throws InputError naming the scene where single-precision tests fail
// outright (an extent that overflows a float or exceeds kMaxSceneExtent, where every ray
// misses), and warns (workloads/error.h) where hits may lose precision.
void check_scene_range(const std::string& scene_name, const AABB& bounds);

struct GeneratedRay {
    Ray ray;
    uint32_t id;
    RayKind kind;
    HitQuery query;
    // With RayGenerator::set_record_steps: rays the generator traced anyway (primaries and
    // diffuse bounces whose hits start further rays) carry that trace, so it is not redone.
    bool traced = false;
    uint32_t prim = kInvalidPrim;
    std::vector<Step> steps;
};

// Emits, per tile: primary rays; then from their hits shadow rays (to a point light, or to a
// random point of an area light), AO rays, a mirror reflection ray, and diffuse paths of
// `diffuse_depth` bounces (all bounce-1 rays of the tile, then bounce 2, ...). Secondary rays
// are generated whether or not primaries are requested, so `--rays ao` simulates AO alone.
class RayGenerator {
  public:
    RayGenerator(const Scene& scene, const Bvh& bvh, const RayGenOptions& options);
    // Over a two-level scene: the same rays, traced through its instances.
    RayGenerator(const InstancedScene& scene, const TwoLevelBvh& bvh, const RayGenOptions& options);
    // Appends tile `index`'s rays (0 <= index < tile_count()) to out, their ids numbered from 0
    // within the tile (TileQueue, workloads/tile_queue.h, hands tiles on in order and numbers ids
    // through the frame); returns how many. Tiles are independent: several threads may generate
    // tiles at once.
    uint32_t generate_tile(int index, std::vector<GeneratedRay>& out) const;
    // Rays the generator traces to find hits keep their step streams (see GeneratedRay).
    void set_record_steps(bool record) { record_steps_ = record; }
    int tile_count() const { return tiles_x_ * tiles_y_; }
    const Camera& camera() const { return camera_; }
    float ao_length() const { return ao_length_; }
    // Point light position, or the area light's corner and edges.
    Vec3 light_position() const { return light_; }
    Vec3 light_edge_u() const { return light_u_; }
    Vec3 light_edge_v() const { return light_v_; }

  private:
    bool record_steps_ = false;
    struct SurfacePoint {
        Vec3 p, n;        // offset origin; normal facing the incoming ray
        Vec3 incoming;    // direction of the ray that found it
        uint64_t stream;  // random stream of this path (pixel and sample)
    };
    bool surface_point(const Ray& r, const Hit& h, uint64_t stream, SurfacePoint& out) const;

    void init(const std::string& name, const AABB& bounds);
    // One level (scene_, bvh_) or two (instanced_, two_).
    const Scene* scene_ = nullptr;
    const Bvh* bvh_ = nullptr;
    const InstancedScene* instanced_ = nullptr;
    const TwoLevelBvh* two_ = nullptr;
    RayGenOptions opt_;
    Camera camera_;
    float scene_scale_ = 1.0f;  // largest coordinate magnitude (offset_ray_origin)
    Vec3 light_, light_u_, light_v_;
    float ao_length_;
    int tiles_x_, tiles_y_;
};

}  // namespace rtsim

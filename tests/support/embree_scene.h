// Embree 3 (libembree-dev) as the oracle and speed baseline: one scene of our triangles, single
// rays in and out. Shared by tests/workloads/test_embree.cpp and bench/bench_tracer.cpp.
#pragma once

#include <embree3/rtcore.h>

#include <chrono>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "workloads/geometry.h"
#include "workloads/instances.h"
#include "workloads/scene.h"

namespace rtsim::test {

class EmbreeScene {
  public:
    // threads: Embree's worker threads for the build (0: its default).
    explicit EmbreeScene(const Scene& s, int threads = 0) {
        device_ =
            rtcNewDevice(threads > 0 ? ("threads=" + std::to_string(threads)).c_str() : nullptr);
        const auto t0 = std::chrono::steady_clock::now();
        scene_ = mesh_scene(device_, s);
        build_seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    ~EmbreeScene() {
        rtcReleaseScene(scene_);
        rtcReleaseDevice(device_);
    }
    EmbreeScene(const EmbreeScene&) = delete;
    EmbreeScene& operator=(const EmbreeScene&) = delete;

    Hit intersect(const Ray& r) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRayHit rh{};
        fill(rh.ray, r);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene_, &ctx, &rh);
        Hit h;
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return h;
        h.t = rh.ray.tfar;
        h.prim = rh.hit.primID;
        h.u = rh.hit.u;
        h.v = rh.hit.v;
        return h;
    }
    bool occluded(const Ray& r) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRay ray{};
        fill(ray, r);
        rtcOccluded1(scene_, &ctx, &ray);
        return ray.tfar ==
               -std::numeric_limits<float>::infinity();  // Embree marks a blocked ray so
    }

    double build_seconds = 0;

  private:
    // Embree's any-hit callback: a candidate the alpha mask (the geometry's user data) does
    // not accept is rejected, and traversal goes on.
    static void alpha_filter(const RTCFilterFunctionNArguments* args) {
        const auto* alpha = static_cast<const AlphaMask*>(args->geometryUserPtr);
        for (unsigned i = 0; i < args->N; ++i) {
            if (args->valid[i] != -1) continue;
            const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
            if (!alpha->accepts(prim, RTCHitN_u(args->hit, args->N, i),
                                RTCHitN_v(args->hit, args->N, i)))
                args->valid[i] = 0;
        }
    }
    // A committed Embree scene of one triangle geometry holding the mesh; with `alpha`, its
    // candidates go through alpha_filter for both closest-hit and occlusion queries.
    static RTCScene mesh_scene(RTCDevice device, const Scene& s, const AlphaMask* alpha = nullptr) {
        RTCScene scene = rtcNewScene(device);
        RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
            g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, s.vertices.size()));
        std::memcpy(v, s.vertices.data(), s.vertices.size() * 12);
        auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
            g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, s.triangles.size()));
        std::memcpy(idx, s.triangles.data(), s.triangles.size() * 12);
        if (alpha) {
            rtcSetGeometryUserData(g, const_cast<AlphaMask*>(alpha));
            rtcSetGeometryIntersectFilterFunction(g, alpha_filter);
            rtcSetGeometryOccludedFilterFunction(g, alpha_filter);
        }
        rtcCommitGeometry(g);
        rtcAttachGeometry(scene, g);
        rtcReleaseGeometry(g);
        rtcCommitScene(scene);
        return scene;
    }
    static void fill(RTCRay& e, const Ray& r) {
        e.org_x = r.org.x;
        e.org_y = r.org.y;
        e.org_z = r.org.z;
        e.dir_x = r.dir.x;
        e.dir_y = r.dir.y;
        e.dir_z = r.dir.z;
        e.tnear = r.tmin;
        e.tfar = r.tmax;
        e.mask =
            0xFFFFFFFFu;  // Debian's Embree is built with ray masks: without this every ray misses
        e.flags = 0;
        e.time = 0;
    }
    RTCDevice device_;
    RTCScene scene_;
    friend class EmbreeInstancedScene;
};

// The same through Embree's instancing API: one Embree scene per mesh, and a top scene of
// instance geometries (geometry id = instance id) with each instance's row-major 3x4 transform
// and mask. A non-opaque instance uses a second scene of its mesh whose geometry has an
// intersection filter (Embree's any-hit callback) that rejects what the mesh's alpha mask
// rejects, at Embree's own barycentrics.
class EmbreeInstancedScene {
  public:
    explicit EmbreeInstancedScene(const InstancedScene& s) {
        device_ = rtcNewDevice(nullptr);
        alpha_.reserve(s.meshes.size());  // filters keep pointers to these
        for (uint32_t m = 0; m < s.meshes.size(); ++m) {
            meshes_.push_back(EmbreeScene::mesh_scene(device_, s.meshes[m]));
            alpha_.push_back(s.mesh_alpha(m));
            filtered_.push_back(EmbreeScene::mesh_scene(device_, s.meshes[m], &alpha_.back()));
        }
        top_ = rtcNewScene(device_);
        for (size_t k = 0; k < s.instances.size(); ++k) {
            const Instance& inst = s.instances[k];
            RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
            rtcSetGeometryInstancedScene(g,
                                         inst.opaque ? meshes_[inst.mesh] : filtered_[inst.mesh]);
            rtcSetGeometryTimeStepCount(g, 1);
            rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR,
                                    inst.object_to_world.m.data());
            rtcSetGeometryMask(g, inst.mask);
            rtcCommitGeometry(g);
            rtcAttachGeometryByID(top_, g, unsigned(k));
            rtcReleaseGeometry(g);
        }
        rtcCommitScene(top_);
    }
    ~EmbreeInstancedScene() {
        rtcReleaseScene(top_);
        for (RTCScene m : meshes_) rtcReleaseScene(m);
        for (RTCScene m : filtered_) rtcReleaseScene(m);
        rtcReleaseDevice(device_);
    }
    EmbreeInstancedScene(const EmbreeInstancedScene&) = delete;
    EmbreeInstancedScene& operator=(const EmbreeInstancedScene&) = delete;

    // The hit and, in `instance`, the instance hit (kNoInstance on a miss).
    Hit intersect(const Ray& r, uint32_t& instance, unsigned mask = 0xFFFFFFFFu) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRayHit rh{};
        EmbreeScene::fill(rh.ray, r);
        rh.ray.mask = mask;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(top_, &ctx, &rh);
        Hit h;
        instance = kNoInstance;
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return h;
        h.t = rh.ray.tfar;
        h.prim = rh.hit.primID;
        h.u = rh.hit.u;
        h.v = rh.hit.v;
        instance = rh.hit.instID[0];
        return h;
    }
    bool occluded(const Ray& r, unsigned mask = 0xFFFFFFFFu) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRay ray{};
        EmbreeScene::fill(ray, r);
        ray.mask = mask;
        rtcOccluded1(top_, &ctx, &ray);
        return ray.tfar == -std::numeric_limits<float>::infinity();
    }

  private:
    RTCDevice device_;
    std::vector<RTCScene> meshes_, filtered_;
    std::vector<AlphaMask> alpha_;
    RTCScene top_;
};

}  // namespace rtsim::test

// Functional BVH2/4/8 traversal: what each ray does (which nodes and triangles, in which order,
// what it hits). The timing model decides when; this file never knows about cycles.
#pragma once

#include <cstdint>
#include <vector>

#include "workloads/bvh.h"
#include "workloads/geometry.h"
#include "workloads/scene.h"
#include "workloads/step.h"

namespace rtsim {

enum class HitQuery : uint8_t {
    Closest,  // nearest intersection (primary, reflection, diffuse rays)
    Any,      // first intersection found, early exit (shadow and AO rays)
};

struct TraceCounters {
    uint32_t nodes = 0, box_tests = 0, tri_tests = 0, max_stack = 0;
    uint32_t any_hits = 0;  // any-hit shader calls (candidate hits on non-opaque instances)
};

// Traces one ray. steps (optional) receives the ordered step stream; counters (optional) the
// per-ray work. A ray that misses the root box costs one box test and records no step: the root
// box is kept on chip.
Hit trace_ray(const Bvh& bvh, const Ray& ray, HitQuery query, std::vector<Step>* steps = nullptr,
              TraceCounters* counters = nullptr);

// trace_ray with its steps left in `steps` (replaced), sized to fit: they grow in a buffer kept
// per thread and are copied once, where growing each ray's own vector reallocated it about
// seven times (5% of a full run's host time).
Hit trace_ray_recorded(const Bvh& bvh, const Ray& ray, HitQuery query, std::vector<Step>& steps);

// Continues one ray's traversal inside the subtree below a child reference (a wide node's
// child[l] and count[l]), keeping the better of `hit` and what it finds there. Packet traversal
// uses it to finish rays one by one: `hit.t` must be the ray's current bound (tmax, or the best
// hit's t), and stays so if nothing nearer is found. Adds the work to `counters`.
void trace_subtree(const Bvh& bvh, const Ray& ray, HitQuery query, uint32_t child, uint32_t count,
                   Hit& hit, TraceCounters& counters);

}  // namespace rtsim

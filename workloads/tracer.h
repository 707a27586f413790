// Functional BVH2 traversal: what each ray does (which nodes and triangles, in which order, what
// it hits). The timing model decides when; this file never knows about cycles.
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
};

// Traces one ray. steps (optional) receives the ordered step stream; counters (optional) the
// per-ray work. A ray that misses the root box costs one box test and records no step: the root
// box is kept on chip.
Hit trace_ray(const Bvh& bvh, const Ray& ray, HitQuery query, std::vector<Step>* steps = nullptr,
              TraceCounters* counters = nullptr);

}  // namespace rtsim

// The per-ray step stream: the contract between the functional tracer (what a ray does) and the
// timing models (when it happens). Self-contained, so models can use it without knowing scenes.
#pragma once

#include <cstdint>
#include <vector>

namespace rtsim {

// One traversal step as the hardware sees it: what it fetches and which unit tests it. Every
// per-kind table (a core's memories, units, instructions and stall causes, the chip's units,
// the trace decoder's records) is sized by kStepKinds. Adding a kind (a ray-sphere or an
// instance-transform unit) is local: a value here, its row of kStepKindInfo (below),
// its records in the BVH layout, and its unit's schema section and binding rows.
enum class StepKind : uint8_t {
    Node = 0,       // fetch an inner-node record, then one box test of `count` child boxes
    Triangle = 1,   // fetch one triangle, then one ray-triangle test (`count` 1)
    Transform = 2,  // fetch an instance record, then move the ray into the instance's object
                    // space (two-level scenes, workloads/instances.h; `count` 1)
    AnyHit = 3,     // a candidate hit on non-opaque geometry handed back to the core: its any-hit
                    // shader's instructions, its read of the triangle's alpha data (none when the
                    // record is 0 bytes), and the shader's latency (workloads/alpha.h; `count` 1)
};
constexpr int kStepKinds = 4;

struct StepKindInfo {
    const char* name;  // "node"
    // The unit kind that tests it, as configs and stats name it ("box_unit": the config section
    // box_unit, the blocks box_unit[i], the stall cause box_unit).
    const char* unit;
};
// Per StepKind, in order (models use it too, so it lives here, not in a library).
inline constexpr StepKindInfo kStepKindInfo[kStepKinds] = {
    {"node", "box_unit"},
    {"triangle", "triangle_unit"},
    {"transform", "transform_unit"},
    {"any_hit", "any_hit_shader"},
};
constexpr const StepKindInfo& step_kind_info(StepKind kind) {
    return kStepKindInfo[int(kind)];
}
constexpr const StepKindInfo& step_kind_info(int kind) {
    return kStepKindInfo[kind];
}

struct Step {
    uint64_t addr;        // byte address in the BVH layout
    uint32_t id;          // inner-node record index, leaf slot of the triangle, or instance record
    uint16_t size_bytes;  // bytes fetched
    StepKind kind;
    uint8_t count;         // items the unit tests: a node's child boxes, 1 for a triangle
    uint32_t treelet = 0;  // treelet of the record (0 when the layout has no treelets)
    uint8_t lanes = 1;     // rays of a packet that take part (1 for a single ray)
    // The ray's traversal stack when the step is fetched (models size short stacks by it):
    // bits 0-6 its entries (saturated at kStackDepthMax), bit 7 set when the step's node or
    // leaf came off the stack (popped) rather than by descending to the nearest child.
    // 0 in packet traces and traces older than version 3 (no stack recorded).
    uint8_t stack = 0;
};
constexpr unsigned kStackDepthMax = 127;
constexpr uint8_t kStackPopped = 0x80;
constexpr uint8_t stack_byte(unsigned depth, bool popped) {
    return uint8_t((depth < kStackDepthMax ? depth : kStackDepthMax) | (popped ? kStackPopped : 0));
}
constexpr unsigned stack_depth(const Step& s) {
    return s.stack & kStackDepthMax;
}
constexpr bool stack_popped(const Step& s) {
    return (s.stack & kStackPopped) != 0;
}
static_assert(sizeof(Step) == 24, "Step is streamed in bulk; keep it small");

enum class RayKind : uint8_t { Primary = 0, Shadow = 1, AO = 2, Diffuse = 3, Reflection = 4 };
constexpr int kRayKindCount = 5;
const char* ray_kind_name(RayKind k);

// One ray's work for the timing model (or one packet's: `rays` rays in lockstep, each step
// with its active lanes).
struct RayWork {
    uint32_t ray_id = 0;
    RayKind kind = RayKind::Primary;
    uint8_t rays = 1;
    std::vector<Step> steps;
};

}  // namespace rtsim

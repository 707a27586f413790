// The any-hit shader: a candidate hit on non-opaque geometry (workloads/alpha.h) handed back to
// the core, which runs the shader (its instructions, core.any_hit_step_instructions, take the
// core's issue slots like traversal control; its read of the triangle's alpha data goes through
// the L1) and has its verdict this unit's latency later. A unit per core by default: the
// shader's pipeline on the core that runs it. Opaque geometry never calls it.
#include "models/unit_kind.h"

namespace rtsim {

RTSIM_REGISTER(UnitKindEntry,
               {"any_hit_shader",
                "any-hit shader calls on candidate hits of non-opaque geometry, one per pipelined "
                "operation",
                {"count", "shared_by", "latency_cycles", "interval_cycles", "alpha_read_bytes"},
                StepKind::AnyHit})

}  // namespace rtsim

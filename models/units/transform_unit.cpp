// The instance-transform unit: moves a ray into an instance's object space when traversal of a
// two-level scene leaves the top-level BVH (workloads/instances.h), one 3x4 matrix applied to
// the ray's origin and direction per pipelined operation. One-level scenes have no such step.
#include "models/unit_kind.h"

namespace rtsim {

RTSIM_REGISTER(UnitKindEntry,
               {"transform_unit",
                "instance transforms of a ray into object space, one per pipelined operation",
                {"count", "shared_by", "latency_cycles", "interval_cycles"},
                StepKind::Transform})

}  // namespace rtsim

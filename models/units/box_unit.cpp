// The ray-box unit: tests a ray against a node's child boxes, `width` boxes per operation (the
// slab test; Ize 2013's conservative rounding in the functional model).
#include "models/unit_kind.h"

namespace rtsim {

RTSIM_REGISTER(UnitKindEntry,
               {"box_unit",
                "ray-box tests of a node's child boxes, width boxes per pipelined operation",
                {"count", "shared_by", "width", "latency_cycles", "interval_cycles"},
                StepKind::Node})

}  // namespace rtsim

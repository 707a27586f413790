// The ray-box unit: tests a ray against a node's child boxes, `width` boxes per operation (the
// slab test: Ize 2013's conservative rounding in fp32, or a reduced-precision datapath that
// rounds outwards, workloads/reduced_box.h). Its precision decides which nodes rays visit, so it
// acts through the functional trace; the timing here is per operation whatever the precision.
#include "models/unit_kind.h"

namespace rtsim {

RTSIM_REGISTER(UnitKindEntry,
               {"box_unit",
                "ray-box tests of a node's child boxes, width boxes per pipelined operation",
                {"count", "shared_by", "width", "latency_cycles", "interval_cycles",
                 "mantissa_bits", "translate_origin"},
                StepKind::Node})

}  // namespace rtsim

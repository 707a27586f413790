// The ray-triangle unit: one watertight ray-triangle test (Woop, Benthin & Wald 2013) per
// pipelined operation.
#include "models/unit_kind.h"

namespace rtsim {

RTSIM_REGISTER(UnitKindEntry, {"triangle_unit",
                               "watertight ray-triangle tests, one per pipelined operation",
                               {"count", "shared_by", "latency_cycles", "interval_cycles"},
                               StepKind::Triangle})

}  // namespace rtsim

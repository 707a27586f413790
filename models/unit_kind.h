// Unit kinds, registered by name (`rtsim list`): the fixed-function units that test a step kind.
// Each is a PipelinedUnit configured by the schema section of its name; kStepKindInfo
// (workloads/step.h) says which step kind it tests. One file each under models/units/.
#pragma once

#include <string>
#include <vector>

#include "models/registry.h"
#include "workloads/step.h"

namespace rtsim {

struct UnitKindEntry {
    static constexpr const char* kKind = "unit_kind";
    std::string name, description;
    std::vector<std::string> params;  // fields of its schema section
    StepKind tests = StepKind::Node;  // the step kind it tests
};
using UnitKindRegistry = Registry<UnitKindEntry>;

}  // namespace rtsim

// Matched differences between two sampled runs of one frame that measured the same units (the
// same sample seed and design: Ekman and Stenstrom's matched pairs). The difference of a figure
// between the two designs is estimated from each unit's difference, with the runs' own
// estimator (sim/sampling/estimators.h) over the same auxiliaries: units where both designs are
// slow cancel, so a small difference gets a narrow interval that the two runs' separate intervals
// would hide.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/sampling/estimators.h"

namespace rtsim {

struct MatchedDifference {
    std::string figure;   // "cycles", "dram.bytes"
    Estimate difference;  // b's figure less a's, over the frame
    double base = 0;      // a's estimate of the figure
};

// The differences b - a of the frame's cycles and DRAM bytes, from two runs' stats.json and the
// sampled_units.csv beside them. Empty, with `why` saying why, where the runs are not a matched
// pair: not both sampled, different units or frames, or a table missing.
std::vector<MatchedDifference> matched_differences(const nlohmann::json& a,
                                                   const std::filesystem::path& a_dir,
                                                   const nlohmann::json& b,
                                                   const std::filesystem::path& b_dir,
                                                   std::string* why);

}  // namespace rtsim

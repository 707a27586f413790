// A paired run's reference design (rtsim run --reference DIR): the frame's every-unit run in
// DIR and, run as a child process once per plan, that design's sample of the run's own units
// (sim/sampling/reference.h says how the pair is estimated).
#pragma once

#include <nlohmann/json.hpp>

#include "sim/config.h"
#include "sim/run.h"
#include "sim/sampling/frame_profile.h"
#include "sim/sampling/reference.h"
#include "sim/sampling/sampler.h"

namespace rtsim {

// Loads --reference `opt.reference_dir` for this run (config `cfg`, its workload's stats.json
// sections `meta`, its frame `profile`, its plan `sp`), running the reference design's matched
// sample if DIR does not hold it yet. Throws InputError, naming DIR, if it is not a reference
// for this frame in units that divide the run's (they are merged to the run's units). Without an
// order of its own (--sample-order), `sp`'s strata are cut from the units in order of the
// reference's cycles (read_unit_order), balanced on work per cycle (balance_unit_order), before
// the plan is.
Reference load_reference(const RunOptions& opt, const Config& cfg, const nlohmann::json& meta,
                         const FrameProfile& profile, SamplingParams& sp);

}  // namespace rtsim

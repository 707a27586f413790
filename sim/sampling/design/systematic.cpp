// sim.sample_design = systematic: every sim.sample_period_units-th unit from a start (SMARTS's
// design). Running every start gives every sample the design can draw, for the exact coverage of
// its intervals.
#include "sim/sampling/sampler.h"

namespace rtsim {
namespace {
void configure_systematic(SamplingParams& p) {
    p.stratified = false;
    p.by_work = false;
}
}  // namespace

RTSIM_REGISTER(SampleDesignEntry,
               {"systematic",
                "every sample_period_units-th unit from a start (sample_first_unit, or drawn)",
                {"sample_period_units", "sample_first_unit", "sample_seed"},
                &configure_systematic})

}  // namespace rtsim

// sim.sample_design = work (with sim.sample_fast_forward = skip): the sample is drawn where the
// frame's profile says the work is. The heaviest units are measured outright (certainty units),
// the rest drawn one per stratum of units of like work, weighted by their design weights
// (SampleDesign::draw_by_work).
#include "sim/sampling/sampler.h"

namespace rtsim {
namespace {
void configure_work(SamplingParams& p) {
    p.stratified = true;
    p.by_work = true;
}
}  // namespace

RTSIM_REGISTER(SampleDesignEntry,
               {"work",
                "where the work is: the heaviest units measured outright, the rest drawn in strata "
                "of like work (needs sample_fast_forward = skip)",
                {"sample_period_units", "sample_seed", "sample_startup_slot_fills"},
                &configure_work,
                true})

}  // namespace rtsim

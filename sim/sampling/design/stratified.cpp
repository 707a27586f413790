// sim.sample_design = stratified (the default): one unit drawn at random in each run of
// sim.sample_period_units units. A fixed stride can alias with the image (1080p rows of 240 tiles
// against a stride of 160 tiles measured 3 column bands); a draw per stratum cannot.
#include "sim/sampling/sampler.h"

namespace rtsim {
namespace {
void configure_stratified(SamplingParams& p) {
    p.stratified = true;
    p.by_work = false;
}
}  // namespace

RTSIM_REGISTER(SampleDesignEntry,
               {"stratified",
                "one unit drawn at random in each run of sample_period_units units",
                {"sample_period_units", "sample_seed"},
                &configure_stratified})

}  // namespace rtsim

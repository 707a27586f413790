// sim.sample_fast_forward = warm: every ray is generated and traced; the ones between measured
// units warm the caches they would have reached (functional warming, as SMARTS does) and never
// reach a core. Units are runs of sim.sample_unit_rays rays; the totals are regressed on what the
// tracer knew of every ray, counted here as the rays go by. Works on trace replays too.
#include "sim/sampling/sampler.h"

namespace rtsim {
namespace {
std::unique_ptr<Sampler> make_warm(const SamplingParams& params, const SampledChip& chip,
                                   const SampledFrame& frame) {
    auto s = std::make_unique<Sampler>(params, chip.ports, *chip.counters, frame.design);
    s->set_write_warming(chip.cores);
    s->set_caches(*chip.l1, *chip.l2, chip.dram_bytes_per_l2_fill);
    s->set_line_range(frame.fetch_begin, frame.fetch_end, chip.l2->params().line_bytes);
    return s;
}
}  // namespace

RTSIM_REGISTER(FastForwardEntry,
               {"warm",
                "every ray traced; between measured units of rays the rays warm the caches "
                "functionally and no core runs them (trace replays sample this way)",
                {"sample_unit_rays", "sample_warmup_rays"},
                false,
                &make_warm})

}  // namespace rtsim

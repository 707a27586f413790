// sim.fidelity = fast (the default): the cores' scheduler of models/core.h.
#include "models/core.h"
#include "models/fidelity.h"

namespace rtsim {
namespace {
std::unique_ptr<ChipDriver> make_fast(const char* module_name, const DriverSetup& setup) {
    return std::make_unique<CoreScheduler>(module_name, setup.cores, setup.wake);
}
}  // namespace

RTSIM_REGISTER(FidelityEntry,
               {"fast",
                "ray slots run in tight loops against the blocks' calendars; a request's path "
                "through the memory levels is computed when it is issued (error against accurate: "
                "bench/results/fidelity.md)",
                {},
                &make_fast})

// The same cores, fed a systematic sample of the rays (sim/sampler.h, attached by the run).
RTSIM_REGISTER(FidelityEntry,
               {"sampled",
                "the fast model on one unit of rays in sim.sample_period_units, the rest "
                "fast-forwarded with functional cache warming; totals estimated with 95% "
                "confidence intervals (stats.json sampling)",
                {"sample_unit_rays", "sample_period_units", "sample_warmup_rays",
                 "sample_fast_forward", "sample_unit_tiles", "sample_warm_tiles",
                 "sample_warmup_tiles", "sample_warmup_tile_rays", "sample_paired_unit_tiles",
                 "sample_paired_warmup_tiles", "sample_paired_warmup_tile_rays",
                 "sample_warmup_slot_fills", "sample_paired_warmup_slot_fills"},
                &make_fast})

}  // namespace rtsim

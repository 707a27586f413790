// sim.sample_fast_forward = skip: units are groups of image tiles, and a tile far from a measured
// unit is never generated or traced. The frame's profile (sim/sampling/frame_profile.h, one
// functional pass, cached) gives every unit's auxiliaries and each skipped tile's lines, which
// are loaded into the caches where the tile would have run.
#include "sim/sampling/sampler.h"

namespace rtsim {
namespace {
std::unique_ptr<Sampler> make_skip(const SamplingParams& params, const SampledChip& chip,
                                   const SampledFrame& frame) {
    auto s = std::make_unique<Sampler>(params, chip.ports, *chip.counters, frame.design);
    s->set_write_warming(chip.cores);
    if (frame.reference) s->set_reference(frame.reference);
    s->set_caches(*chip.l1, *chip.l2, chip.dram_bytes_per_l2_fill);
    s->set_l1s_over_l2(chip.l1s_over_l2);
    s->set_profile(frame.profile, chip.l2, frame.cache_dir);
    return s;
}
}  // namespace

RTSIM_REGISTER(FastForwardEntry,
               {"skip",
                "units of image tiles; tiles far from a measured unit are never traced, and the "
                "frame's cached profile stands in for them (needs rays generated on the fly)",
                {"sample_unit_tiles", "sample_warm_tiles", "sample_warmup_tiles",
                 "sample_warmup_tile_rays", "sample_warmup_slot_fills", "sample_unit_slot_fills",
                 "sample_paired_unit_tiles", "sample_paired_warmup_tiles",
                 "sample_paired_warmup_tile_rays", "sample_paired_warmup_slot_fills"},
                true,
                &make_skip})

}  // namespace rtsim

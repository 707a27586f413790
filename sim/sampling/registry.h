// The parts of sampled simulation that are chosen by name (docs/extending.md): fast-forward
// layers (sim.sample_fast_forward) and sample designs (sim.sample_design), one file each in
// sim/sampling/fast_forward/ and sim/sampling/design/. Config checks need only this header.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "models/registry.h"

namespace rtsim {

struct SamplingParams;  // sim/sampling/sampler.h
class Sampler;
struct SampledChip;
struct SampledFrame;

// Sampling layers, registered by what becomes of the work between measured units
// (sim.sample_fast_forward; `rtsim list fast_forward`): each builds its sampler over a chip.
struct FastForwardEntry {
    static constexpr const char* kKind = "fast_forward";
    std::string name, description;
    std::vector<std::string> params;
    // True when the layer needs the frame's profile (units of tiles, generated on the fly).
    bool needs_profile = false;
    std::unique_ptr<Sampler> (*make)(const SamplingParams&, const SampledChip&,
                                     const SampledFrame&) = nullptr;
};
using FastForwardRegistry = Registry<FastForwardEntry>;

// Sample designs, registered by name (sim.sample_design; `rtsim list sample_design`): which
// units are measured. `configure` sets the plan's choice of units.
struct SampleDesignEntry {
    static constexpr const char* kKind = "sample_design";
    std::string name, description;
    std::vector<std::string> params;
    void (*configure)(SamplingParams&) = nullptr;
    // True when the design draws from the frame's profile (sim.sample_fast_forward = skip).
    bool needs_profile = false;
};
using SampleDesignRegistry = Registry<SampleDesignEntry>;

// The sampler sim.sample_fast_forward names, over `chip`, for `frame`.
std::unique_ptr<Sampler> make_sampler(const std::string& fast_forward, const SamplingParams& params,
                                      const SampledChip& chip, const SampledFrame& frame);

}  // namespace rtsim

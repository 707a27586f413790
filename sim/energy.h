// stats.json's "energy" section: each block's energy from its counters and a cost
// per access or operation (energy.*, defaults from public sources named in the schema), DRAM's
// from the command-level model's currents when it ran, the total, energy per ray and average
// power. A sampled run's blocks use its estimated totals.
#pragma once

#include <nlohmann/json.hpp>

#include "sim/params.h"
#include "sim/sampling/estimators.h"

namespace rtsim {

// Energy of a 64-bit access to an SRAM of `bytes`: the three stated sizes' energies
// interpolated (and extrapolated) linearly in log size.
double sram_word_pj(const EnergyParams& e, double bytes);

// The section, from a finished run's stats (its counters, bandwidth and sampling sections).
nlohmann::json energy_report(const Params& P, const nlohmann::json& stats);

// A sampled run's energy figures with their intervals (stats.json's sampling.energy: total_pj,
// per_ray_nj, average_power_w and blocks_pj, each value, lo, hi, half_width_pct): the model
// above over the counters' estimates (`stats` already holds its energy section from them), its
// interval from their joint jackknife (JointEstimates; "cycles" gives the seconds at
// `clock_hz`).
nlohmann::json sampled_energy(const Params& P, const nlohmann::json& stats,
                              const JointEstimates& joint, double clock_hz);

}  // namespace rtsim

// The fast engine's judgement of its own run: which regimes the run sits in where the fast engine
// is known to stray from the time-ordered reference, and how far runs there strayed.
//
// The regimes and their bounds were measured with `scripts/bench_fidelity.py --random 300 --seed
// 1001` (random configs on 10 meshes against sim.fidelity = accurate; the tuning set) and are
// checked on configs drawn fresh (bench/results/fidelity_random.md):
//   treelet_loads   treelet mode with treelet loads (traversal.treelet_prefetch): the loaders'
//                   lines and the slots' misses meet at the MSHRs in another order (seeds
//                   1001-1003, after both engines' loaders came to wait alike for an MSHR: 83
//                   runs, 59 over 1%, median 2.3%, 95th percentile 18%).
//   l1_bound        L1 stalls above 40% of slot cycles: slots waiting on few MSHRs (106 runs,
//                   95th percentile 14%).
//   crossbar_bound  the crossbar busy above 30% of cycles: transfers booked when issued, not in
//                   time order (55 runs, 95th percentile 16%).
//   command_dram_writes  command-level DRAM (dram.model = command) with write requests at the
//                   L2 (seed 1001 again, after later fixes: 14 runs, 95th percentile 11%; 3 of
//                   the 8 outside the regimes above were over 1%).
//   memory_path_order  blocks in the memory path (memory_path.*) that met over 1% of their
//                   requests out of time order (`--random 80 --seed 388002`, the blocks' tuning
//                   seed: 1 run, 14%; the other 34 runs with a block met at most 0.2%. On the
//                   fresh seed 57783, 3 of 47 runs with a block were in it, 1 over 1%).
// Runs in none of them: 139 of 146 within 1%, 95th percentile 0.97% (before the fourth regime).
#pragma once

#include <nlohmann/json.hpp>

#include "sim/params.h"

namespace rtsim {

// stats.json's "fidelity_check" for a run of `params` whose report is `out` (its stalls,
// counters and total_cycles): {engine, regimes: [{name, measure, threshold, expected_error_pct}],
// expected_error_pct, flagged, note}. For the accurate engine: {engine, reference: true}.
nlohmann::json fidelity_check(const Params& params, const nlohmann::json& out);

}  // namespace rtsim

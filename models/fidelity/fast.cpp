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

}  // namespace rtsim

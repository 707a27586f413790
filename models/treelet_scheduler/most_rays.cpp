// Most rays: the treelet with the most queued rays (ties: the lowest id), so a treelet's load is
// shared by as many rays as possible. It may starve a treelet with few rays while others fill.
#include <limits>
#include <set>
#include <utility>

#include "models/treelet_scheduler.h"

namespace rtsim {
namespace {

class MostRays final : public TreeletScheduler {
  public:
    explicit MostRays(const TreeletSchedulerParams&) {}
    void changed(uint32_t treelet, size_t before, size_t after, uint64_t) override {
        if (before) by_count_.erase({kMax - before, treelet});
        if (after) by_count_.insert({kMax - after, treelet});
    }
    bool pick(uint32_t& treelet) override {
        if (by_count_.empty()) return false;
        treelet = by_count_.begin()->second;
        return true;
    }

  private:
    static constexpr size_t kMax = std::numeric_limits<size_t>::max();
    std::set<std::pair<size_t, uint32_t>> by_count_;  // (kMax - count, id): the first has most
};

}  // namespace

RTSIM_REGISTER(TreeletSchedulerEntry, {"most_rays",
                                       "the treelet with the most queued rays (ties: lowest id)",
                                       {},
                                       &make_treelet_scheduler<MostRays>})

}  // namespace rtsim

// Round robin: the next treelet with queued rays after the one picked last (wrapping), so every
// treelet with rays is served within one round of the others.
#include <set>

#include "models/treelet_scheduler.h"

namespace rtsim {
namespace {

class RoundRobin final : public TreeletScheduler {
  public:
    explicit RoundRobin(const TreeletSchedulerParams&) {}
    void changed(uint32_t treelet, size_t before, size_t after, uint64_t) override {
        if (before && !after) nonempty_.erase(treelet);
        if (!before && after) nonempty_.insert(treelet);
    }
    bool pick(uint32_t& treelet) override {
        if (nonempty_.empty()) return false;
        auto it = nonempty_.upper_bound(last_);
        treelet = last_ = it != nonempty_.end() ? *it : *nonempty_.begin();
        return true;
    }

  private:
    std::set<uint32_t> nonempty_;
    uint32_t last_ = 0;  // the treelet picked last (initially 0)
};

}  // namespace

RTSIM_REGISTER(TreeletSchedulerEntry,
               {"round_robin",
                "the next treelet with queued rays after the one picked last",
                {},
                &make_treelet_scheduler<RoundRobin>})

}  // namespace rtsim

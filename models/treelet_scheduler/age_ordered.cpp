// Age ordered: the most-rays choice (a treelet's load shared by many rays) with a bound on
// starvation. The oldest queued ray (the one queued first among all waiting) may be passed over
// by at most `max_wait_batches` batches; the next batch then comes from its treelet. So the
// oldest ray leaves within max_wait_batches + 1 batches, and a ray with k older rays waiting
// leaves within (k + 1) * (max_wait_batches + 1) batches; 0 serves rays strictly oldest first.
#include <limits>
#include <set>
#include <utility>

#include "models/treelet_scheduler.h"

namespace rtsim {
namespace {

class AgeOrdered final : public TreeletScheduler {
  public:
    explicit AgeOrdered(const TreeletSchedulerParams& p) : max_wait_(p.max_wait_batches) {}
    void changed(uint32_t treelet, size_t before, size_t after, uint64_t front_seq) override {
        if (before) {
            by_count_.erase({kMax - before, treelet});
            by_age_.erase({front_[treelet], treelet});
        }
        if (after) {
            by_count_.insert({kMax - after, treelet});
            if (front_.size() <= treelet) front_.resize(treelet + 1);
            front_[treelet] = front_seq;
            by_age_.insert({front_seq, treelet});
        }
    }
    bool pick(uint32_t& treelet) override {
        if (by_count_.empty()) return false;
        const auto [oldest_seq, oldest_treelet] = *by_age_.begin();
        if (oldest_seq != waiting_seq_) {  // a new oldest ray: it has not been passed over yet
            waiting_seq_ = oldest_seq;
            passed_over_ = 0;
        }
        treelet = passed_over_ >= max_wait_ ? oldest_treelet : by_count_.begin()->second;
        passed_over_ += treelet != oldest_treelet;
        return true;
    }

  private:
    static constexpr size_t kMax = std::numeric_limits<size_t>::max();
    uint32_t max_wait_;
    std::set<std::pair<size_t, uint32_t>> by_count_;  // (kMax - count, id): the first has most
    std::set<std::pair<uint64_t, uint32_t>> by_age_;  // (front ray's seq, id): the first is oldest
    std::vector<uint64_t> front_;                     // per treelet: its front ray's seq
    uint64_t waiting_seq_ = std::numeric_limits<uint64_t>::max();  // the oldest ray last seen
    uint32_t passed_over_ = 0;                                     // batches that passed it over
};

}  // namespace

RTSIM_REGISTER(TreeletSchedulerEntry, {"age_ordered",
                                       "most queued rays, but the oldest queued ray waits at most "
                                       "treelet_max_wait_batches batches (bounded starvation)",
                                       {"treelet_max_wait_batches"},
                                       &make_treelet_scheduler<AgeOrdered>})

}  // namespace rtsim

// Treelet schedulers: which treelet's queued rays a core gets next from the ray buffer. One file
// each under models/treelet_scheduler/, registered by name (traversal.treelet_scheduler). A
// scheduler is asked once per batch, so it is a virtual interface.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "models/registry.h"

namespace rtsim {

class TreeletScheduler {
  public:
    virtual ~TreeletScheduler() = default;
    // Treelet `treelet`'s queue went from `before` to `after` rays (one of them may be zero);
    // `front_seq` is the queueing order of its front ray (rays are numbered as they are queued,
    // so a smaller number waited longer); meaningless when `after` is 0.
    virtual void changed(uint32_t treelet, size_t before, size_t after, uint64_t front_seq) = 0;
    // The treelet whose rays go next; false when no treelet has queued rays. Called once per
    // batch, which then leaves that treelet's queue (and is reported through changed()).
    virtual bool pick(uint32_t& treelet) = 0;
};

// What a scheduler may be configured with.
struct TreeletSchedulerParams {
    uint32_t treelets = 1;
    uint32_t max_wait_batches = 0;  // age_ordered: batches the oldest ray may be passed over
};

struct TreeletSchedulerEntry {
    static constexpr const char* kKind = "treelet_scheduler";
    std::string name, description;
    std::vector<std::string> params;
    std::unique_ptr<TreeletScheduler> (*make)(const TreeletSchedulerParams&) = nullptr;
};
using TreeletSchedulerRegistry = Registry<TreeletSchedulerEntry>;

// The factory of a scheduler whose constructor takes the params.
template <typename S>
std::unique_ptr<TreeletScheduler> make_treelet_scheduler(const TreeletSchedulerParams& p) {
    return std::make_unique<S>(p);
}

}  // namespace rtsim

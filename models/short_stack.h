// A ray's traversal stack as hardware keeps it: the top `entries` on chip (a short stack), the
// rest spilled to memory. The functional tracer records the stack's depth at every step and
// whether the step's node or leaf was popped (Step::stack); this replays those depths against
// the short stack and says what memory traffic each step causes first:
// - pushes that overflow the short stack write its oldest entries out (one contiguous write);
// - pops that find it empty read entries back, as many as it holds (one contiguous read; the
//   step's fetch waits for it, as the popped entry is the address it fetches).
// Pops of entries a closer hit has culled read them too: hardware must read an entry to find
// its distance. Between two steps only the net change of depth is known, so a push and a pop
// of the same entry cancel; pops past the bottom (a saturated depth) are ignored.
#pragma once

#include <algorithm>
#include <cstdint>

#include "workloads/step.h"

namespace rtsim {

// Where the traversal's own data lives: 16 GiB regions far above any BVH layout (which starts
// at 0), together below 2^36 bytes (the caches' tags are 32 bits): slots' spilled stacks, ray
// records (treelet queues in memory, models/ray_buffer.h) and the rays' hit records. Configs
// that would overrun a region are refused (sim/config.cpp).
constexpr uint64_t kLocalRegionBytes = uint64_t(1) << 34;
constexpr uint64_t kStackRegionBase = uint64_t(1) << 34;
constexpr uint64_t kRayRecordBase = uint64_t(2) << 34;
constexpr uint64_t kHitRecordBase = uint64_t(3) << 34;
constexpr uint64_t kLocalRegionsEnd = uint64_t(4) << 34;

struct StackTraffic {
    uint32_t spill_entries = 0, spill_from = 0;    // written: memory entries [from, from + n)
    uint32_t refill_entries = 0, refill_from = 0;  // read back
    bool any() const { return spill_entries != 0 || refill_entries != 0; }
};

class ShortStack {
  public:
    explicit ShortStack(uint32_t entries = 0) : entries_(entries) {}
    void reset() { on_chip_ = spilled_ = 0; }
    // The traffic before `step` is fetched, and the stack after its pop.
    StackTraffic before(const Step& step) {
        StackTraffic t;
        const uint32_t depth = stack_depth(step), popped = stack_popped(step) ? 1 : 0;
        const uint32_t total = on_chip_ + spilled_;
        const uint32_t pushes = depth + popped > total ? depth + popped - total : 0;
        uint32_t pops = total + pushes - depth;
        on_chip_ += pushes;
        if (on_chip_ > entries_) {
            t.spill_entries = on_chip_ - entries_;
            t.spill_from = spilled_;
            spilled_ += t.spill_entries;
            on_chip_ = entries_;
        }
        if (pops > on_chip_ && spilled_ > 0) {
            // Read back what the pops need, topping the short stack up to full.
            const uint32_t need = std::min(pops - on_chip_, spilled_);
            t.refill_entries = std::min(spilled_, std::max(need, entries_ - on_chip_));
            spilled_ -= t.refill_entries;
            t.refill_from = spilled_;
            on_chip_ += t.refill_entries;
        }
        pops = std::min(pops, on_chip_);
        on_chip_ -= pops;
        return t;
    }
    uint32_t on_chip() const { return on_chip_; }
    uint32_t spilled() const { return spilled_; }

  private:
    uint32_t entries_;
    uint32_t on_chip_ = 0, spilled_ = 0;
};

}  // namespace rtsim

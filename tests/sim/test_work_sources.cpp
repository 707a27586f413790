// The ray source's helper thread (sim/work_sources.h): batches come out in order whatever their
// sizes, the helper fills at most a few ahead, and a batch that fails stops the rays after the
// ones before it.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "sim/work_sources.h"

namespace rtsim {
namespace {

// Batches of the given sizes, ray ids numbered on through them; the fill of batch `fail_at`
// throws as a damaged trace chunk would.
class NumberedBatches : public PrefetchingSource {
  public:
    explicit NumberedBatches(std::vector<size_t> sizes, int fail_at = -1)
        : PrefetchingSource(false, "rays"), sizes_(std::move(sizes)), fail_at_(fail_at) {
        prefetch();
    }
    ~NumberedBatches() override { stop_helper(); }
    std::atomic<int> filled{0};  // batches the helper has filled

  protected:
    void fill(Batch& b) override {
        const size_t k = next_++;
        if (int(k) == fail_at_) throw InputError("batch " + std::to_string(k) + " is damaged");
        b.records.resize(sizes_[k]);
        for (TraceRecord& r : b.records) {
            r.ray_id = id_++;
            r.steps.assign(1, Step{});
        }
        b.last = next_ == sizes_.size();
        ++filled;
    }

  private:
    std::vector<size_t> sizes_;
    int fail_at_;
    size_t next_ = 0;  // fill's, on the helper thread
    uint32_t id_ = 0;
};

std::vector<uint32_t> drain(NumberedBatches& source) {
    std::vector<uint32_t> ids;
    RayWork work;
    while (source.next(work, 0)) ids.push_back(work.ray_id);
    return ids;
}

TEST(WorkSources, RaysComeInOrderWhateverTheBatchSizes) {
    // Empty batches between others, single rays, and more batches than the helper fills ahead.
    const std::vector<size_t> sizes{2, 0, 5, 1, 7, 0, 3, 4, 1};
    NumberedBatches source(sizes);
    const std::vector<uint32_t> ids = drain(source);
    ASSERT_EQ(ids.size(), 23u);
    for (uint32_t i = 0; i < ids.size(); ++i) EXPECT_EQ(ids[i], i);
    RayWork work;
    EXPECT_FALSE(source.next(work, 0));  // and stays done
    EXPECT_FALSE(source.failed());
    EXPECT_EQ(source.filled.load(), int(sizes.size()));
}

TEST(WorkSources, TheHelperFillsAFewBatchesAheadNotAll) {
    NumberedBatches source(std::vector<size_t>(20, 4));
    // Untouched, the helper fills up to three batches and then waits for the simulation.
    for (int tries = 0; tries < 2000 && source.filled.load() < 3; ++tries)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_EQ(source.filled.load(), 3);
    // Taking the first ray takes a batch: the helper fills one more.
    RayWork work;
    ASSERT_TRUE(source.next(work, 0));
    EXPECT_EQ(work.ray_id, 0u);
    for (int tries = 0; tries < 2000 && source.filled.load() < 4; ++tries)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_EQ(source.filled.load(), 4);
}

TEST(WorkSources, AFailedBatchStopsTheRaysAfterTheOnesBefore) {
    NumberedBatches source(std::vector<size_t>(6, 4), /*fail_at=*/3);
    const std::vector<uint32_t> ids = drain(source);
    ASSERT_EQ(ids.size(), 12u);  // batches 0-2
    EXPECT_EQ(ids.back(), 11u);
    EXPECT_TRUE(source.failed());
    EXPECT_TRUE(source.failure_is_input);
    EXPECT_EQ(source.failure, "batch 3 is damaged");
    RayWork work;
    EXPECT_FALSE(source.next(work, 0));
}

}  // namespace
}  // namespace rtsim

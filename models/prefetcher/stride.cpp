// Stride prefetching over the cache's miss stream (one stream per cache: requests carry no
// instruction address to tell streams apart). Two consecutive misses the same distance apart,
// that distance at most kMaxStrideLines lines, confirm a stride D; while it holds, a miss of
// line L fetches L + D ... L + degree * D. A different distance re-trains it.
#include <cstdlib>

#include "models/prefetcher.h"

namespace rtsim {
namespace {

class Stride final : public Prefetcher {
  public:
    // Farther strides are more likely two unrelated misses than a stream.
    static constexpr int64_t kMaxStrideLines = 64;

    explicit Stride(const PrefetcherParams& p) : degree_(p.degree) {}
    void on_miss(uint64_t line, std::vector<uint64_t>& out) override {
        const int64_t delta = int64_t(line - last_line_);
        const bool confirmed =
            seen_ && delta != 0 && delta == last_delta_ && std::llabs(delta) <= kMaxStrideLines;
        if (confirmed)
            for (int64_t k = 1; k <= degree_; ++k) {
                const int64_t ahead = int64_t(line) + k * delta;
                if (ahead >= 0) out.push_back(uint64_t(ahead));
            }
        if (seen_) last_delta_ = delta;
        last_line_ = line;
        seen_ = true;
    }

  private:
    int64_t degree_;
    bool seen_ = false;
    uint64_t last_line_ = 0;
    int64_t last_delta_ = 0;
};

std::unique_ptr<Prefetcher> make_stride(const PrefetcherParams& p) {
    return std::make_unique<Stride>(p);
}

}  // namespace

RTSIM_REGISTER(PrefetcherEntry,
               {"stride",
                "two misses the same distance D apart (at most 64 lines) confirm a stride; a miss "
                "of line L then fetches L+D .. L+prefetch_degree*D",
                {"prefetch_degree"},
                &make_stride})

}  // namespace rtsim

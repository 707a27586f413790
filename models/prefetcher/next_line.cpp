// Next-line prefetching: a demand miss of line L fetches L + 1 ... L + degree. BVH layouts put
// a node's children, and a leaf's triangles, in consecutive bytes, so the line after a missed
// one is often the next one a ray asks for.
#include "models/prefetcher.h"

namespace rtsim {
namespace {

class NextLine final : public Prefetcher {
  public:
    explicit NextLine(const PrefetcherParams& p) : degree_(uint64_t(p.degree)) {}
    void on_miss(uint64_t line, std::vector<uint64_t>& out) override {
        for (uint64_t k = 1; k <= degree_; ++k) out.push_back(line + k);
    }

  private:
    uint64_t degree_;
};

std::unique_ptr<Prefetcher> make_next_line(const PrefetcherParams& p) {
    return std::make_unique<NextLine>(p);
}

}  // namespace

RTSIM_REGISTER(PrefetcherEntry, {"next_line",
                                 "a demand miss of line L fetches lines L+1 .. L+prefetch_degree",
                                 {"prefetch_degree"},
                                 &make_next_line})

}  // namespace rtsim

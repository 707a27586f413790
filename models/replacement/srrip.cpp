// Static re-reference interval prediction (Jaleel, Theobald, Steely & Emer, ISCA 2010), SRRIP-HP:
// each way holds an M-bit re-reference prediction value (RRPV, `rrpv_bits`). A filled line is
// predicted to be re-referenced in the distant-but-not-far future (RRPV 2^M - 2), a hit promotes
// it to near-immediate (RRPV 0); the victim is the first way predicted far (RRPV 2^M - 1), all
// ways ageing by one until there is one. Scan-resistant where LRU is not: a sweep of lines used
// once leaves the lines that were hit.
#include "models/cache_impl.h"

namespace rtsim {
namespace {

struct Srrip {
    static uint32_t far(const ReplacementState& s) { return (uint32_t(1) << s.rrpv_bits) - 1; }
    template <int G>
    static void hit(uint32_t* words, int way, ReplacementState&) {
        words[way] = 0;
    }
    template <int G>
    static void filled(uint32_t* words, int way, ReplacementState& s) {
        words[way] = far(s) - 1;
    }
    template <int G>
    static int victim(const uint32_t* tags, uint32_t* words, ReplacementState& s) {
        const int invalid = first_invalid_way<G>(tags, s);
        if (invalid >= 0) return invalid;
        const int ways = ways_of<G>(s);
        // Ageing every way until one reaches `far` is one step: add what the oldest lacks.
        uint32_t oldest = 0;
        for (int w = 0; w < ways; ++w) oldest = std::max(oldest, words[w]);
        const uint32_t age = far(s) - oldest;
        if (age)
            for (int w = 0; w < ways; ++w) words[w] += age;
        int victim = 0;
        while (words[victim] != far(s)) ++victim;
        return victim;
    }
};

}  // namespace

RTSIM_REGISTER(ReplacementEntry,
               {"srrip",
                "static re-reference interval prediction (Jaleel et al. 2010, SRRIP-HP): "
                "scan-resistant, rrpv_bits per way",
                {"rrpv_bits"},
                &Cache::use_policy<Srrip>})

}  // namespace rtsim

// Linked into test binaries that run the rtsim command: the runs they start share a BVH cache in
// the build folder, never the user's own (~/.cache/rtsim), unless the caller chose one.
#include <cstdlib>

namespace {
struct UseTestBvhCache {
    UseTestBvhCache() { setenv("RTSIM_BVH_CACHE", RTSIM_TEST_BVH_CACHE, 0); }
} const kUseTestBvhCache;
}  // namespace

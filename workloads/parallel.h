// Parallel loops over independent items (rays). Work is split into fixed blocks and every item's
// result is written to its own slot, so results are identical for any thread count.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace rtsim {

// Threads to use for `requested` (0: all hardware threads).
inline int resolve_threads(int requested) {
    if (requested > 0) return requested;
    return std::max(1u, std::thread::hardware_concurrency());
}

// Calls body(begin, end) on blocks of [0, n) from `threads` threads. The first exception thrown
// by any block is rethrown after all threads stop.
template <class Body>
void parallel_blocks(size_t n, size_t block, int threads, Body body) {
    if (n == 0) return;
    threads = std::max(1, std::min<int>(threads, int((n + block - 1) / block)));
    if (threads == 1) {
        for (size_t b = 0; b < n; b += block) body(b, std::min(n, b + block));
        return;
    }
    std::atomic<size_t> next{0};
    std::exception_ptr error;
    std::mutex error_mutex;
    auto worker = [&] {
        for (;;) {
            const size_t b = next.fetch_add(block);
            if (b >= n) return;
            try {
                body(b, std::min(n, b + block));
            } catch (...) {
                std::lock_guard<std::mutex> lock(error_mutex);
                if (!error) error = std::current_exception();
                next = n;
            }
        }
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
    if (error) std::rethrow_exception(error);
}

}  // namespace rtsim

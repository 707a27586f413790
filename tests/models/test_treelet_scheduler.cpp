// Treelet schedulers registered by name: each against a brute-force reference that scans every
// queue on every pick, on random queue traffic; the age-ordered scheduler's starvation bound; and
// hand-worked pick orders.
#include <gtest/gtest.h>

#include <deque>
#include <random>
#include <string>
#include <vector>

#include "models/registry.h"
#include "models/treelet_scheduler.h"

using namespace rtsim;

namespace {

// Queues of ray sequence numbers per treelet, driving a scheduler as the ray buffer does.
struct Queues {
    std::vector<std::deque<uint64_t>> q;
    uint64_t next_seq = 0;
    explicit Queues(size_t n) : q(n) {}
    void push(TreeletScheduler& s, uint32_t t) {
        const size_t before = q[t].size();
        q[t].push_back(next_seq++);
        s.changed(t, before, q[t].size(), q[t].front());
    }
    // Takes up to `n` rays of treelet t from the front.
    void take(TreeletScheduler& s, uint32_t t, size_t n) {
        const size_t before = q[t].size();
        for (size_t i = 0; i < n && !q[t].empty(); ++i) q[t].pop_front();
        s.changed(t, before, q[t].size(), q[t].empty() ? 0 : q[t].front());
    }
};

// Brute force: scans every queue.
struct Reference {
    std::string policy;
    uint32_t max_wait;
    uint32_t last = 0;
    uint64_t waiting = ~uint64_t(0);
    uint32_t passed = 0;
    bool pick(const Queues& qs, uint32_t& t) {
        int most = -1, oldest = -1;
        for (size_t k = 0; k < qs.q.size(); ++k) {
            if (qs.q[k].empty()) continue;
            if (most < 0 || qs.q[k].size() > qs.q[size_t(most)].size()) most = int(k);
            if (oldest < 0 || qs.q[k].front() < qs.q[size_t(oldest)].front()) oldest = int(k);
        }
        if (most < 0) return false;
        if (policy == "most_rays") {
            t = uint32_t(most);
        } else if (policy == "round_robin") {
            const size_t n = qs.q.size();
            for (size_t step = 1; step <= n; ++step) {
                const size_t k = (last + step) % n;
                if (!qs.q[k].empty()) {
                    t = last = uint32_t(k);
                    break;
                }
            }
        } else {  // age_ordered
            if (qs.q[size_t(oldest)].front() != waiting) {
                waiting = qs.q[size_t(oldest)].front();
                passed = 0;
            }
            t = passed >= max_wait ? uint32_t(oldest) : uint32_t(most);
            if (t != uint32_t(oldest)) ++passed;
        }
        return true;
    }
};

std::unique_ptr<TreeletScheduler> make(const std::string& name, uint32_t treelets,
                                       uint32_t max_wait = 0) {
    TreeletSchedulerParams p;
    p.treelets = treelets;
    p.max_wait_batches = max_wait;
    return TreeletSchedulerRegistry::at(name).make(p);
}

}  // namespace

TEST(TreeletScheduler, EveryPolicyEqualsBruteForceReference) {
    for (const std::string policy : {"most_rays", "round_robin", "age_ordered"})
        for (uint32_t max_wait : {0u, 1u, 3u, 20u})
            for (uint32_t treelets : {1u, 5u, 40u}) {
                auto s = make(policy, treelets, max_wait);
                Reference ref{policy, max_wait};
                Queues qs(treelets);
                std::mt19937_64 rng(treelets * 131 + max_wait);
                for (int round = 0; round < 3000; ++round) {
                    // Skewed arrivals: low treelets get most rays, as near a BVH's root.
                    for (int a = int(rng() % 6); a-- > 0;)
                        qs.push(*s, uint32_t(rng() % treelets) % (1 + uint32_t(rng() % treelets)));
                    uint32_t got = 999, want = 999;
                    const bool any = s->pick(got);
                    ASSERT_EQ(any, ref.pick(qs, want)) << policy << " round " << round;
                    if (!any) continue;
                    ASSERT_EQ(got, want) << policy << " wait " << max_wait << " treelets "
                                         << treelets << " round " << round;
                    qs.take(*s, got, 1 + rng() % 4);
                }
            }
}

// The bound age_ordered promises: the oldest queued ray is passed over by at most
// max_wait_batches batches, however the traffic is skewed; most_rays has no such bound.
TEST(TreeletScheduler, AgeOrderedBoundsHowLongTheOldestRayIsPassedOver) {
    for (uint32_t max_wait : {0u, 2u, 7u}) {
        auto s = make("age_ordered", 8, max_wait);
        Queues qs(8);
        std::mt19937_64 rng(max_wait);
        uint64_t oldest = ~uint64_t(0);
        uint32_t passed = 0, worst = 0;
        for (int round = 0; round < 20000; ++round) {
            for (int a = int(rng() % 4); a-- > 0;) qs.push(*s, rng() % 5 == 0 ? 7 : 0);
            uint32_t t;
            if (!s->pick(t)) continue;
            uint64_t seq = ~uint64_t(0);
            for (auto& q : qs.q)
                if (!q.empty()) seq = std::min(seq, q.front());
            if (seq != oldest) oldest = seq, passed = 0;
            const bool served = !qs.q[t].empty() && qs.q[t].front() == seq;
            passed = served ? 0 : passed + 1;
            worst = std::max(worst, passed);
            qs.take(*s, t, 2);
        }
        EXPECT_EQ(worst, max_wait) << "the bound is kept, and the traffic reaches it";
    }
}

// Treelet 0 holds one ray; treelet 1 holds three and gets a new ray after every batch of one.
// Worked by hand: most_rays serves treelet 1 for ever; age_ordered with a wait of 2 passes the
// old ray over twice, then serves it; with 0 it serves it first.
TEST(TreeletScheduler, HandWorkedPickOrders) {
    auto order = [](const std::string& policy, uint32_t max_wait) {
        auto s = make(policy, 2, max_wait);
        Queues qs(2);
        qs.push(*s, 0);
        for (int i = 0; i < 3; ++i) qs.push(*s, 1);
        std::vector<uint32_t> picks;
        for (int b = 0; b < 4; ++b) {
            uint32_t t;
            EXPECT_TRUE(s->pick(t));
            picks.push_back(t);
            qs.take(*s, t, 1);
            qs.push(*s, 1);
        }
        return picks;
    };
    EXPECT_EQ(order("most_rays", 0), (std::vector<uint32_t>{1, 1, 1, 1}));
    EXPECT_EQ(order("age_ordered", 2), (std::vector<uint32_t>{1, 1, 0, 1}));
    EXPECT_EQ(order("age_ordered", 0), (std::vector<uint32_t>{0, 1, 1, 1}));
    EXPECT_EQ(order("round_robin", 0), (std::vector<uint32_t>{1, 0, 1, 1}));
}

TEST(TreeletScheduler, RegistryListsEverySchedulerAndRefusesUnknownOnes) {
    EXPECT_EQ(ComponentIndex::names("treelet_scheduler"),
              (std::vector<std::string>{"age_ordered", "most_rays", "round_robin"}));
    EXPECT_THROW(TreeletSchedulerRegistry::at("shortest_first"), std::invalid_argument);
}

// The treelet ray buffer: queues, scheduler policies, ports, admission back-pressure; and cores
// running rays through it.
#include <gtest/gtest.h>

#include "fixed_memory.h"
#include "models/core.h"
#include "models/ray_buffer.h"
#include "models/unit.h"

using namespace rtsim;

namespace {

// Rays whose steps visit the given treelets in order (one node step per entry).
class TreeletSource : public RayWorkSource {
  public:
    explicit TreeletSource(std::vector<std::vector<uint32_t>> rays) : rays_(std::move(rays)) {}
    bool next(RayWork& w, Cycle) override {
        if (given_ == rays_.size()) return false;
        w.ray_id = uint32_t(given_);
        w.steps.clear();
        for (uint32_t t : rays_[given_]) {
            Step s{0x1000 + uint64_t(t) * 256, t, 64, StepKind::Node, 2};
            s.treelet = t;
            w.steps.push_back(s);
        }
        ++given_;
        return true;
    }
    size_t given() const { return given_; }

  private:
    std::vector<std::vector<uint32_t>> rays_;
    size_t given_ = 0;
};

std::vector<TreeletSpan> spans(int n) {
    std::vector<TreeletSpan> s(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) s[size_t(k)] = {0x1000 + uint64_t(k) * 256, 256, 0, 0};
    return s;
}

}  // namespace

TEST(RayBuffer, MostRaysPicksTheFullestQueue) {
    // Rays start in treelets 2, 1, 2, 0, 2, 1.
    TreeletSource src({{2}, {1}, {2}, {0}, {2}, {1}});
    RayBufferParams p;
    p.batch_rays = 100;
    RayBuffer most("most", p, spans(3), &src);
    uint32_t t = 99;
    std::deque<uint32_t> rays;
    ASSERT_TRUE(most.next_batch(0, t, rays));
    EXPECT_EQ(t, 2u);  // three rays queued there
    EXPECT_EQ(rays.size(), 3u);
    rays.clear();
    ASSERT_TRUE(most.next_batch(0, t, rays));
    EXPECT_EQ(t, 1u);  // two
    rays.clear();
    ASSERT_TRUE(most.next_batch(0, t, rays));
    EXPECT_EQ(t, 0u);
    rays.clear();
    EXPECT_FALSE(most.next_batch(0, t, rays));
    EXPECT_FALSE(most.finished());  // rays are out in batches, not yet released
    EXPECT_EQ(most.admitted, 6u);
}

// Equal queues: most-rays breaks the tie by the lowest id, round robin goes on from the last
// treelet picked (initially 0) and wraps.
std::vector<uint32_t> pick_order(const std::string& policy) {
    TreeletSource src({{0}, {0}, {1}, {1}, {2}, {2}});
    RayBufferParams p;
    p.batch_rays = 6;  // the first request admits every ray
    p.scheduler = policy;
    RayBuffer rb(sc_core::sc_gen_unique_name(policy.c_str()), p, spans(3), &src);
    std::vector<uint32_t> picked;
    uint32_t t;
    std::deque<uint32_t> rays;
    while (rb.next_batch(0, t, rays)) picked.push_back(t);
    EXPECT_EQ(rays.size(), 6u);
    return picked;
}

TEST(RayBuffer, PoliciesOrderEqualQueues) {
    EXPECT_EQ(pick_order("most_rays"), (std::vector<uint32_t>{0, 1, 2}));
    EXPECT_EQ(pick_order("round_robin"), (std::vector<uint32_t>{1, 2, 0}));
}

TEST(RayBuffer, PortsServeAccessesPerCycleAfterLatency) {
    // N reads at cycle 0 through P ports of latency L: the last starts at ceil(N/P) - 1.
    const int n = 10, ports = 3;
    const Cycle L = 5;
    std::vector<std::vector<uint32_t>> rays(n, std::vector<uint32_t>{0});
    TreeletSource src(rays);
    RayBufferParams p;
    p.ports = ports;
    p.latency_cycles = L;
    p.batch_rays = n;
    RayBuffer rb("rb", p, spans(1), &src);
    uint32_t t;
    std::deque<uint32_t> batch;
    ASSERT_TRUE(rb.next_batch(0, t, batch));           // admission writes use the ports too
    const Cycle writes_end = (n + ports - 1) / ports;  // first cycle the ports are free again
    Cycle last = 0;
    RayWork w;
    size_t pos;
    for (uint32_t h : batch) last = std::max(last, rb.read(h, writes_end + L, w, pos));
    EXPECT_EQ(last, writes_end + L + Cycle((n + ports - 1) / ports - 1) + L);
    EXPECT_EQ(rb.reads, uint64_t(n));
    EXPECT_EQ(rb.writes, uint64_t(n));
}

// Queues in memory: every admission and crossing writes the ray's record at its own address
// (posted, readable at once) and every read of it waits for the memory, not for ports.
TEST(RayBuffer, RecordsInMemoryAreWrittenAndReadThere) {
    TreeletSource src({{0, 1}, {0}});
    RayBufferParams p;
    p.in_memory = true;
    p.ray_bytes = 48;
    p.batch_rays = 2;
    RayBuffer rb("rb_mem", p, spans(2), &src);
    test::FixedLatencyMemory mem(100);
    rb.down.bind(mem.up);
    test::elaborate();
    uint32_t t;
    std::deque<uint32_t> batch;
    ASSERT_TRUE(rb.next_batch(10, t, batch));
    ASSERT_EQ(batch.size(), 2u);
    ASSERT_EQ(mem.write_addrs.size(), 2u);  // both admissions
    EXPECT_EQ(mem.write_times[0], 10u);
    EXPECT_EQ(mem.write_bytes, 96u);
    for (size_t k = 0; k < 2; ++k) EXPECT_EQ(mem.write_addrs[k], rb.record_address(batch[k]));
    EXPECT_EQ(rb.record_address(1) - rb.record_address(0), 48u);
    RayWork w;
    size_t pos;
    // A read at 20 returns at 20 + 100: the memory's latency, nothing else.
    EXPECT_EQ(rb.read(batch[0], 20, w, pos), 120u);
    ASSERT_EQ(mem.addrs.size(), 1u);
    EXPECT_EQ(mem.addrs[0], rb.record_address(batch[0]));
    // The ray crosses into treelet 1: its record is written again, at once.
    EXPECT_EQ(rb.requeue(batch[0], w, 1, 1, 200), 200u);
    EXPECT_EQ(mem.write_addrs.size(), 3u);
    EXPECT_EQ(mem.write_addrs[2], rb.record_address(batch[0]));
    EXPECT_EQ(rb.writes, 3u);
    EXPECT_EQ(rb.reads, 1u);
    EXPECT_EQ(rb.port_wait_cycles, 0u);
    // A driver that runs memory itself gets the writes' addresses instead, and reads that
    // return when the record may be read.
    rb.set_defer(true);
    batch.clear();
    ASSERT_TRUE(rb.next_batch(300, t, batch));
    EXPECT_EQ(rb.read(batch[0], 310, w, pos), 310u);
    EXPECT_EQ(rb.requeue(batch[0], w, pos, 0, 320), 320u);
    EXPECT_EQ(rb.deferred_writes().size(), 1u);
    EXPECT_EQ(mem.write_addrs.size(), 3u);  // nothing sent
}

TEST(RayBuffer, FullBufferHoldsNewRaysBack) {
    std::vector<std::vector<uint32_t>> rays(10, std::vector<uint32_t>{0});
    TreeletSource src(rays);
    RayBufferParams p;
    p.capacity_rays = 3;
    p.batch_rays = 8;
    RayBuffer rb("rb", p, spans(1), &src);
    uint32_t t;
    std::deque<uint32_t> batch;
    ASSERT_TRUE(rb.next_batch(0, t, batch));
    EXPECT_EQ(batch.size(), 3u);
    EXPECT_EQ(src.given(), 3u);  // the source was not drained into nowhere
    EXPECT_EQ(rb.admission_blocked, 1u);
    std::deque<uint32_t> more;
    EXPECT_FALSE(rb.next_batch(1, t, more));  // full, nothing queued
    rb.release(batch.front());
    EXPECT_TRUE(rb.next_batch(2, t, more));
    EXPECT_EQ(more.size(), 1u);
    EXPECT_EQ(rb.peak_rays, 3u);
}

// Cores through the ray buffer: every ray finishes, every step runs once, a ray is queued
// again exactly where its treelet changes, and a tiny buffer only slows things down.
void run_cores_through_buffer(uint32_t capacity, uint64_t& rays_done, uint64_t& steps_done,
                              RayBuffer*& out, uint64_t& crossings_expected) {
    std::vector<std::vector<uint32_t>> rays;
    crossings_expected = 0;
    for (int r = 0; r < 200; ++r) {
        std::vector<uint32_t> path;
        for (int s = 0; s < 1 + r % 7; ++s) path.push_back(uint32_t((r * 3 + s / 2) % 5));
        for (size_t s = 1; s < path.size(); ++s) crossings_expected += path[s] != path[s - 1];
        rays.push_back(path);
    }
    rays.push_back({});  // a ray that misses the scene still passes through
    static TreeletSource src(rays);
    static test::FixedLatencyMemory mem(3);
    static PipelinedUnit box("box", UnitParams{1, 4, 1, 8}), tri("tri", UnitParams{1, 8, 1});
    RayBufferParams p;
    p.capacity_rays = capacity;
    p.batch_rays = 4;
    static RayBuffer rb("rb", p, spans(5), &src);
    static std::vector<std::unique_ptr<Core>> cores;
    std::vector<Core*> ptrs;
    CoreParams cp;
    cp.ray_slots = 4;
    for (int i = 0; i < 3; ++i) {
        cores.push_back(std::make_unique<Core>(
            ("core" + std::to_string(i)).c_str(), cp,
            std::array<TargetSocketBase*, kStepKinds>{&mem.up, &mem.up},
            std::array<TargetSocketBase*, kStepKinds>{&box.up, &tri.up}, &src));
        cores.back()->set_ray_buffer(&rb.up);
        ptrs.push_back(cores.back().get());
    }
    static CoreScheduler sched("sched", ptrs, &rb);
    sc_core::sc_start();
    rays_done = steps_done = 0;
    for (auto& c : cores) {
        rays_done += c->rays;
        steps_done += c->steps;
    }
    out = &rb;
}

TEST(RayBufferCores, EveryRayFinishesAndCrossesWhereItsTreeletChanges) {
    uint64_t rays, steps, crossings;
    RayBuffer* rb;
    run_cores_through_buffer(64, rays, steps, rb, crossings);
    EXPECT_EQ(rays, 201u);
    uint64_t expected_steps = 0;
    for (int r = 0; r < 200; ++r) expected_steps += uint64_t(1 + r % 7);
    EXPECT_EQ(steps, expected_steps);
    EXPECT_EQ(rb->crossings, crossings);
    EXPECT_EQ(rb->admitted, 201u);
    EXPECT_TRUE(rb->finished());
    EXPECT_LE(rb->peak_rays, 64u);
}

TEST(RayBufferCores, TinyBufferBackPressuresAndLosesNoRay) {
    uint64_t rays, steps, crossings;
    RayBuffer* rb;
    run_cores_through_buffer(5, rays, steps, rb, crossings);
    EXPECT_EQ(rays, 201u);
    EXPECT_EQ(rb->admitted, 201u);
    EXPECT_GT(rb->admission_blocked, 0u);
    EXPECT_LE(rb->peak_rays, 5u);
    EXPECT_EQ(rb->crossings, crossings);
    EXPECT_TRUE(rb->finished());
}

// A core finds the ray buffer through the socket chip assembly bound (its `up`), once the
// kernel has elaborated the sockets; the buffer answers nothing but that request.
TEST(RayBufferCores, ACoreFindsTheBufferThroughItsSocket) {
    TreeletSource src(std::vector<std::vector<uint32_t>>{{0}});
    RayBuffer rb("rb_found", RayBufferParams{}, spans(1), &src);
    test::FixedLatencyMemory mem(3);
    PipelinedUnit box("box_found", UnitParams{1, 4, 1, 8}), tri("tri_found", UnitParams{1, 8, 1});
    Core core("core_found", CoreParams{}, {&mem.up, &mem.up}, {&box.up, &tri.up}, &src);
    core.set_ray_buffer(&rb.up);
    EXPECT_EQ(core.ray_buffer(), nullptr);
    test::elaborate();
    EXPECT_EQ(core.ray_buffer(), &rb);
    EXPECT_EQ(find_direct<PipelinedUnit>(*core.ray_buffer_socket.operator->()), nullptr);
    tlm::tlm_generic_payload gp;
    gp.set_command(tlm::TLM_READ_COMMAND);
    sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
    core.ray_buffer_socket->b_transport(gp, delay);
    EXPECT_EQ(gp.get_response_status(), tlm::TLM_COMMAND_ERROR_RESPONSE);
}

#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <memory>
#include <vector>

#include "fixed_memory.h"
#include "models/core.h"
#include "models/core_slots.h"
#include "models/fidelity.h"
#include "models/unit.h"

using namespace rtsim;

namespace {

// Rays of `steps` identical steps each, at distinct addresses.
class SyntheticSource : public RayWorkSource {
  public:
    SyntheticSource(int rays, int steps, StepKind kind) : rays_(rays), steps_(steps), kind_(kind) {}
    bool next(RayWork& w, Cycle) override {
        if (given_ == rays_) return false;
        w.ray_id = uint32_t(given_++);
        w.steps.clear();
        for (int i = 0; i < steps_; ++i)
            w.steps.push_back({uint64_t(i) * 64, uint32_t(i), 64, kind_,
                               kind_ == StepKind::Node ? uint8_t(2) : uint8_t(1)});
        return true;
    }

  private:
    int rays_, steps_, given_ = 0;
    StepKind kind_;
};

}  // namespace

// N slots each running one single-step ray, memory and issue free: the box pipeline of latency L
// and interval 1 is the only cost, so the frame ends at N + L - 1.
TEST(Core, FullPipelineThroughCoreFinishesInNPlusLMinusOne) {
    const int n = 16;
    const Cycle L = 8;
    test::FixedLatencyMemory mem(0);
    PipelinedUnit box("box", UnitParams{1, L, 1, 8}), tri("tri", UnitParams{1, 18, 1});
    SyntheticSource src(n, 1, StepKind::Node);
    CoreParams cp;
    cp.ray_slots = n;
    cp.issue_width = n;
    cp.issue_latency_cycles = 0;
    Core core("core", cp, {&mem.up, &mem.up}, {&box.up, &tri.up}, &src);
    CoreScheduler sched("sched", {&core});
    sc_core::sc_start();
    EXPECT_EQ(core.rays, uint64_t(n));
    EXPECT_EQ(core.last_cycle, n + L - 1);
    EXPECT_EQ(box.ops, uint64_t(n));
    EXPECT_EQ(tri.ops, 0u);
}

// No-work cycles are counted, not inferred: 4 slots, 2 rays of one triangle step (issue I,
// memory M, unit T): two slots retire at cycle 0, two run a ray to I + I + M + T and then retire
// (their last look for work is at their ray's end). Worked by hand: no_work = 2 * D (the idle
// slots) and every slot cycle is charged once, nothing left unaccounted.
TEST(Core, NoWorkCyclesAreChargedAndNothingIsLeftOver) {
    const Cycle M = 30, T = 18, I = 2;
    test::FixedLatencyMemory mem(M);
    // Two triangle pipelines: the two rays' tests do not wait for each other.
    PipelinedUnit box("box", UnitParams{1, 8, 1}), tri("tri", UnitParams{2, T, 1});
    SyntheticSource src(2, 1, StepKind::Triangle);
    CoreParams cp;
    cp.ray_slots = 4;
    cp.issue_width = 4;
    cp.issue_latency_cycles = I;
    Core core("core", cp, {&mem.up, &mem.up}, {&box.up, &tri.up}, &src);
    CoreScheduler sched("sched", {&core});
    sc_core::sc_start();
    const Cycle D = I + I + M + T;
    ASSERT_EQ(core.last_cycle, D);
    ReportContext ctx;
    ctx.total_cycles = D;
    const auto e = core.stall_report(ctx);
    EXPECT_EQ(e["slot_cycles"].get<uint64_t>(), 4 * D);
    EXPECT_EQ(e["no_work"].get<uint64_t>(), 2 * D);
    EXPECT_EQ(e["unaccounted_cycles"].get<int64_t>(), 0);
    EXPECT_EQ(e["issue"].get<uint64_t>(), 2 * 2 * I);
    EXPECT_EQ(e["dram"].get<uint64_t>(), 2 * M);
    EXPECT_EQ(e["triangle_unit"].get<uint64_t>(), 2 * T);
}

// One slot: every step waits for the previous one, so latencies add up exactly.
// Hit records through a write buffer whose writes are accepted W = 100 cycles after they are
// posted. Four one-step rays end their box operations at 8, 9, 10, 11 (latency 8, interval 1).
struct WriteBufferRun {
    test::FixedLatencyMemory mem{0}, local{0};
    PipelinedUnit box{"box", UnitParams{1, 8, 1, 8}}, tri{"tri", UnitParams{1, 18, 1}};
    SyntheticSource src{4, 1, StepKind::Node};
    std::unique_ptr<Core> core;
    std::unique_ptr<CoreScheduler> sched;
    explicit WriteBufferRun(uint32_t entries) {
        local.write_latency = 100;
        CoreParams cp;
        cp.ray_slots = 4;
        cp.issue_width = 4;
        cp.issue_latency_cycles = 0;
        cp.hit_record_bytes = 16;
        cp.write_buffer_entries = entries;
        core = std::make_unique<Core>(
            "core", cp, std::array<TargetSocketBase*, kStepKinds>{&mem.up, &mem.up},
            std::array<TargetSocketBase*, kStepKinds>{&box.up, &tri.up}, &src);
        core->set_local_memory(&local.up, 0);
        sched = std::make_unique<CoreScheduler>("sched", std::vector<Core*>{core.get()});
        sc_core::sc_start();
    }
};

// One entry: ray 0 posts at 8, and ray k waits for the entry until 8 + 100k, so the frame ends
// at 308 and the write-buffer stalls add up to 99 x (1 + 2 + 3) = 594 cycles.
TEST(Core, WriteBufferHoldsWritesUntilAccepted) {
    WriteBufferRun run(1);
    EXPECT_EQ(run.core->rays, 4u);
    EXPECT_EQ(run.core->last_cycle, 308u);
    EXPECT_EQ(run.core->stall_cycles[Core::kWriteBuffer], 594u);
    EXPECT_EQ(run.local.write_times, (std::vector<Cycle>{8, 108, 208, 308}));
    EXPECT_EQ(run.core->hit_record_bytes, 64u);
}

// Unbounded: every ray posts its record when its box operation ends and nothing waits.
TEST(Core, UnboundedWriteBufferNeverStalls) {
    WriteBufferRun run(0);
    EXPECT_EQ(run.core->last_cycle, 11u);
    EXPECT_EQ(run.core->stall_cycles[Core::kWriteBuffer], 0u);
    EXPECT_EQ(run.local.write_times, (std::vector<Cycle>{8, 9, 10, 11}));
}

TEST(Core, SingleSlotLatenciesAdd) {
    const Cycle M = 30, B = 8, T = 18, I = 2;
    const int rays = 5, steps = 7;
    test::FixedLatencyMemory mem(M);
    PipelinedUnit box("box", UnitParams{1, B, 1}), tri("tri", UnitParams{1, T, 1});
    SyntheticSource src(rays, steps, StepKind::Triangle);
    CoreParams cp;
    cp.ray_slots = 1;
    cp.issue_latency_cycles = I;
    Core core("core", cp, {&mem.up, &mem.up}, {&box.up, &tri.up}, &src);
    CoreScheduler sched("sched", {&core});
    sc_core::sc_start();
    EXPECT_EQ(core.last_cycle, Cycle(rays) * (I + steps * (I + M + T)));
    EXPECT_EQ(core.steps, uint64_t(rays * steps));
    EXPECT_EQ(mem.addrs.size(), size_t(rays * steps));
    EXPECT_EQ(core.ray_latency_cycles, core.last_cycle);  // back to back, never overlapping
    // Stall attribution, analytically: issue I per setup and per step, memory M and unit T per
    // step.
    EXPECT_EQ(core.stall_cycles[Core::kIssue], Cycle(rays) * (I + steps * I));
    EXPECT_EQ(core.stall_cycles[Core::kDram], Cycle(rays) * steps * M);
    EXPECT_EQ(core.stall_cycles[Core::kUnitStall + int(StepKind::Triangle)],
              Cycle(rays) * steps * T);
    EXPECT_EQ(core.stall_cycles[Core::kUnitStall + int(StepKind::Node)] +
                  core.stall_cycles[Core::kL1] + core.stall_cycles[Core::kL2],
              0u);
}

// A ray through a two-level scene, one slot: TLAS node, instance transform, BLAS node,
// triangle. Each step costs its issue I, memory M and its own unit's latency (box B, transform
// X, triangle T), and the transform's wait is charged to the transform unit.
TEST(Core, InstanceTransformStepRunsOnItsOwnUnit) {
    const Cycle M = 30, B = 8, X = 5, T = 18, I = 2;
    test::FixedLatencyMemory mem(M);
    PipelinedUnit box("box", UnitParams{1, B, 1}), tri("tri", UnitParams{1, T, 1}),
        xf("xf", UnitParams{1, X, 1});
    struct TwoLevelRay : RayWorkSource {
        bool given = false;
        bool next(RayWork& w, Cycle) override {
            if (given) return false;
            given = true;
            w.steps = {{0, 0, 64, StepKind::Node, 2},
                       {4096, 0, 64, StepKind::Transform, 1},
                       {64, 1, 64, StepKind::Node, 2},
                       {8192, 0, 48, StepKind::Triangle, 1}};
            return true;
        }
    } src;
    CoreParams cp;
    cp.ray_slots = 1;
    cp.issue_latency_cycles = I;
    Core core("core", cp, {&mem.up, &mem.up, &mem.up}, {&box.up, &tri.up, &xf.up}, &src);
    CoreScheduler sched("sched", {&core});
    sc_core::sc_start();
    EXPECT_EQ(core.last_cycle, I + (I + M + B) + (I + M + X) + (I + M + B) + (I + M + T));
    EXPECT_EQ(xf.ops, 1u);
    EXPECT_EQ(box.ops, 2u);
    EXPECT_EQ(tri.ops, 1u);
    EXPECT_EQ(core.stall_cycles[Core::kUnitStall + int(StepKind::Transform)], X);
    EXPECT_EQ(mem.addrs.size(), 4u);
}

// A candidate hit on non-opaque geometry: its triangle step, then an any-hit step that issues
// the shader's N instructions on the core's port, reads the alpha record (memory M) and waits the
// shader's latency S; a second call whose record is 0 bytes reads nothing. The shader's waits
// are charged to the any-hit shader, and only the reads that have bytes reach memory.
TEST(Core, AnyHitStepIssuesTheShaderAndWaitsItsLatency) {
    const Cycle M = 30, T = 18, S = 20, I = 2;
    const int N = 6;
    test::FixedLatencyMemory mem(M);
    PipelinedUnit box("box", UnitParams{1, 8, 1}), tri("tri", UnitParams{1, T, 1}),
        xf("xf", UnitParams{1, 4, 1}), shader("shader", UnitParams{1, S, 1});
    struct AlphaRay : RayWorkSource {
        bool given = false;
        bool next(RayWork& w, Cycle) override {
            if (given) return false;
            given = true;
            w.steps = {{8192, 0, 48, StepKind::Triangle, 1},
                       {12288, 0, 16, StepKind::AnyHit, 1},
                       {12304, 1, 0, StepKind::AnyHit, 1}};
            return true;
        }
    } src;
    CoreParams cp;
    cp.ray_slots = 1;
    cp.issue_latency_cycles = I;
    cp.step_instructions[int(StepKind::AnyHit)] = N;
    Core core("core", cp, {&mem.up, &mem.up, &mem.up, &mem.up},
              {&box.up, &tri.up, &xf.up, &shader.up}, &src);
    CoreScheduler sched("sched", {&core});
    sc_core::sc_start();
    EXPECT_EQ(core.last_cycle, I + (I + M + T) + (N - 1 + I + M + S) + (N - 1 + I + S));
    EXPECT_EQ(shader.ops, 2u);
    EXPECT_EQ(tri.ops, 1u);
    EXPECT_EQ(core.stall_cycles[Core::kUnitStall + int(StepKind::AnyHit)], 2 * S);
    EXPECT_EQ(mem.addrs.size(), 2u);
}

// Issue width 1 serialises step issue across slots: K slots of one-step rays with free memory
// and a unit of latency 1 finish at ~2K (setup issue + step issue per ray).
TEST(Core, IssueWidthLimitsThroughput) {
    const int k = 10;
    test::FixedLatencyMemory mem(0);
    PipelinedUnit box("box", UnitParams{1, 1, 1, 8}), tri("tri", UnitParams{1, 1, 1});
    SyntheticSource src(k, 1, StepKind::Node);
    CoreParams cp;
    cp.ray_slots = k;
    cp.issue_width = 1;
    cp.issue_latency_cycles = 0;
    Core core("core", cp, {&mem.up, &mem.up}, {&box.up, &tri.up}, &src);
    CoreScheduler sched("sched", {&core});
    sc_core::sc_start();
    // 2k issue slots at one per cycle: the last issues at 2k - 1, then the unit adds 1.
    EXPECT_EQ(core.last_cycle, Cycle(2 * k));
    EXPECT_GT(core.issue_stall_cycles, 0u);
}

TEST(Core, NoWorkCostsNothing) {
    test::FixedLatencyMemory mem(0);
    PipelinedUnit box("box", UnitParams{}), tri("tri", UnitParams{});
    SyntheticSource src(0, 1, StepKind::Node);
    Core core("core", CoreParams{}, {&mem.up, &mem.up}, {&box.up, &tri.up}, &src);
    CoreScheduler sched("sched", {&core});
    sc_core::sc_start();
    EXPECT_EQ(core.rays, 0u);
    EXPECT_EQ(core.last_cycle, 0u);
    EXPECT_EQ(sc_core::sc_time_stamp(), sc_core::SC_ZERO_TIME);
}

// Control instructions per step go through the issue port, issue_width per cycle: n instructions
// at width 1 add n - 1 cycles before the fetch.
TEST(Core, StepInstructionsOccupyTheIssuePort) {
    const Cycle M = 30, T = 18, I = 2;
    const int rays = 3, steps = 5, n = 4;
    test::FixedLatencyMemory mem(M);
    PipelinedUnit box("box", UnitParams{1, 8, 1}), tri("tri", UnitParams{1, T, 1});
    SyntheticSource src(rays, steps, StepKind::Triangle);
    CoreParams cp;
    cp.ray_slots = 1;
    cp.issue_latency_cycles = I;
    cp.step_instructions[int(StepKind::Triangle)] = n;
    Core core("core", cp, {&mem.up, &mem.up}, {&box.up, &tri.up}, &src);
    CoreScheduler sched("sched", {&core});
    sc_core::sc_start();
    EXPECT_EQ(core.last_cycle, Cycle(rays) * (I + steps * ((n - 1) + I + M + T)));
    EXPECT_EQ(core.stall_cycles[Core::kIssue], Cycle(rays) * (I + steps * ((n - 1) + I)));
}

// Cores of different speeds sharing one memory level: the scheduler hands that level every
// request in time order.
void run_cores_sharing_memory(std::vector<Cycle>& times, uint64_t& rays) {
    test::FixedLatencyMemory mem(20);
    std::vector<std::unique_ptr<PipelinedUnit>> units;
    std::vector<std::unique_ptr<SyntheticSource>> sources;
    std::vector<std::unique_ptr<Core>> cores;
    std::vector<Core*> ptrs;
    CoreParams cp;
    cp.ray_slots = 3;
    for (int i = 0; i < 4; ++i) {
        const std::string n = std::to_string(i);
        units.push_back(std::make_unique<PipelinedUnit>(("tri" + n).c_str(),
                                                        UnitParams{1, Cycle(5 + 7 * i), 1}));
        sources.push_back(std::make_unique<SyntheticSource>(20 + 5 * i, 3 + i, StepKind::Triangle));
        cores.push_back(std::make_unique<Core>(
            ("core" + n).c_str(), cp, std::array<TargetSocketBase*, kStepKinds>{&mem.up, &mem.up},
            std::array<TargetSocketBase*, kStepKinds>{&units.back()->up, &units.back()->up},
            sources.back().get()));
        ptrs.push_back(cores.back().get());
    }
    CoreScheduler sched("sched", ptrs);
    sc_core::sc_start();
    times = mem.times;
    rays = 0;
    for (auto& c : cores) rays += c->rays;
}

namespace {
// An engine whose fetches complete later, as the time-ordered reference's do: it records what the
// slot state machine asks of it, and the test plays the memory.
struct RecordingEngine {
    static constexpr bool kTimeOrdered = true;
    std::vector<std::pair<size_t, Cycle>> readies, idles, fetches;  // slot, cycle
    int work_changes = 0;
    bool retired = false;
    bool beyond(Cycle) const { return false; }
    void ready(size_t slot, Cycle c) { readies.emplace_back(slot, c); }
    void idle(size_t slot, Cycle t, bool for_good) {
        idles.emplace_back(slot, t);
        retired = for_good;
    }
    void work_changed(Cycle) { ++work_changes; }
    void records_written(Cycle) {}
    void start_loader(Cycle) { ADD_FAILURE() << "no treelet mode here"; }
    void loader_ready(Cycle) {}
    bool load_line(Cache*, uint64_t, uint32_t, Cycle) { return true; }
    bool read_record(size_t, Cycle) { return false; }
    bool write_entry_busy(size_t, Cycle) { return false; }
    void post_write(uint64_t, uint32_t, Cycle) { ADD_FAILURE() << "no writes here"; }
    void read_stack(size_t, uint64_t, uint32_t, Cycle) { ADD_FAILURE() << "no stack here"; }
    void fetch(size_t slot, const Step&, Cycle issued, Core::Fetch& f) {
        fetches.emplace_back(slot, issued);
        f.kind = Core::Fetch::kPending;
    }
};
}  // namespace

// The slot state machine both engines run, driven by hand: a ray of two node steps, issue
// latency I, memory M (charged to DRAM), box latency L. Setup issues at 0 and is done at I; each
// step issues one instruction (I), its fetch completes M later, its test L after that:
// step 1 fetched at 2I + M, done at 2I + M + L; step 2 issued at 3I + M + L, done at
// 3I + 2M + 2L, where the ray ends; then the source is empty and the slot retires.
TEST(Core, TheSlotStateMachineFollowsItsEngineByHand) {
    const Cycle I = 2, M = 30, L = 8;
    test::FixedLatencyMemory mem(0);
    PipelinedUnit box("box", UnitParams{1, L, 1, 8}), tri("tri", UnitParams{1, 18, 1});
    SyntheticSource src(1, 2, StepKind::Node);
    CoreParams cp;
    cp.ray_slots = 1;
    cp.issue_latency_cycles = I;
    Core core("core", cp, {&mem.up, &mem.up}, {&box.up, &tri.up}, &src);
    test::elaborate();  // the core finds its units through their sockets
    RecordingEngine e;
    const Cycle by_level[kMemLevels] = {0, 0, M, 0};
    EXPECT_EQ(core.run_slot(0, 0, e), Core::kRunOn);
    ASSERT_EQ(e.readies.size(), 1u);
    EXPECT_EQ(e.readies.back().second, I);  // set up
    core.run_slot(0, I, e);
    ASSERT_EQ(e.fetches.size(), 1u);
    EXPECT_EQ(e.fetches.back().second, 2 * I);
    EXPECT_EQ(e.readies.size(), 1u);  // pending: nothing until the data is there
    core.step_fetched(0, 2 * I + M, by_level, e);
    EXPECT_EQ(e.readies.back().second, 2 * I + M + L);
    EXPECT_EQ(core.rays, 0u);
    core.run_slot(0, 2 * I + M + L, e);
    ASSERT_EQ(e.fetches.size(), 2u);
    EXPECT_EQ(e.fetches.back().second, 3 * I + M + L);
    const Cycle end = 3 * I + 2 * M + 2 * L;
    core.step_fetched(0, 3 * I + 2 * M + L, by_level, e);
    EXPECT_EQ(e.readies.back().second, end);
    EXPECT_EQ(core.rays, 1u);  // the last step's test ends the ray
    EXPECT_EQ(core.last_cycle, end);
    EXPECT_EQ(e.work_changes, 1);
    core.run_slot(0, end, e);
    ASSERT_EQ(e.idles.size(), 1u);
    EXPECT_EQ(e.idles.back().second, end);
    EXPECT_TRUE(e.retired);
    // Every cycle of the ray charged once: issue 3I, DRAM 2M, box unit 2L.
    EXPECT_EQ(core.stall_cycles[Core::kIssue], 3 * I);
    EXPECT_EQ(core.stall_cycles[Core::kDram], 2 * M);
    EXPECT_EQ(core.stall_cycles[Core::kUnitStall + int(StepKind::Node)], 2 * L);
    EXPECT_EQ(core.ray_latency_cycles, end);
}

// The largest amount by which a request arrived earlier than one before it.
Cycle worst_lag(const std::vector<Cycle>& times) {
    Cycle latest = 0, lag = 0;
    for (Cycle t : times) {
        lag = std::max(lag, latest > t ? latest - t : 0);
        latest = std::max(latest, t);
    }
    return lag;
}

TEST(CoreScheduler, KeepsSharedRequestsInTimeOrder) {
    std::vector<Cycle> times;
    uint64_t rays = 0;
    run_cores_sharing_memory(times, rays);
    EXPECT_EQ(rays, uint64_t(20 + 25 + 30 + 35));
    EXPECT_EQ(times.size(), size_t(20 * 3 + 25 * 4 + 30 * 5 + 35 * 6));
    EXPECT_EQ(worst_lag(times), 0u);
}

// The slot and core picks take the least key: keys must order by cycle, then by index, with
// kParkedCycle and kNeverCycle after every real cycle, and give back both halves exactly.
TEST(CycleKeys, OrderByCycleThenIndexAndRoundTrip) {
    for (size_t count : {size_t(1), size_t(8), size_t(13), size_t(4096)}) {
        const CycleKeys keys(count);
        const Cycle latest = (Cycle(1) << 40) - 1;  // beyond any calendar's cycles
        const std::vector<Cycle> cycles = {0, 1, 7, 4096, latest, kParkedCycle, kNeverCycle};
        for (size_t a = 0; a < cycles.size(); ++a)
            for (size_t i : {size_t(0), count - 1}) {
                const uint64_t k = keys.key(cycles[a], i);
                EXPECT_EQ(keys.cycle(k), cycles[a]) << count;
                EXPECT_EQ(keys.index(k), i) << count;
                for (size_t b = 0; b < cycles.size(); ++b)
                    for (size_t j : {size_t(0), count - 1}) {
                        const bool earlier =
                            cycles[a] < cycles[b] || (cycles[a] == cycles[b] && i < j);
                        EXPECT_EQ(k < keys.key(cycles[b], j), earlier)
                            << count << ": " << cycles[a] << "/" << i << " vs " << cycles[b] << "/"
                            << j;
                    }
            }
    }
}

namespace {

// Looks at a core every 13 ns of kernel time until its rays are done.
struct Watcher : sc_core::sc_module {
    SC_HAS_PROCESS(Watcher);
    const Core& core;
    uint64_t rays;
    std::vector<uint64_t> finished_seen;  // the core's finished rays at each look
    Cycle latest_ahead = 0;               // how far past the kernel's time a finished ray ended
    Watcher(sc_core::sc_module_name name, const Core& c, uint64_t total)
        : sc_module(name), core(c), rays(total) {
        SC_THREAD(watch);
    }
    void watch() {
        for (int look = 0; look < 100000 && core.rays < rays; ++look) {
            wait(sc_core::sc_time(13, sc_core::SC_NS));
            const Cycle now = now_cycles();
            if (core.last_cycle > now) latest_ahead = std::max(latest_ahead, core.last_cycle - now);
            finished_seen.push_back(core.rays);
        }
    }
};

}  // namespace

// The accurate engine runs each cycle's stages at the kernel's time, so another SystemC process
// sees the chip at its own time: a ray counted finished ended no later than a step's unit latency
// past the kernel's time (its end is known when its last step issues), and the rays finish over
// many looks. (An engine that ran ahead of the kernel in windows of 4,096 cycles finished every
// ray of this frame, about 1,000 cycles, before the first look.)
TEST(Core, TheAccurateEngineRunsOnTheKernelsTime) {
    StageQueue stages;
    IdealMemory memory("memory", 20);
    memory.set_stage_queue(&stages);
    PipelinedUnit box("box", UnitParams{1, 8, 1, 8}), tri("tri", UnitParams{1, 18, 1});
    SyntheticSource src(64, 3, StepKind::Node);
    CoreParams cp;
    cp.ray_slots = 4;
    Core core("core", cp, {&memory.up, &memory.up, &memory.up, &memory.up}, {&box.up, &tri.up},
              &src);
    core.set_local_memory(&memory.up, 0);
    DriverSetup setup;
    setup.cores = {&core};
    setup.stages = &stages;
    const auto driver = FidelityRegistry::at("accurate").make("driver", setup);
    Watcher watcher("watcher", core, 64);
    sc_core::sc_start();
    EXPECT_EQ(core.rays, 64u);
    EXPECT_LE(watcher.latest_ahead, 8u);  // the box unit's latency
    std::vector<uint64_t> distinct = watcher.finished_seen;
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    EXPECT_GE(distinct.size(), 20u);
}

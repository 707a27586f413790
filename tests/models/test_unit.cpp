#include <gtest/gtest.h>

#include "models/unit.h"

using namespace rtsim;

// Analytical pipeline timing: N operations, all ready at cycle 0, on `count` pipelines of
// latency L and interval II. The last one starts at ceil(N/count - 1) * II and ends L later.
TEST(PipelinedUnit, LatencyLIntervalOneFinishesNOpsInNPlusLMinusOneCycles) {
    for (Cycle L : {1, 4, 18}) {
        for (uint64_t N : {1, 2, 100}) {
            PipelinedUnit u(sc_core::sc_gen_unique_name("u"), UnitParams{1, L, 1});
            Cycle last = 0;
            for (uint64_t i = 0; i < N; ++i) last = std::max(last, u.issue(0));
            // Results of op i are available at i + L; the N ops occupy cycles 0 .. N+L-1 exclusive.
            EXPECT_EQ(last, N - 1 + L) << "N=" << N << " L=" << L;
            EXPECT_EQ(u.ops, N);
            EXPECT_EQ(u.busy_cycles, N);
            EXPECT_EQ(u.queue_cycles, N * (N - 1) / 2);
        }
    }
}

TEST(PipelinedUnit, IntervalAndPipelineCount) {
    PipelinedUnit slow(sc_core::sc_gen_unique_name("u"), UnitParams{1, 10, 3});
    Cycle last = 0;
    for (int i = 0; i < 5; ++i) last = slow.issue(0);
    EXPECT_EQ(last, 4u * 3 + 10);
    PipelinedUnit wide(sc_core::sc_gen_unique_name("u"), UnitParams{2, 10, 1});
    for (int i = 0; i < 6; ++i) last = wide.issue(0);
    EXPECT_EQ(last, 2u + 10);  // 6 ops over 2 pipelines: starts 0,0,1,1,2,2
}

TEST(PipelinedUnit, IdleGapsAreNotBusy) {
    PipelinedUnit u(sc_core::sc_gen_unique_name("u"), UnitParams{1, 5, 1});
    EXPECT_EQ(u.issue(0), 5u);
    EXPECT_EQ(u.issue(100), 105u);
    EXPECT_EQ(u.busy_cycles, 2u);
    EXPECT_EQ(u.queue_cycles, 0u);
}

TEST(PipelinedUnit, WideNodesTakeSeveralOperations) {
    UnitParams p{1, 8, 1};
    p.width = 4;
    PipelinedUnit u(sc_core::sc_gen_unique_name("u"), p);
    EXPECT_EQ(u.issue(0, 8), 1u + 8);  // two back-to-back operations: the second starts at 1
    EXPECT_EQ(u.ops, 2u);
    EXPECT_EQ(u.issue(0, 3), 2u + 8);  // one more operation, queued behind them
    EXPECT_EQ(u.busy_cycles, 3u);
    EXPECT_EQ(u.queue_cycles, 2u);
}

TEST(PipelinedUnit, UnlimitedNeverQueues) {
    UnitParams p{1, 8, 3};
    p.unlimited = true;
    PipelinedUnit u(sc_core::sc_gen_unique_name("u"), p);
    for (int i = 0; i < 10; ++i) EXPECT_EQ(u.issue(5), 13u);  // all at once, each after its latency
    EXPECT_EQ(u.queue_cycles, 0u);
    EXPECT_EQ(u.busy_cycles, 30u);
}

// Operations reach a unit in the order the simulator meets them, not the order their operands
// arrive: one waiting on DRAM must not hold up one whose data is already there.
TEST(PipelinedUnit, AnOperationReadyEarlierDoesNotQueueBehindALaterOne) {
    PipelinedUnit u(sc_core::sc_gen_unique_name("u"), UnitParams{1, 8, 1});
    EXPECT_EQ(u.issue(300), 308u);
    EXPECT_EQ(u.issue(10), 18u);
    EXPECT_EQ(u.issue(300), 309u);  // this one does wait: cycle 300 is taken
    EXPECT_EQ(u.queue_cycles, 1u);
}

namespace {
// A requester of its own: an initiator socket, as a core has one per step kind.
struct UnitRequester : sc_core::sc_module {
    InitiatorSocket<UnitRequester> socket;
    explicit UnitRequester(sc_core::sc_module_name name) : sc_core::sc_module(name), socket("s") {}
    Cycle op(Cycle ready, int items) {
        return PipelinedUnit::transport(*socket.operator->(), ready, items, 1);
    }
};
}  // namespace

// Two requesters share one unit through its socket (box_unit.shared_by = 2). The unit: one
// pipeline, latency 4, an operation every 2 cycles, 8 boxes per operation. By hand: A and B both
// ready at 10: A issues at 10 (done 14), B waits for 12 (done 16); A's 16-box node at 11 takes
// two operations from 14, at 14 and 16: done 20. Waits: 2 + 3 cycles.
TEST(PipelinedUnit, RequestersShareTheUnitThroughItsSocket) {
    PipelinedUnit unit(sc_core::sc_gen_unique_name("u"), UnitParams{1, 4, 2, 8});
    UnitRequester a(sc_core::sc_gen_unique_name("a")), b(sc_core::sc_gen_unique_name("b"));
    a.socket.bind(unit.up);
    b.socket.bind(unit.up);
    sc_core::sc_report_handler::set_actions(sc_core::SC_ID_NO_SC_START_ACTIVITY_,
                                            sc_core::SC_DO_NOTHING);
    sc_core::sc_start(sc_core::SC_ZERO_TIME);
    EXPECT_EQ(a.op(10, 1), 14u);
    EXPECT_EQ(b.op(10, 1), 16u);
    EXPECT_EQ(a.op(11, 16), 20u);
    EXPECT_EQ(unit.ops, 4u);
    EXPECT_EQ(unit.queue_cycles, 5u);
    // The direct access a core asks for once is the unit itself; a payload that is not a unit
    // operation is refused.
    EXPECT_EQ(find_direct<PipelinedUnit>(*a.socket.operator->()), &unit);
    tlm::tlm_generic_payload gp;
    gp.set_command(tlm::TLM_READ_COMMAND);
    sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
    a.socket->b_transport(gp, delay);
    EXPECT_EQ(gp.get_response_status(), tlm::TLM_COMMAND_ERROR_RESPONSE);
    EXPECT_EQ(unit.ops, 4u);
}

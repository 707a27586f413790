// The blocks' contract (models/transaction.h): the StageQueue's order, a cache serving the
// time-ordered engine's requests through its TLM-2.0 socket, and the fast engine's loosely timed
// calls through the same sockets.
#include <gtest/gtest.h>

#include <algorithm>
#include <queue>
#include <random>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "fixed_memory.h"
#include "models/cache.h"
#include "models/crossbar.h"
#include "models/line_map.h"
#include "models/transaction.h"

using namespace rtsim;

namespace {

// Records the stages it is given, and schedules more from inside one when asked.
struct Recorder final : StageHandler {
    StageQueue* queue = nullptr;
    struct Ran {
        Cycle t;
        uint32_t id;
    };
    std::vector<Ran> ran;
    // id -> (delay, order, new id) of a stage to schedule when stage id runs
    std::vector<std::tuple<Cycle, uint64_t, uint32_t>> then;
    void run_stage(uint32_t, uint32_t id, uint32_t, Cycle t) override {
        ran.push_back({t, id});
        if (id < then.size() && std::get<2>(then[id]) != 0) {
            const auto [delay, order, next] = then[id];
            queue->schedule(t + delay, order, this, 0, next);
        }
    }
};

}  // namespace

// Stages run by cycle, then order class, then the order they were scheduled, against the plain
// model of that rule (one heap of every stage): cycles within the ring, beyond it (waiting
// apart), far apart (the queue jumps), and stages scheduled from inside a stage, at its own cycle
// (in any class, even one already passed: it runs next) or later.
TEST(StageQueue, RunsStagesInCycleThenClassThenScheduleOrder) {
    std::mt19937_64 rng(7);
    for (int round = 0; round < 20; ++round) {
        StageQueue q;
        Recorder rec;
        rec.queue = &q;
        using Key = std::tuple<Cycle, uint64_t, uint64_t, uint32_t>;  // cycle, class, seq, id
        std::priority_queue<Key, std::vector<Key>, std::greater<Key>> model;
        uint64_t seq = 0;
        const int n = 2000;
        rec.then.assign(2 * n + 1, {0, 0, 0});
        const Cycle spans[] = {8, 600, 5000, 100000};
        const Cycle span = spans[round % 4];
        for (uint32_t id = 1; id <= uint32_t(n); ++id) {
            const Cycle t = rng() % span;
            const uint64_t order = rng() % 5;
            q.schedule(t, order, &rec, 0, id);
            model.emplace(t, order, seq++, id);
            // Every fourth stage schedules another when it runs: at its own cycle or later.
            if (id % 4 == 0) {
                const Cycle delay = (rng() % 3 == 0) ? 0 : rng() % (2 * span + 1);
                rec.then[id] = {delay, rng() % 5, id + uint32_t(n)};
            }
        }
        size_t i = 0;
        while (!model.empty()) {
            const auto [t, order, s, id] = model.top();
            model.pop();
            ASSERT_FALSE(q.empty());
            q.run_next();
            ASSERT_EQ(rec.ran.size(), i + 1);
            ASSERT_EQ(rec.ran[i].id, id) << "round " << round << ", stage " << i;
            ASSERT_EQ(rec.ran[i].t, t);
            EXPECT_EQ(q.now(), t);
            if (id < rec.then.size() && std::get<2>(rec.then[id]) != 0) {
                const auto [delay, next_order, next] = rec.then[id];
                model.emplace(t + delay, next_order, seq++, next);
            }
            ++i;
        }
        EXPECT_TRUE(q.empty());
    }
}

TEST(StageQueue, RefusesAStageBeforeTheCurrentCycle) {
    StageQueue q;
    Recorder rec;
    rec.queue = &q;
    q.schedule(10, StageQueue::kMemoryOrder, &rec, 0, 1);
    q.run_next();
    EXPECT_EQ(q.now(), 10u);
    EXPECT_THROW(q.schedule(9, StageQueue::kMemoryOrder, &rec, 0, 2), std::logic_error);
}

namespace {

// A requester with a socket of its own: sends reads and records when each is answered.
struct Requester final : sc_core::sc_module {
    InitiatorSocket<Requester> socket;
    StageQueue* queue;
    PayloadPool pool;
    std::vector<std::pair<uint64_t, Cycle>> answers;  // address, cycle
    Requester(sc_core::sc_module_name name, StageQueue* q)
        : sc_module(name), socket("socket"), queue(q) {
        socket.register_nb_transport_bw(this, &Requester::nb_transport_bw);
    }
    // A read of `bytes` at `addr` reaching the target at t (the queue's current cycle or later).
    void read(uint64_t addr, uint32_t bytes, Cycle t) {
        tlm::tlm_generic_payload& gp = pool.acquire(tlm::TLM_READ_COMMAND, addr, bytes, t);
        tlm::tlm_phase phase = tlm::BEGIN_REQ;
        sc_core::sc_time delay = cycles_delay(t - queue->now());
        EXPECT_EQ(socket->nb_transport_fw(gp, phase, delay), tlm::TLM_UPDATED);
        EXPECT_EQ(phase, tlm::END_REQ);  // accepted at once: the next request may follow
    }
    tlm::tlm_sync_enum nb_transport_bw(tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time& delay) {
        EXPECT_EQ(phase, tlm::BEGIN_RESP);
        EXPECT_EQ(delay, sc_core::SC_ZERO_TIME);
        EXPECT_EQ(gp.get_response_status(), tlm::TLM_OK_RESPONSE);
        answers.emplace_back(gp.get_address(), queue->now());
        pool.release(gp);
        return tlm::TLM_COMPLETED;
    }
};

}  // namespace

// Two requesters bound to one cache (hit latency 4) over ideal memory (latency 50): A's read at
// cycle 0 is looked up at 4, misses, and its fill reaches ideal memory at 4 and is back at 54;
// B's read of the same line at 1 is looked up at 5, finds the line filling and waits on the same
// fill (a merged miss); both are answered at 54, each through its own socket. B's second read of
// the line at 60 hits: answered at 64. Worked by hand from the latencies.
TEST(MemoryContract, ACacheAnswersEachRequesterThroughItsOwnSocketByHand) {
    StageQueue q;
    CacheParams p;
    p.size_bytes = 1024;
    p.ways = 2;
    p.line_bytes = 64;
    p.hit_latency_cycles = 4;
    p.mshrs = 2;
    IdealMemory memory("memory", 50);
    Cache cache("cache", p, &memory.up);
    Requester a("a", &q), b("b", &q);
    a.socket.bind(cache.up);
    b.socket.bind(cache.up);
    cache.set_stage_queue(&q);
    memory.set_stage_queue(&q);
    sc_core::sc_start(sc_core::SC_ZERO_TIME);  // elaboration binds the sockets

    a.read(0x1000, 32, 0);
    b.read(0x1020, 32, 1);
    while (!q.empty()) q.run_next();
    ASSERT_EQ(a.answers.size(), 1u);
    ASSERT_EQ(b.answers.size(), 1u);
    EXPECT_EQ(a.answers[0], std::make_pair(uint64_t(0x1000), Cycle(54)));
    EXPECT_EQ(b.answers[0], std::make_pair(uint64_t(0x1020), Cycle(54)));
    EXPECT_EQ(cache.misses, 1u);
    EXPECT_EQ(cache.merged_misses, 1u);

    b.read(0x1000, 8, 60);  // reaches the cache at 60, within the call
    while (!q.empty()) q.run_next();
    ASSERT_EQ(b.answers.size(), 2u);
    EXPECT_EQ(b.answers[1], std::make_pair(uint64_t(0x1000), Cycle(64)));
    EXPECT_EQ(cache.accesses, 3u);
    EXPECT_EQ(cache.misses, 1u);
}

// The time-ordered cache's map of fills in flight, against std::unordered_map over random sets,
// finds and erases, with lines that collide in a small table and tables that grow.
namespace {

// Sends loosely timed reads from a process, the kernel's time at 100 ns.
struct LtRequester final : sc_core::sc_module {
    InitiatorSocket<LtRequester> socket;
    LtPort port{socket};
    std::vector<Cycle> answers;
    std::vector<AccessBreakdown> breakdowns;
    bool early_refused = false;
    SC_HAS_PROCESS(LtRequester);
    explicit LtRequester(sc_core::sc_module_name name) : sc_core::sc_module(name), socket("s") {
        SC_THREAD(run);
    }
    void run() {
        wait(sc_core::sc_time(100, sc_core::SC_NS));
        for (const Cycle at : {Cycle(130), Cycle(100), Cycle(131)}) {
            AccessBreakdown bd;
            answers.push_back(port.read(0x40 * at, 64, at, &bd));
            breakdowns.push_back(bd);
        }
        try {
            port.read(0, 64, 99, nullptr);  // before the kernel's time: no delay can say it
        } catch (const std::logic_error&) {
            early_refused = true;
        }
    }
};

}  // namespace

// The fast engine's calls: a read issued at cycle 130 while the kernel is at 100 ns reaches the
// block with a 30 ns delay, through a crossbar (64 bytes at 16 per cycle: 4 cycles to cross)
// to a memory of latency 40: back at 130 + 40 + 4 = 174, the crossing charged to the crossbar and
// the latency to the memory's level. A read at 100 is back at 144; one at 131 comes back from the
// memory at 171 while the link is busy until 174 (the first read's line), so it crosses
// 174..178. A request before the kernel's time is refused.
TEST(MemoryContract, LooselyTimedCallsCountTheirDelayFromTheKernelsTime) {
    test::FixedLatencyMemory memory(40);
    Crossbar crossbar("crossbar", 16.0, &memory.up);
    LtRequester requester("requester");
    requester.socket.bind(crossbar.up);
    sc_core::sc_start();
    ASSERT_EQ(memory.times, (std::vector<Cycle>{130, 100, 131}));
    EXPECT_EQ(requester.answers, (std::vector<Cycle>{174, 144, 178}));
    EXPECT_EQ(requester.breakdowns[0].cycles[kLevelDram], 40u);
    EXPECT_EQ(requester.breakdowns[0].cycles[kLevelCrossbar], 4u);
    EXPECT_EQ(requester.breakdowns[2].cycles[kLevelCrossbar], 7u);  // 3 waiting, 4 crossing
    EXPECT_TRUE(requester.early_refused);
}

namespace {
// A block that only records which requester each call came from.
struct IdRecorder final : sc_core::sc_module {
    TargetSocket<IdRecorder> up;
    std::vector<int> ids;
    explicit IdRecorder(sc_core::sc_module_name name) : sc_core::sc_module(name), up("up") {
        up.register_b_transport<&IdRecorder::b_transport>(this);
    }
    void b_transport(int id, tlm::tlm_generic_payload& gp, sc_core::sc_time&) {
        ids.push_back(id);
        gp.set_response_status(tlm::TLM_OK_RESPONSE);
    }
};
struct Caller final : sc_core::sc_module {
    InitiatorSocket<Caller> socket;
    explicit Caller(sc_core::sc_module_name name) : sc_core::sc_module(name), socket("s") {}
    tlm::tlm_response_status call(bool blocking) {
        MemoryPayload gp;
        sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
        tlm::tlm_phase phase = tlm::BEGIN_REQ;
        if (blocking)
            socket->b_transport(gp, delay);
        else
            socket->nb_transport_fw(gp, phase, delay);
        return gp.get_response_status();
    }
};
}  // namespace

// The target socket hands each requester its own index, in the order they bound, and refuses a
// call the block registered nothing for.
TEST(MemoryContract, TheTargetSocketNamesEachRequesterInBindOrder) {
    IdRecorder block("block");
    Caller a("a"), b("b"), c("c");
    b.socket.bind(block.up);
    c.socket.bind(block.up);
    a.socket.bind(block.up);
    test::elaborate();
    for (Caller* x : {&a, &b, &c, &a}) EXPECT_EQ(x->call(true), tlm::TLM_OK_RESPONSE);
    EXPECT_EQ(block.ids, (std::vector<int>{2, 0, 1, 2}));
    EXPECT_EQ(a.call(false), tlm::TLM_COMMAND_ERROR_RESPONSE);  // no nb_transport_fw registered
}

TEST(LineMap, AgreesWithAStandardMap) {
    std::mt19937_64 rng(11);
    for (const uint64_t span : {uint64_t(40), uint64_t(5000), uint64_t(1) << 40}) {
        LineMap map;
        std::unordered_map<uint64_t, uint32_t> reference;
        std::vector<uint64_t> lines;
        for (int op = 0; op < 200000; ++op) {
            const uint64_t line =
                lines.empty() || rng() % 3 == 0 ? rng() % span : lines[rng() % lines.size()];
            const uint32_t* found = map.find(line);
            const auto it = reference.find(line);
            ASSERT_EQ(found != nullptr, it != reference.end()) << "line " << line;
            if (found) {
                ASSERT_EQ(*found, it->second);
            }
            switch (rng() % 3) {
                case 0:
                case 1: {
                    const uint32_t value = uint32_t(rng());
                    map.set(line, value);
                    reference[line] = value;
                    lines.push_back(line);
                    break;
                }
                case 2:
                    if (uint32_t* v = map.find(line)) {
                        map.erase(v);
                        reference.erase(line);
                    }
                    break;
            }
            // Keep the live set bounded, as fills in flight are.
            if (reference.size() > 3000) {
                const uint64_t drop = reference.begin()->first;
                map.erase(map.find(drop));
                reference.erase(drop);
            }
        }
        for (const auto& [line, value] : reference) {
            const uint32_t* found = map.find(line);
            ASSERT_NE(found, nullptr);
            EXPECT_EQ(*found, value);
        }
    }
}

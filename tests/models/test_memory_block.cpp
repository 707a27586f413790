// Memory-path blocks built from the registry (models/memory_block.h), here the stream buffer,
// checked against a timeline worked by hand, under both engines' calls.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "models/cache.h"
#include "models/memory_block.h"
#include "models/transaction.h"

using namespace rtsim;

namespace {

std::unique_ptr<MemoryBlock> stream_buffer(const char* name, int entries, int depth,
                                           int hit_latency_cycles, uint64_t limit = ~0ull) {
    MemoryBlockSetting setting;
    setting.level = kLevelDram;
    setting.address_limit_bytes = limit;
    const nlohmann::json config = {
        {"entries", entries}, {"depth", depth}, {"hit_latency_cycles", hit_latency_cycles}};
    return MemoryBlockRegistry::at("stream_buffer").make(name, config, setting);
}

std::map<std::string, uint64_t> counters(const StatsRegistry& reg) {
    std::map<std::string, uint64_t> out;
    for (const auto& e : reg.entries()) out[e.name] = *e.value;
    return out;
}

// The requests of the timeline, each a read unless `write`.
struct Step {
    uint64_t addr;
    Cycle at;
    bool write = false;
};

// A stream buffer of 4 lines, reading 2 ahead, 2-cycle hits, over a memory of latency 40; lines
// of 64 bytes:
//   read    0 at 100: miss, below at 100, back at 140; reads 64 and 128 ahead at 100 (there at 140)
//   read   64 at 150: hit, there: 152; reads 192 ahead at 150 (there at 190)
//   read  128 at 151: hit: 153; reads 256 ahead (191)
//   read  192 at 160: hit on a line on its way (190): 192, a late hit; reads 320 ahead (200)
//   read 1024 at 170: miss, 210; reads 1088 and 1152 ahead: the buffer is full (256, 320, 1088,
//                     1152)
//   read 2048 at 180: miss, 220; reads 2112 and 2176 ahead, dropping 256 and 320 (unused)
//   write 1088 at 190: passes through and drops 1088 (unused)
//   read 1088 at 200: miss, 240; 1152 is held, reads 1216 ahead
// Reads 7, hits 3 (1 late), lines read ahead 10, unused 3, writes 1.
const std::vector<Step> kSteps = {{0, 100},    {64, 150},   {128, 151},        {192, 160},
                                  {1024, 170}, {2048, 180}, {1088, 190, true}, {1088, 200}};
const std::vector<Cycle> kAnswers = {140, 152, 153, 192, 210, 220, 240};

void expect_counters(const StatsRegistry& reg, const std::string& block) {
    const auto c = counters(reg);
    EXPECT_EQ(c.at(block + ".reads"), 7u);
    EXPECT_EQ(c.at(block + ".hits"), 3u);
    EXPECT_EQ(c.at(block + ".late_hits"), 1u);
    EXPECT_EQ(c.at(block + ".read_aheads"), 10u);
    EXPECT_EQ(c.at(block + ".unused_read_aheads"), 3u);
    EXPECT_EQ(c.at(block + ".writes"), 1u);
}

// Sends each step through its socket as a stage at the step's cycle (after the answers due
// then: a line there at t is there for a read at t), and records when each read is answered.
struct TimedRequester final : sc_core::sc_module, StageHandler {
    InitiatorSocket<TimedRequester> socket;
    StageQueue* queue;
    PayloadPool pool;
    std::vector<Step> steps;
    std::vector<Cycle> answers;
    TimedRequester(sc_core::sc_module_name name, StageQueue* q)
        : sc_module(name), socket("socket"), queue(q) {
        socket.register_nb_transport_bw(this, &TimedRequester::nb_transport_bw);
    }
    void plan(const std::vector<Step>& s) {
        steps = s;
        for (uint32_t i = 0; i < steps.size(); ++i)
            queue->schedule(steps[i].at, StageQueue::kSlotOrder, this, 0, i);
    }
    void run_stage(uint32_t, uint32_t i, uint32_t, Cycle t) override {
        const Step& s = steps[i];
        tlm::tlm_generic_payload& gp =
            pool.acquire(s.write ? tlm::TLM_WRITE_COMMAND : tlm::TLM_READ_COMMAND, s.addr, 64, t);
        tlm::tlm_phase phase = tlm::BEGIN_REQ;
        sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
        const tlm::tlm_sync_enum status = socket->nb_transport_fw(gp, phase, delay);
        if (s.write) {
            EXPECT_EQ(status, tlm::TLM_COMPLETED);  // nothing waits for a posted write here
            pool.release(gp);
        } else {
            EXPECT_EQ(status, tlm::TLM_UPDATED);
            EXPECT_EQ(phase, tlm::END_REQ);
        }
    }
    tlm::tlm_sync_enum nb_transport_bw(tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time&) {
        EXPECT_EQ(phase, tlm::BEGIN_RESP);
        EXPECT_EQ(gp.get_response_status(), tlm::TLM_OK_RESPONSE);
        answers.push_back(queue->now());
        pool.release(gp);
        return tlm::TLM_COMPLETED;
    }
};

// Calls a block through its socket as the fast engine does (b_transport, LtPort).
struct LtRequester final : sc_core::sc_module {
    InitiatorSocket<LtRequester> socket;
    LtPort port{socket};
    explicit LtRequester(sc_core::sc_module_name name) : sc_module(name), socket("socket") {}
};

// A block over a memory of `latency_cycles`, called through its socket by a requester as the
// fast engine calls it, its counters in `reg`; elaborated.
struct LtRig {
    IdealMemory memory;
    std::unique_ptr<MemoryBlock> block;
    LtRequester requester{"requester"};
    StatsRegistry reg;
    LtRig(Cycle latency_cycles, std::unique_ptr<MemoryBlock> b)
        : memory("memory", latency_cycles), block(std::move(b)) {
        block->bind_below(memory.up);
        requester.socket.bind(block->target_socket());
        block->register_stats(reg);
        sc_core::sc_start(sc_core::SC_ZERO_TIME);  // elaboration binds the sockets
    }
    LtPort& port() { return requester.port; }
};

}  // namespace

TEST(StreamBuffer, LooselyTimedReadsFollowTheHandTimeline) {
    LtRig rig(40, stream_buffer("sb", 4, 2, 2));
    std::vector<Cycle> answers;
    for (const Step& s : kSteps) {
        if (s.write)
            rig.port().write(s.addr, 64, s.at);
        else
            answers.push_back(rig.port().read(s.addr, 64, s.at));
    }
    EXPECT_EQ(answers, kAnswers);
    expect_counters(rig.reg, "sb");
}

TEST(StreamBuffer, TimeOrderedReadsFollowTheSameTimeline) {
    StageQueue q;
    IdealMemory memory("memory", 40);
    auto block = stream_buffer("sb", 4, 2, 2);
    block->bind_below(memory.up);
    TimedRequester requester("requester", &q);
    requester.socket.bind(block->target_socket());
    memory.set_stage_queue(&q);
    block->set_stage_queue(&q);
    StatsRegistry reg;
    block->register_stats(reg);
    sc_core::sc_start(sc_core::SC_ZERO_TIME);
    requester.plan(kSteps);
    while (!q.empty()) q.run_next();
    EXPECT_EQ(requester.answers, kAnswers);
    expect_counters(reg, "sb");
}

// A stream is read ahead only up to the caches' address limit, and a read deeper than the buffer
// reads no more lines ahead than it holds.
TEST(StreamBuffer, ReadsNothingAheadPastTheLimitOrBeyondItsEntries) {
    IdealMemory memory("memory", 10);
    auto near_limit = stream_buffer("near", 8, 4, 1, /*limit=*/3 * 64);
    near_limit->bind_below(memory.up);
    auto shallow = stream_buffer("shallow", 2, 8, 1);
    shallow->bind_below(memory.up);
    LtRequester a("a"), b("b");
    a.socket.bind(near_limit->target_socket());
    b.socket.bind(shallow->target_socket());
    StatsRegistry reg;
    near_limit->register_stats(reg);
    shallow->register_stats(reg);
    sc_core::sc_start(sc_core::SC_ZERO_TIME);
    a.port.read(0, 64, 0);  // lines 1 and 2 end at the limit; 3 and 4 would pass it
    b.port.read(0, 64, 0);
    const auto c = counters(reg);
    EXPECT_EQ(c.at("near.read_aheads"), 2u);
    EXPECT_EQ(c.at("shallow.read_aheads"), 2u);
    EXPECT_EQ(c.at("shallow.unused_read_aheads"), 0u);
}

// Functional warming leaves the lines a read would, and counts nothing: a timed read after
// warming finds the line the warmed miss read ahead.
TEST(StreamBuffer, WarmingLeavesTheLinesAndCountsNothing) {
    LtRig rig(40, stream_buffer("sb", 4, 2, 2));
    rig.port().warm(0, 64);
    for (const auto& [name, value] : counters(rig.reg)) EXPECT_EQ(value, 0u) << name;
    EXPECT_EQ(rig.port().read(64, 64, 10), 12u);  // there since warming: the hit latency only
    EXPECT_EQ(counters(rig.reg).at("sb.hits"), 1u);
}

namespace {

// A cache block's section: 4 KiB of 2 ways, 64-byte lines, 12-cycle hits, one bank.
nlohmann::json cache_config() {
    return {{"size_kib", 4},
            {"ways", 2},
            {"line_bytes", 64},
            {"hit_latency_cycles", 12},
            {"mshrs", 4},
            {"banks", 1},
            {"replacement", "lru"},
            {"rrpv_bits", 2},
            {"write_policy", "write_back"}};
}

std::unique_ptr<MemoryBlock> cache_block(const char* name) {
    MemoryBlockSetting setting;
    setting.level = kLevelDram;
    setting.address_limit_bytes = 1 << 20;
    const nlohmann::json config = cache_config();
    EXPECT_EQ(MemoryBlockRegistry::at("cache").check(config), "");
    return MemoryBlockRegistry::at("cache").make(name, config, setting);
}

// A cache level of 12-cycle hits over a memory of latency 40: a read at 100 is looked up at 112,
// misses, and its line is back at 152; the same line at 200 hits at 212; another line's read at
// 200 waits for the bank behind it (one bank, one lookup a cycle), is looked up from 201, misses,
// and is back at 201 + 12 + 40 = 253.
const std::vector<Step> kCacheSteps = {{0, 100}, {0, 200}, {4096, 200}};
const std::vector<Cycle> kCacheAnswers = {152, 212, 253};

}  // namespace

TEST(CacheBlock, LooselyTimedReadsFollowTheHandTimeline) {
    LtRig rig(40, cache_block("l3"));
    std::vector<Cycle> answers;
    for (const Step& s : kCacheSteps) answers.push_back(rig.port().read(s.addr, 64, s.at));
    EXPECT_EQ(answers, kCacheAnswers);
    const auto c = counters(rig.reg);
    EXPECT_EQ(c.at("l3.cache.hits"), 1u);
    EXPECT_EQ(c.at("l3.cache.misses"), 2u);
}

TEST(CacheBlock, TimeOrderedReadsFollowTheSameTimeline) {
    StageQueue q;
    IdealMemory memory("memory", 40);
    auto block = cache_block("l3");
    block->bind_below(memory.up);
    TimedRequester requester("requester", &q);
    requester.socket.bind(block->target_socket());
    memory.set_stage_queue(&q);
    block->set_stage_queue(&q);
    sc_core::sc_start(sc_core::SC_ZERO_TIME);
    requester.plan(kCacheSteps);
    while (!q.empty()) q.run_next();
    EXPECT_EQ(requester.answers, kCacheAnswers);
}

// What the schema's ranges cannot say is checked by the block: its sets, its policy's ways.
TEST(CacheBlock, RefusesAGeometryItCannotBuild) {
    nlohmann::json config = cache_config();
    config["size_kib"] = 3;
    const auto check = MemoryBlockRegistry::at("cache").check;
    EXPECT_NE(check(config).find("size_kib: "), std::string::npos) << check(config);
    config["ways"] = 3;  // 3 KiB of 3 ways: 16 sets
    EXPECT_EQ(check(config), "");
    config["replacement"] = "tree_plru";
    EXPECT_EQ(check(config).rfind("replacement: tree_plru needs a power-of-two number of ways", 0),
              0u)
        << check(config);
}

// The fast engine may meet a read after one later in simulated time. A line read ahead at 200
// was not yet asked for at 150: a read of it at 150 misses (below at 150, back at 190) as in time
// order, and is counted as out of order.
TEST(StreamBuffer, AReadBeforeItsLineWasReadAheadMisses) {
    LtRig rig(40, stream_buffer("sb", 4, 1, 2));
    EXPECT_EQ(rig.port().read(0, 64, 200), 240u);   // reads 64 ahead at 200
    EXPECT_EQ(rig.port().read(64, 64, 150), 190u);  // before that: a miss
    EXPECT_EQ(rig.port().read(64, 64, 250), 252u);  // after it: the line read ahead
    const auto c = counters(rig.reg);
    EXPECT_EQ(c.at("sb.hits"), 1u);
    EXPECT_EQ(c.at("sb.out_of_order_reads"), 1u);
}

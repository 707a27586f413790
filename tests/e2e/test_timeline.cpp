// Small cases whose every cycle is worked out by hand, run through the whole simulator: a trace
// written here (one ray, a node then a triangle, both missing every cache) replayed by `rtsim
// run` on a config whose every latency is stated. The expected cycles come from the timeline in
// the comments, not from the simulator. Every case runs through both fidelities: the fast model
// and the time-ordered reference (sim.fidelity = accurate) must each match the hand timeline.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "support/scratch_dir.h"
#include "workloads/trace_file.h"

using namespace rtsim;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// One inner node (64 bytes at 0x10000000) and one triangle (48 bytes right after it): both in
// the same 2 KiB DRAM row and each in its own 64-byte line.
json tiny_layout_metadata(int nodes = 1) {
    return {{"scene", {{"name", "hand-made"}, {"triangles", 1}}},
            {"bvh",
             {{"builder", "sah"},
              {"width", 2},
              {"node_format", "full"},
              {"layout",
               {{"node_base_addr", 0x10000000},
                {"node_size_bytes", 64},
                {"inner_node_count", nodes},
                {"triangle_base_addr", 0x10000000 + 64 * nodes},
                {"triangle_size_bytes", 48},
                {"triangle_count", 1}}}}},
            {"workload", {{"rays", "primary"}}}};
}

// `rays` rays, each a node step then a triangle step; with `own_nodes`, ray i visits node i (its
// own line), else all visit node 0.
std::string write_trace(const fs::path& path, int rays, bool own_nodes = false) {
    TraceWriter w(path.string(), tiny_layout_metadata(own_nodes ? rays : 1).dump(), 16);
    for (int i = 0; i < rays; ++i) {
        TraceRecord r;
        r.ray_id = uint32_t(i);
        Step node{}, tri{};
        node.kind = StepKind::Node;
        node.id = own_nodes ? uint32_t(i) : 0;
        node.count = 2;
        tri.kind = StepKind::Triangle;
        tri.id = 0;
        tri.count = 1;
        r.steps.assign(2, node);
        r.steps[1] = tri;
        w.add(r);
    }
    w.finish();
    return path.string();
}

// Every latency stated, so schema defaults can change without moving the expected cycles.
const char* kStatedConfig =
    " --set core.count=1 --set core.issue_width=1 --set core.issue_latency_cycles=1"
    " --set core.node_step_instructions=1 --set core.triangle_step_instructions=1"
    " --set core.ray_setup_instructions=1 --set box_unit.latency_cycles=8"
    " --set box_unit.width=8 --set triangle_unit.latency_cycles=18"
    " --set l1.hit_latency_cycles=4 --set l1.banks=1 --set l1.mshrs=16"
    " --set l2.hit_latency_cycles=30 --set l2.mshrs=64 --set crossbar.bytes_per_cycle=0"
    " --set dram.channels=1 --set dram.banks=1 --set dram.row_bytes=2048"
    " --set dram.bytes_per_cycle=16 --set dram.burst_bytes=64 --set dram.latency_cycles=150"
    " --set dram.t_rcd_cycles=14 --set dram.t_cas_cycles=14 --set dram.t_ccd_cycles=4"
    " --set dram.t_rp_cycles=14";

const char* const kFidelities[] = {"fast", "accurate"};

json run_trace(const std::string& trace, const std::string& extra, const std::string& name,
               const std::string& fidelity) {
    const fs::path out = test::scratch_dir() / (name + "_" + fidelity);
    const std::string cmd = std::string(RTSIM_BINARY) + " run -q --trace '" + trace + "'" +
                            kStatedConfig + extra + " --set sim.fidelity=" + fidelity + " --out '" +
                            out.string() + "' 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(out / "stats.json");
    return json::parse(in);
}

}  // namespace

// One ray, one slot:
//   0    ray setup: 1 instruction, issue latency 1                          -> 1
//   1    node step: issue -> fetch at 2; L1 lookup 4 -> miss at 6; L2 lookup 30 -> miss at 36;
//        DRAM: empty bank, tRCD 14 -> column at 50, tCAS 14 -> data at 64, one 64-byte burst at
//        16 B/cycle -> 68, controller latency 150 -> 218; box test (2 children, 1 op) 8 -> 226
//   226  triangle step: issue -> 227; L1 miss at 231; L2 miss at 261; DRAM: the same row is
//        open, so column at 261, data 275, burst 279, +150 -> 429; triangle test 18 -> 447
TEST(Timeline, OneRayMissingEveryLevelByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "one_ray.rtt", 1);
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);

        const json s = run_trace(trace, " --set core.ray_slots=1", "one_ray", fidelity);
        EXPECT_EQ(s["total_cycles"].get<uint64_t>(), 447u);
        const json& st = s["stalls"]["total"];
        EXPECT_EQ(st["issue"].get<uint64_t>(), 1u + 1 + 1);
        EXPECT_EQ(st["l1"].get<uint64_t>(), 4u + 4);
        EXPECT_EQ(st["l2"].get<uint64_t>(), 30u + 30);
        EXPECT_EQ(st["dram"].get<uint64_t>(), (218u - 36) + (429 - 261));
        EXPECT_EQ(st["box_unit"].get<uint64_t>(), 8u);
        EXPECT_EQ(st["triangle_unit"].get<uint64_t>(), 18u);
        EXPECT_EQ(st["no_work"].get<uint64_t>(), 0u);
        EXPECT_EQ(s["bandwidth"]["dram"]["row_hits"].get<uint64_t>(), 1u);
        EXPECT_EQ(s["bandwidth"]["dram"]["row_empty"].get<uint64_t>(), 1u);
    }
}

// Two identical rays on two slots, one issue per cycle: the slots take turns at the port, and
// the second ray's fetches find the first one's fills in flight (merged, no second DRAM read):
//   0    A's setup issues at 0 -> 1; B's waits for the port -> issues at 1 -> 2
//   1    A's node step: the port took B at 1, so it issues at 2 -> fetch 3; L1 miss at 7, L2
//        miss at 37, DRAM column 51, data 65, burst 69, +150 -> 219; box unit 219 -> 227
//   2    B's node step: port at 3 -> fetch 4; L1 lookup 4 -> 8 finds the line filling until
//        219; the box pipeline took A's op at 219, so B's enters at 220 -> 228
//   227  A's triangle: fetch 228, L1 miss 232, L2 miss 262, DRAM row hit: column 262, data
//        276, burst 280, +150 -> 430; triangle unit 430 -> 448
//   228  B's triangle: fetch 229, lookup 233 finds the line filling until 430; the triangle
//        pipeline took A's op at 430, so B's enters at 431 -> 449
TEST(Timeline, TwoRaysShareFillsAndPipelinesByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "two_rays.rtt", 2);
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);

        const json s = run_trace(trace, " --set core.ray_slots=2", "two_rays", fidelity);
        EXPECT_EQ(s["total_cycles"].get<uint64_t>(), 449u);
        const json& st = s["stalls"]["total"];
        // Issue latency 1 on each of 6 issues, and 3 port waits (B's setup, A's and B's node
        // steps).
        EXPECT_EQ(st["issue"].get<uint64_t>(), 6u + 1 + 1 + 1);
        // B's merged waits are charged where the fills were: L2 until they reached DRAM, then DRAM.
        EXPECT_EQ(st["dram"].get<uint64_t>(), (219u - 37) + (430 - 262) + (219 - 37) + (430 - 262));
        EXPECT_EQ(s["caches"]["l1_total"]["misses"].get<uint64_t>(), 2u);
        EXPECT_EQ(s["caches"]["l1_total"]["merged_misses"].get<uint64_t>(), 2u);
        EXPECT_EQ(s["bandwidth"]["dram"]["bytes"].get<uint64_t>(), 128u);
        EXPECT_EQ(s["stalls"]["total"]["unaccounted_cycles"].get<int64_t>(), 0);
    }
}

// Two rays on two slots, each with its own node line, and one L1 MSHR: a miss waits for the
// MSHR, first come first served, and holds it until its data is there.
//   0    A's setup -> 1; B's waits for the port -> 2
//   1    A's node step: port at 2 -> fetch 3; L1 miss at 7 takes the MSHR; L2 miss at 37;
//        DRAM empty bank: column 51, data 65, burst 69, +150 -> 219; box 219 -> 227
//   2    B's node step (node 1, another line): port at 3 -> fetch 4; L1 miss at 8 waits for
//        the MSHR until 219; L2 miss at 249; DRAM row hit (bank free since 55): column 249,
//        data 263, burst 267, +150 -> 417; box 417 -> 425
//   227  A's triangle: fetch 228; L1 miss at 232 waits for the MSHR until 417; L2 miss at 447;
//        DRAM row hit: column 447, data 461, burst 465, +150 -> 615; triangle 615 -> 633
//   425  B's triangle: fetch 426; lookup at 430 finds A's fill in flight (merged) until 615;
//        the triangle pipeline took A's op at 615, so B's enters at 616 -> 634
// Stalls: issue A 1+2+1, B 2+2+1; L1 A 4 + (4+185), B (4+211) + 4; L2 A 30+30, B 30 + 17 of
// the merged wait (A's fill was at the L2 from 430 to 447); DRAM A 182+168, B 168 + 168;
// box 8+8; triangle 18 + 19; no work: A's slot from 633 to 634.
TEST(Timeline, OneMshrQueuesMissesByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "mshr.rtt", 2, true);
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);
        const json s =
            run_trace(trace, " --set core.ray_slots=2 --set l1.mshrs=1", "one_mshr", fidelity);
        EXPECT_EQ(s["total_cycles"].get<uint64_t>(), 634u);
        const json& st = s["stalls"]["total"];
        EXPECT_EQ(st["issue"].get<uint64_t>(), 4u + 5);
        EXPECT_EQ(st["l1"].get<uint64_t>(), 4u + 189 + 215 + 4);
        EXPECT_EQ(st["l2"].get<uint64_t>(), 30u + 30 + 30 + 17);
        EXPECT_EQ(st["dram"].get<uint64_t>(), 182u + 168 + 168 + 168);
        EXPECT_EQ(st["box_unit"].get<uint64_t>(), 16u);
        EXPECT_EQ(st["triangle_unit"].get<uint64_t>(), 18u + 19);
        EXPECT_EQ(st["no_work"].get<uint64_t>(), 1u);
        EXPECT_EQ(st["unaccounted_cycles"].get<int64_t>(), 0);
        EXPECT_EQ(s["caches"]["l1_total"]["misses"].get<uint64_t>(), 3u);
        EXPECT_EQ(s["caches"]["l1_total"]["merged_misses"].get<uint64_t>(), 1u);
        EXPECT_EQ(s["counters"]["l1[0].mshr_wait_cycles"].get<uint64_t>(), 211u + 185);
        EXPECT_EQ(s["bandwidth"]["dram"]["row_hits"].get<uint64_t>(), 2u);
        EXPECT_EQ(s["bandwidth"]["dram"]["row_empty"].get<uint64_t>(), 1u);
    }
}

// The same ray on the command-level DRAM model (DDR4-3200: tRCD = CL = 22, a burst in 4
// device cycles), with the chip clocked at the device's 1.6 GHz so a chip cycle is a device
// cycle, and no refresh:
//   0    ray setup -> 1
//   1    node step: fetch at 2; L1 miss at 6; L2 miss at 36; DRAM: ACT at 36, RD at 58, last
//        data beat 58 + 22 + 4 = 84, +150 -> 234; box test 8 -> 242
//   242  triangle step: fetch 243; L1 miss 247; L2 miss 277; DRAM: the row is open (the
//        triangle is the next burst of it), RD at 277, data 303, +150 -> 453; triangle 18 -> 471
TEST(Timeline, OneRayOnTheCommandLevelDramByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "one_ray_cmd.rtt", 1);
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);
        const json s = run_trace(trace,
                                 " --set core.ray_slots=1 --set dram.model=command"
                                 " --set dram.device=DDR4_8Gb_x8_3200 --set dram.refresh=false"
                                 " --set clock_ghz=1.6",
                                 "one_ray_cmd", fidelity);
        EXPECT_EQ(s["total_cycles"].get<uint64_t>(), 471u);
        EXPECT_EQ(s["stalls"]["total"]["dram"].get<uint64_t>(), (234u - 36) + (453 - 277));
        const json& d = s["bandwidth"]["dram"];
        EXPECT_EQ(d["row_hits"].get<uint64_t>(), 1u);
        EXPECT_EQ(d["row_empty"].get<uint64_t>(), 1u);
        EXPECT_EQ(d["commands"]["act"].get<uint64_t>(), 1u);
        // Energy by hand: one activate-precharge pair 4200 pJ, two read bursts 2 x 2784 pJ.
        EXPECT_NEAR(d["energy_pj"]["activate"].get<double>(), 4200.0, 1e-6);
        EXPECT_NEAR(d["energy_pj"]["read"].get<double>(), 2 * 2784.0, 1e-6);
        EXPECT_EQ(s["out_of_order"]["dram_requests"].get<uint64_t>(), 0u);
    }
}

// Two cores, one slot each, one ray each (ray i to core i), both rays the same node and triangle:
// they share the L2 and the crossbar (8 bytes per cycle, so a 64-byte line crosses in 8 cycles).
// Same-cycle ties go to the lower core.
//   0    both setups -> 1
//   1    both node steps: fetch at 2; each core's own L1 misses at 6; both reach the L2 at 6 (a
//        tie): core 0's lookup misses at 36 and goes to DRAM (empty bank: column 50, data 64,
//        burst 68, +150 -> 218); core 1's finds the fill in flight and waits for it (merged)
//   218  the line returns to both: core 0's crosses the link 218..226, core 1's 226..234;
//        box tests 226 -> 234 and 234 -> 242 (each core has its own box unit)
//   234  core 0's triangle: fetch 235; L1 miss 239; L2 miss 269; DRAM row hit: column 269,
//        data 283, burst 287, +150 -> 437; link 437..445; triangle unit 445 -> 463
//   242  core 1's triangle: fetch 243; L1 miss 247; L2 lookup 277 finds core 0's fill in
//        flight until 437; link after core 0's line: 445..453; triangle unit 453 -> 471
TEST(Timeline, TwoCoresShareTheL2AndTheCrossbarByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "two_cores.rtt", 2);
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);
        const json s = run_trace(trace,
                                 " --set core.count=2 --set core.ray_slots=1"
                                 " --set crossbar.bytes_per_cycle=8",
                                 "two_cores", fidelity);
        EXPECT_EQ(s["total_cycles"].get<uint64_t>(), 471u);
        EXPECT_EQ(s["caches"]["l2"]["misses"].get<uint64_t>(), 2u) << s["caches"].dump();
        EXPECT_EQ(s["bandwidth"]["dram"]["bytes"].get<uint64_t>(), 128u);
        EXPECT_EQ(s["bandwidth"]["crossbar"]["bytes"].get<uint64_t>(), 4u * 64);
        EXPECT_EQ(s["stalls"]["total"]["unaccounted_cycles"].get<int64_t>(), 0);
    }
}

namespace {

// Rays given as lists of steps: 'n' + id a node step (node `id`'s line), 't' the triangle.
std::string write_steps(const fs::path& path, const std::vector<std::string>& rays, int nodes) {
    TraceWriter w(path.string(), tiny_layout_metadata(nodes).dump(), 16);
    for (size_t i = 0; i < rays.size(); ++i) {
        TraceRecord r;
        r.ray_id = uint32_t(i);
        for (size_t c = 0; c < rays[i].size(); ++c) {
            Step s{};
            if (rays[i][c] == 't') {
                s.kind = StepKind::Triangle;
                s.count = 1;
            } else {
                s.kind = StepKind::Node;
                s.id = uint32_t(rays[i][++c] - '0');
                s.count = 2;
            }
            r.steps.push_back(s);
        }
        w.add(r);
    }
    w.finish();
    return path.string();
}

}  // namespace

// A lookup and a fill of the same line in the same cycle: fills complete first, so the lookup
// hits. The L2's lines are 128 bytes, two of the L1's: node 0's line and the triangle's share
// one. Lines cross the crossbar in one cycle (64 bytes a cycle); L1 lookups take 4 cycles,
// triangle tests 25. Ray A is the triangle then node 0, ray B the triangle twice then node 0,
// on one core's two slots:
//   0    setups: A -> 1, B -> 2
//   2    A's triangle step -> fetch 3; L1 miss at 7, L2 miss at 37; DRAM: two bursts; the line
//        crosses back: F
//   3    B's triangle step -> fetch 4; lookup at 8 finds A's miss in flight: merged, also F
//   F    the triangle unit takes A's test at F (-> F+25) and B's at F+1 (-> F+26)
//   F+25 A's node step -> fetch F+26; L1 miss at F+30; the L2 holds the line (it came with the
//        triangle's): hit at F+60; the line crosses, and the L1's fill completes at F+61
//   F+26 B's second triangle step -> fetch F+27; L1 hit at F+31; triangle unit -> F+56
//   F+56 B's node step -> fetch F+57; its lookup ends at F+61, as A's fill completes: a hit
//   The L1: misses for A's triangle and node; three hits, one of them a merged miss (B's first
//   triangle, which found its line filling), the others B's second triangle and its node; the
//   L2: one miss, one hit.
// The fill's completion is only known at F+60 (when the L2 answers), after the lookup's event
// was made at F+57, so an engine that ordered the two by when they were made would see a
// merged miss.
TEST(Timeline, AFillCompletesBeforeALookupInTheSameCycleByHand) {
    const std::string trace = write_steps(test::scratch_dir() / "tie.rtt", {"tn0", "ttn0"}, 1);
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);
        const json s = run_trace(trace,
                                 " --set core.ray_slots=2 --set l2.line_bytes=128"
                                 " --set crossbar.bytes_per_cycle=64"
                                 " --set triangle_unit.latency_cycles=25",
                                 "tie", fidelity);
        const json& l1 = s["caches"]["l1_total"];
        EXPECT_EQ(l1["misses"].get<uint64_t>(), 2u) << l1.dump();
        EXPECT_EQ(l1["merged_misses"].get<uint64_t>(), 1u) << l1.dump();
        EXPECT_EQ(l1["hits"].get<uint64_t>(), 3u) << l1.dump();
        EXPECT_EQ(s["caches"]["l2"]["misses"].get<uint64_t>(), 1u);
        EXPECT_EQ(s["caches"]["l2"]["hits"].get<uint64_t>(), 1u);
    }
}

// One ray as in OneRayMissingEveryLevelByHand, whose triangle is the line after its node, with a
// next-line prefetcher (models/prefetcher.h) at the L2, then at the L1 (one L2 bank), then at
// an L1 with one MSHR:
//   L2: the node's L2 miss at 36 fetches the node line (DRAM until 218) and, an MSHR being
//       free, the triangle's line at 36 too (the same open row behind it: back long before 261).
//       226: triangle step, fetch 227, L1 miss at 231, L2 lookup 261 finds the prefetched line:
//       data at 261; triangle 18 -> 279. DRAM stalls: the node's 218 - 36 only.
//   L1: the node's L1 miss at 6 also prefetches the triangle's line: its L2 lookup waits for
//       the bank until 7, misses at 37, DRAM behind the node's: back before 231. 226: triangle
//       step, fetch 227, L1 lookup 231 hits; triangle 18 -> 249.
//   L1 with one MSHR: the node's miss holds it, the prefetch is dropped: the 447 cycles of the
//       ray without a prefetcher.
TEST(Timeline, ANextLinePrefetchServesTheTriangleByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "prefetch.rtt", 1);
    struct Case {
        const char* name;
        const char* extra;
        uint64_t cycles;
        const char* cache;  // the caches section with the prefetcher
        uint64_t issued, dropped, useful, dram_bytes, dram_stall;
    };
    const Case cases[] = {
        {"l2", " --set l2.prefetcher=next_line", 279, "l2", 1, 0, 1, 128, 218 - 36},
        {"l1", " --set l1.prefetcher=next_line --set l2.banks=1", 249, "l1_total", 1, 0, 1, 128,
         218 - 36},
        {"l1_one_mshr", " --set l1.prefetcher=next_line --set l1.mshrs=1", 447, "l1_total", 0, 1, 0,
         128, (218 - 36) + (429 - 261)},
    };
    for (const Case& c : cases)
        for (const char* fidelity : kFidelities) {
            SCOPED_TRACE(std::string(c.name) + " " + fidelity);
            const json s = run_trace(trace, std::string(" --set core.ray_slots=1") + c.extra,
                                     std::string("prefetch_") + c.name, fidelity);
            EXPECT_EQ(s["total_cycles"].get<uint64_t>(), c.cycles);
            const json& pf = s["caches"][c.cache]["prefetch"];
            EXPECT_EQ(pf["issued"].get<uint64_t>(), c.issued) << pf.dump();
            EXPECT_EQ(pf["dropped"].get<uint64_t>(), c.dropped) << pf.dump();
            EXPECT_EQ(pf["useful"].get<uint64_t>(), c.useful) << pf.dump();
            EXPECT_EQ(s["bandwidth"]["dram"]["bytes"].get<uint64_t>(), c.dram_bytes);
            EXPECT_EQ(s["stalls"]["total"]["dram"].get<uint64_t>(), c.dram_stall);
            EXPECT_EQ(s["stalls"]["total"]["unaccounted_cycles"].get<int64_t>(), 0);
        }
}

// Three rays, each with its own node line, and one L1 MSHR: misses waiting for it are served
// first come, first served.
//   0    setups: A -> 1, B -> 2, C -> 3 (one issue a cycle, the longest waiting first)
//   3    A's node step (ready since 1) -> fetch 4; B's at 4 -> 5; C's at 5 -> 6
//   A: L1 miss at 8 takes the MSHR; L2 miss 38; DRAM empty: column 52, data 66, burst 70, +150
//      -> 220; box 220 -> 228
//   B: L1 miss at 9 waits; C: at 10 waits
//   220  the MSHR goes to B (first to wait): L2 miss 250; DRAM row hit: column 250, data 264,
//        burst 268, +150 -> 418; box 418 -> 426
//   228  A's triangle step -> fetch 229; L1 miss at 233 waits behind C
//   418  C: L2 miss 448; column 448, data 462, burst 466, +150 -> 616; box 616 -> 624
//   616  A's triangle: L2 miss 646; column 646, data 660, burst 664, +150 -> 814; triangle
//        814 -> 832
//   426  B's triangle -> fetch 427; lookup at 431 finds A's miss (waiting) and merges: 814;
//        triangle 815 -> 833.  624: C's -> fetch 625, lookup 629 merges: triangle 816 -> 834
//   MSHR waits: B 211, C 408, A's triangle 383.
TEST(Timeline, MissesWaitingForAnMshrAreServedInOrderByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "fcfs.rtt", 3, true);
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);
        const json s =
            run_trace(trace, " --set core.ray_slots=3 --set l1.mshrs=1", "fcfs", fidelity);
        EXPECT_EQ(s["total_cycles"].get<uint64_t>(), 834u);
        EXPECT_EQ(s["counters"]["l1[0].mshr_wait_cycles"].get<uint64_t>(), 211u + 408 + 383);
        EXPECT_EQ(s["caches"]["l1_total"]["misses"].get<uint64_t>(), 4u);
        EXPECT_EQ(s["caches"]["l1_total"]["merged_misses"].get<uint64_t>(), 2u);
    }
}

// Posted writes through a one-entry write buffer: each ray writes a 16-byte hit record when it
// ends; an entry is held until the L2 has looked the write up, and a write that finds the
// buffer full waits. One slot, two identical rays; box and triangle tests take 1 cycle; lines
// cross the crossbar at 8 bytes a cycle (a 64-byte line in 8, a hit record in 2).
//   0    A's setup -> 1; node step -> fetch 2; L1 miss 6; L2 miss 36; DRAM: column 50, data
//        64, burst 68, +150 -> 218; crossing 218..226; box -> 227
//   227  A's triangle -> fetch 228; L1 miss 232; L2 miss 262; DRAM row hit: column 262, data
//        276, burst 280, +150 -> 430; crossing -> 438; triangle -> 439
//   439  A ends: its record takes the entry, crosses up 439..441, the L2 looks it up 441..471
//        (the entry is free again at 471). B takes the slot: setup -> 440; node -> fetch 441,
//        L1 hit 445, box -> 446; triangle -> fetch 447, hit 451, triangle -> 452
//   452  B ends; its record waits for the entry until 471 (19 cycles of write_buffer stall)
TEST(Timeline, AFullWriteBufferHoldsTheNextWriteByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "writes.rtt", 2);
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);
        const json s = run_trace(trace,
                                 " --set core.ray_slots=1 --set core.hit_record_bytes=16"
                                 " --set core.write_buffer_entries=1"
                                 " --set crossbar.bytes_per_cycle=8"
                                 " --set box_unit.latency_cycles=1"
                                 " --set triangle_unit.latency_cycles=1",
                                 "writes", fidelity);
        const json& st = s["stalls"]["total"];
        EXPECT_EQ(st["write_buffer"].get<uint64_t>(), 19u) << st.dump();
        EXPECT_EQ(s["counters"]["core[0].hit_record_writes"].get<uint64_t>(), 2u);
        EXPECT_EQ(s["total_cycles"].get<uint64_t>(), 471u);
        EXPECT_EQ(st["unaccounted_cycles"].get<int64_t>(), 0);
    }
}

// A sampled replay whose second window waits for the first to drain. Six rays, all on node 0
// and triangle 0, two slots, units of one ray, one unit in three from unit 0, no warm-up: rays 0
// and 3 are measured, rays 1 and 4 close them (detailed), rays 2 and 5 are fast-forwarded.
//   0    rays 0 and 1 run as in TwoRaysShareFillsAndPipelinesByHand: done at 448 and 449
//   448  slot A asks: ray 2 warms the caches; ray 3 starts a window while ray 1 runs until 449,
//        so it is held and A parks
//   449  both slots take rays 3 and 4 (A first), every fetch an L1 hit:
//        A's setup 449 -> 450; B's waits for the port -> 451
//        A's node: port at 451 -> fetch 452, hit 456, box 464; B's: port 452 -> fetch 453,
//        hit 457, the box pipeline took A's op at 456 -> 465
//        A's triangle: issue 464 -> fetch 465, hit 469, triangle 487; B's: issue 465 -> fetch
//        466, hit 470 -> 488
// No work: A parked from 448 to 449, and retired from 487 to the end at 488. Without the drain,
// A takes ray 3 at 448 while ray 1 still runs.
TEST(Timeline, ASampledWindowStartsOnceTheOneBeforeHasDrainedByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "drain.rtt", 6);
    const std::string sampled =
        " --set core.ray_slots=2 --set sim.sampled=true --set sim.sample_fast_forward=warm"
        " --set sim.sample_unit_rays=1 --set sim.sample_period_units=3"
        " --set sim.sample_warmup_rays=0 --set sim.sample_design=systematic"
        " --set sim.sample_first_unit=0";
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);
        const json s =
            run_trace(trace, sampled + " --set sim.sample_window_hold=drain", "drain", fidelity);
        EXPECT_EQ(s["sampling"]["rays_detailed"].get<uint64_t>(), 4u);
        EXPECT_EQ(s["sampling"]["simulated_cycles"].get<uint64_t>(), 488u) << s["sampling"].dump();
        EXPECT_EQ(s["stalls"]["total"]["no_work"].get<uint64_t>(), 2u);
        // Without the drain the second window overlaps the first: another timeline.
        const json free =
            run_trace(trace, sampled + " --set sim.sample_window_hold=none", "no_drain", fidelity);
        EXPECT_LT(free["sampling"]["simulated_cycles"].get<uint64_t>(), 488u);
    }
}

// A sampled replay whose window waits for the predicted cycles of what it skipped. Six rays, each
// with its own node line (triangle 0 shared), two slots, units of two rays, one unit in two
// from unit 0, no warm-up: rays 0-1 and 4-5 are measured, ray 2 closes unit 0, ray 3 is
// fast-forwarded.
//   0    rays 0 and 1: A's node misses to DRAM (column 51, +150 -> 219, box 227), B's follows
//        on the open row (column 55, burst after A's, -> 223, box 231); A's triangle misses
//        (column 262 -> 430, triangle 448), B's merges into it (triangle 449)
//   448  A takes ray 2 (closes unit 0: 448 cycles): node 2 misses (fetch 450, L2 miss 484,
//        column 484 -> 652, box 660), triangle hits (fetch 661 -> 665, triangle 683)
//   449  B asks: ray 3 is fast-forwarded and ray 4 starts a window. One unit measured, so the
//        hold is cycles in proportion to work, 448 x 3 / 6 = 224: until 673. Ray 2 is still
//        running, one of two slots: with a release share of 0 the window waits; past 673
//        it goes with the next finish, ray 2's at 683.
//   683  rays 4 (A) and 5 (B): setups 684 and 685, node fetches 686 and 687, L2 misses 720 and
//        721, DRAM columns 720 and 724 -> 888 and 892, boxes 896 and 900, triangles (L1 hits)
//        919 and 923. No work: B from 449 to 683, A from 919 to 923.
// With the default release share (0.5) one running ray of two slots does not hold the window:
// ray 4 goes out at 449 as without a hold.
TEST(Timeline, ASampledWindowWaitsForThePredictedCyclesOfWhatItSkippedByHand) {
    const std::string trace = write_trace(test::scratch_dir() / "hold.rtt", 6, true);
    const std::string sampled =
        " --set core.ray_slots=2 --set sim.sampled=true --set sim.sample_fast_forward=warm"
        " --set sim.sample_unit_rays=2 --set sim.sample_period_units=2"
        " --set sim.sample_warmup_rays=0 --set sim.sample_design=systematic"
        " --set sim.sample_first_unit=0 --set sim.sample_window_hold=predicted";
    for (const char* fidelity : kFidelities) {
        SCOPED_TRACE(fidelity);
        const json held = run_trace(
            trace, sampled + " --set sim.sample_window_hold_release_share=0", "hold", fidelity);
        EXPECT_EQ(held["sampling"]["rays_detailed"].get<uint64_t>(), 5u);
        EXPECT_EQ(held["sampling"]["simulated_cycles"].get<uint64_t>(), 923u);
        EXPECT_EQ(held["stalls"]["total"]["no_work"].get<uint64_t>(), (683u - 449) + (923 - 919));
        const json shared = run_trace(trace, sampled, "hold_share", fidelity);
        const json none =
            run_trace(trace,
                      " --set core.ray_slots=2 --set sim.sampled=true"
                      " --set sim.sample_fast_forward=warm --set sim.sample_unit_rays=2"
                      " --set sim.sample_period_units=2 --set sim.sample_warmup_rays=0"
                      " --set sim.sample_design=systematic --set sim.sample_first_unit=0"
                      " --set sim.sample_window_hold=none",
                      "hold_none", fidelity);
        EXPECT_LT(none["sampling"]["simulated_cycles"].get<uint64_t>(), 923u);
        EXPECT_EQ(shared["sampling"]["simulated_cycles"], none["sampling"]["simulated_cycles"]);
        EXPECT_EQ(shared["stalls"]["total"]["no_work"], none["stalls"]["total"]["no_work"]);
    }
}

// Ray packets: up to 64 rays traverse the BVH together, a node visited when any active ray hits
// it, with an active mask per visit. Lane utilisation (active rays / packet size per node visit)
// is what decides whether packets pay: high on coherent primary rays, low on incoherent ones.
// Optionally a packet falls back to single rays for a subtree once its utilisation drops under
// a threshold (Benthin, Wald, Woop, Ernst & Mark 2011, "Combining single and packet-ray tracing").
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "workloads/bvh.h"
#include "workloads/tracer.h"

namespace rtsim {

constexpr int kMaxPacketSize = 64;

struct PacketOptions {
    int size = 16;                  // rays per packet, 1..64
    float switch_threshold = 0.0f;  // go single-ray below this active fraction; 0: never
};

struct PacketStats {
    uint64_t packets = 0;
    uint64_t node_visits = 0;       // inner-node visits by packets
    uint64_t active_lanes = 0;      // active rays summed over those visits
    uint64_t lane_slots = 0;        // packet size summed over those visits
    uint64_t box_tests = 0;         // ray-box tests of active rays (packet and single-ray parts)
    uint64_t tri_tests = 0;         // ray-triangle tests of active rays
    uint64_t switches = 0;          // subtrees finished ray by ray after a switch
    uint64_t single_ray_nodes = 0;  // node visits made by single rays after a switch

    double utilization() const {
        return lane_slots ? double(active_lanes) / double(lane_slots) : 0.0;
    }
    void add(const PacketStats& o);
};

// Groups rays 0..n-1 into packets: runs [first, last) of consecutive rays of one kind
// (`kind_of(i)`), at most `size` long.
template <class KindOf>
std::vector<std::pair<size_t, size_t>> packet_runs(size_t n, int size, KindOf kind_of) {
    std::vector<std::pair<size_t, size_t>> runs;
    for (size_t i = 0; i < n;) {
        size_t e = i + 1;
        while (e < n && e - i < size_t(size) && kind_of(e) == kind_of(i)) ++e;
        runs.push_back({i, e});
        i = e;
    }
    return runs;
}

// Traces rays[0, n) (n <= 64) as one packet; all share `query`. hits[i] gets what trace_ray
// would return for rays[i] (the same t; on an exact tie possibly another primitive).
// steps (optional) receives the packet's step stream, each step with the lanes that take part
// (the steps of subtrees finished ray by ray after a switch are not recorded).
void trace_packet(const Bvh& bvh, const Ray* rays, int n, HitQuery query, Hit* hits,
                  const PacketOptions& options, PacketStats& stats,
                  std::vector<Step>* steps = nullptr);

}  // namespace rtsim

// DRAM traffic by what it carries: BVH node records, triangles, instance records (two-level
// scenes), alpha data (any-hit shaders' reads), spilled stacks, ray records (treelet queues in
// memory) and hit records, read and written. The treelet study needs it: queues cut BVH traffic and
// add ray-record traffic, and only the split shows which wins.
#pragma once

#include <array>
#include <cstdint>

#include "models/dram.h"
#include "models/ray_buffer.h"
#include "models/short_stack.h"
#include "workloads/bvh.h"

namespace rtsim {

// Sits between the L2 and the DRAM model (or its other fronts), forwarding everything.
class DramRegions final : public DramModel {
  public:
    enum Region {
        kNodes,
        kTriangles,
        kInstances,
        kAlpha,
        kStack,
        kRayRecords,
        kHitRecords,
        kOther,
        kRegions
    };
    static constexpr const char* kNames[kRegions] = {
        "nodes", "triangles", "instances", "alpha", "stack", "ray_records", "hit_records", "other"};
    DramRegions(DramModel& inner, const BvhLayout& layout)
        : inner_(inner),
          node_begin_(layout.node_addr(0)),
          node_end_(layout.node_addr(layout.inner_node_count)),
          tri_begin_(layout.tri_addr(0)),
          tri_end_(layout.tri_addr(layout.triangle_count)),
          instance_begin_(layout.instance_base_addr),
          instance_end_(layout.instance_base_addr + layout.instance_bytes_total()),
          alpha_begin_(layout.alpha_base_addr),
          alpha_end_(layout.alpha_base_addr + layout.alpha_bytes_total()) {}

    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* breakdown = nullptr) override {
        read_bytes[region(addr)] += size_bytes;
        return inner_.access(addr, size_bytes, now, breakdown);
    }
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        write_bytes[region(addr)] += size_bytes;
        return inner_.write(addr, size_bytes, now);
    }
    void warm(uint64_t addr, uint32_t size_bytes) override { inner_.warm(addr, size_bytes); }
    void warm_write(uint64_t addr, uint32_t size_bytes) override {
        inner_.warm_write(addr, size_bytes);
    }
    Cycle advance(DramRequest& r, Cycle now, bool& done) override {
        if (r.stage == 0) (r.write ? write_bytes : read_bytes)[region(r.addr)] += r.size_bytes;
        return inner_.advance(r, now, done);
    }
    // Only its own counters (the model below registers its own).
    void register_stats(StatsRegistry& reg) override {
        for (int k = 0; k < kRegions; ++k) {
            reg.add("dram", std::string(kNames[k]) + "_read_bytes", &read_bytes[size_t(k)],
                    "bytes the L2 read from DRAM for this region");
            reg.add("dram", std::string(kNames[k]) + "_write_bytes", &write_bytes[size_t(k)],
                    "bytes the L2 wrote to DRAM for this region");
        }
    }
    // stats.json "bandwidth.dram.by_region": read and written bytes per region.
    nlohmann::json report(const ReportContext& ctx) const override {
        nlohmann::json r = inner_.report(ctx), by = nlohmann::json::object();
        for (int k = 0; k < kRegions; ++k)
            by[kNames[k]] = {{"read_bytes", read_bytes[size_t(k)]},
                             {"write_bytes", write_bytes[size_t(k)]}};
        r["by_region"] = by;
        return r;
    }
    uint64_t out_of_order_requests() const override { return inner_.out_of_order_requests(); }
    uint64_t bytes_moved(uint32_t size_bytes) const override {
        return inner_.bytes_moved(size_bytes);
    }
    void set_series(TimeSeries* bytes) override { inner_.set_series(bytes); }
    void follow(const TimeFloor* floor) override { inner_.follow(floor); }

    std::array<uint64_t, kRegions> read_bytes{}, write_bytes{};

  private:
    Region region(uint64_t addr) const {
        if (addr >= node_begin_ && addr < node_end_) return kNodes;
        if (addr >= tri_begin_ && addr < tri_end_) return kTriangles;
        if (addr >= instance_begin_ && addr < instance_end_) return kInstances;
        if (addr >= alpha_begin_ && addr < alpha_end_) return kAlpha;
        if (addr >= kHitRecordBase) return kHitRecords;
        if (addr >= kRayRecordBase) return kRayRecords;
        if (addr >= kStackRegionBase) return kStack;
        return kOther;
    }
    DramModel& inner_;
    uint64_t node_begin_, node_end_, tri_begin_, tri_end_, instance_begin_, instance_end_,
        alpha_begin_, alpha_end_;
};

}  // namespace rtsim

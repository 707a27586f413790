// A cache level of its own in the memory path: an L1.5 below each core's L1s
// (memory_path.below_l1 = cache: one per core, private to it) or an L3 below the L2 (below_l2 =
// cache: shared, taking the L2's misses and write-backs). It is the chip's Cache (models/cache.h),
// with the same behaviour in both engines, built from its memory_path.cache section; its counters
// are under its SystemC name (below_l2.cache.hits) and its stats.json section is the caches'.
// Waits on its fills are charged in stall attribution as its own level charges them: to the
// level it stands in front of.
#include <fmt/format.h>

#include "models/cache.h"
#include "models/memory_block.h"
#include "models/replacement.h"

namespace rtsim {
namespace {

CacheParams params_of(const nlohmann::json& c, uint64_t address_limit_bytes) {
    CacheParams p;
    p.size_bytes = c.at("size_kib").get<uint64_t>() * 1024;
    p.ways = c.at("ways").get<int>();
    p.line_bytes = c.at("line_bytes").get<uint32_t>();
    p.hit_latency_cycles = c.at("hit_latency_cycles").get<Cycle>();
    p.mshrs = c.at("mshrs").get<int>();
    p.banks = c.at("banks").get<int>();
    p.replacement = c.at("replacement").get<std::string>();
    p.rrpv_bits = c.at("rrpv_bits").get<int>();
    p.write_back = c.at("write_policy").get<std::string>() == "write_back";
    p.address_limit_bytes = address_limit_bytes;
    return p;
}

class CacheBlock final : public MemoryBlock {
  public:
    CacheBlock(sc_core::sc_module_name name, const CacheParams& params, int level)
        : MemoryBlock(name), cache_("cache", params, nullptr, level) {}
    TargetSocketBase& target_socket() override { return cache_.up; }
    void bind_below(TargetSocketBase& below) override { cache_.down.bind(below); }
    void set_stage_queue(StageQueue* queue) override { cache_.set_stage_queue(queue); }
    void register_stats(StatsRegistry& reg) override { cache_.register_stats(reg); }
    nlohmann::json report(const ReportContext& ctx) const override {
        nlohmann::json out = cache_.report(ctx);
        out["block"] = "cache";
        return out;
    }
    void follow(const TimeFloor* floor) override { cache_.follow(floor); }
    uint64_t out_of_order_requests() const override { return cache_.lookup_out_of_order; }
    uint64_t requests() const override { return cache_.accesses + cache_.write_requests; }

  private:
    Cache cache_;
};

std::unique_ptr<MemoryBlock> make_cache(const char* module_name, const nlohmann::json& config,
                                        const MemoryBlockSetting& setting) {
    return std::make_unique<CacheBlock>(module_name, params_of(config, setting.address_limit_bytes),
                                        setting.level);
}

// The geometry the schema's ranges cannot check: a power-of-two number of sets, and ways the
// replacement policy can serve.
std::string check_cache(const nlohmann::json& c) {
    const int64_t size = c.at("size_kib").get<int64_t>() * 1024;
    const int64_t ways = c.at("ways"), line = c.at("line_bytes");
    const int64_t sets = size / (ways * line);
    if (size % (ways * line) != 0 || sets <= 0 || (sets & (sets - 1)) != 0)
        return fmt::format(
            "size_kib: size_kib / (ways * line_bytes) must be a power-of-two number of sets, got "
            "{} KiB / ({} * {}) = {:.4g} sets",
            size / 1024, ways, line, double(size) / double(ways * line));
    const ReplacementEntry& policy = ReplacementRegistry::at(c.at("replacement"));
    const std::string why = policy.check ? policy.check(int(ways)) : "";
    return why.empty() ? why : "replacement: " + policy.name + " " + why;
}

}  // namespace

RTSIM_REGISTER(MemoryBlockEntry,
               {"cache",
                "a cache level of its own: an L1.5 below each core's L1s, or an L3 below the L2",
                {"memory_path.cache.size_kib", "memory_path.cache.ways",
                 "memory_path.cache.line_bytes", "memory_path.cache.hit_latency_cycles",
                 "memory_path.cache.mshrs", "memory_path.cache.banks",
                 "memory_path.cache.replacement", "memory_path.cache.rrpv_bits",
                 "memory_path.cache.write_policy"},
                &make_cache,
                &check_cache})

}  // namespace rtsim

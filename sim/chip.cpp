#include "sim/chip.h"

#include <fmt/format.h>

#include "models/traversal_mode.h"
#include "workloads/error.h"

namespace rtsim {
namespace {

// A block's instance name: its kind and index, as in stats (l1[3], l1[3].misses) and SystemC's
// module hierarchy alike.
std::string indexed(const char* kind, int i) {
    return fmt::format("{}[{}]", kind, i);
}

// Every fetch lies in the layout's records (nodes, triangles, instances, alpha data): the
// caches' tags need only reach the end of them.
uint64_t address_limit(const BvhLayout& layout) {
    return layout.fetch_end() + 1;
}

}  // namespace

// Treelet k's runs of node records, triangles and (two-level TLAS treelets) instance records as
// byte ranges.
std::vector<TreeletSpan> treelet_spans(const BvhLayout& L) {
    std::vector<TreeletSpan> spans(L.treelet_count());
    for (uint32_t k = 0; k < L.treelet_count(); ++k) {
        const bool cut = !L.treelet_node_start.empty();
        const uint32_t n0 = cut ? L.treelet_node_start[k] : 0;
        const uint32_t n1 = cut ? L.treelet_node_start[k + 1] : L.inner_node_count;
        const uint32_t t0 = cut ? L.treelet_tri_start[k] : 0;
        const uint32_t t1 = cut ? L.treelet_tri_start[k + 1] : L.triangle_count;
        spans[k] = {L.node_addr(n0), uint64_t(n1 - n0) * L.node_size_bytes, L.tri_addr(t0),
                    uint64_t(t1 - t0) * L.tri_size_bytes};
        if (!L.treelet_instance_start.empty()) {
            const uint32_t i0 = L.treelet_instance_start[k], i1 = L.treelet_instance_start[k + 1];
            spans[k].instance_addr = L.instance_base_addr + uint64_t(i0) * L.instance_size_bytes;
            spans[k].instance_bytes = uint64_t(i1 - i0) * L.instance_size_bytes;
        }
    }
    return spans;
}

Chip::Chip(const Params& P, RayWorkSource* source, const BvhLayout& layout,
           std::function<std::unique_ptr<DramModel>(DramModel&)> make_front) {
    if (P.sim.window_cycles > 0)
        for (auto* p :
             {&series.dram_bytes, &series.l1_fill_bytes, &series.l2_fill_bytes, &series.rays})
            *p = std::make_unique<TimeSeries>(P.sim.window_cycles);
    // Annotated delays count cycles in SystemC time units (models/transaction.h).
    if (sc_core::sc_time(1.0, sc_core::SC_NS).value() != kTimeUnitsPerCycle)
        throw std::logic_error("SystemC's time resolution is not the default 1 ps");
    DramParams dram_params = P.dram;
    dram_params.chip_clock_ghz = P.clock_ghz;
    dram = DramModelRegistry::at(P.dram_model).make("dram", dram_params);
    dram->register_stats(stats);
    dram->set_series(series.dram_bytes.get());
    if (make_front) dram_front = make_front(*dram);
    dram_regions = std::make_unique<DramRegions>(dram_front ? *dram_front : *dram, layout);
    dram_regions->register_stats(stats);
    dram_port = std::make_unique<DramPort>("dram_port", *dram_regions);
    dram_port->set_stage_queue(&stages);
    // A block the config places in the memory path: built by its registration, charged to the
    // level it stands in front of, bound to `next`; what it fetches lies below `limit_bytes` (the
    // caches' address limit at its level).
    const auto path_block = [&](MemoryPathPosition position, const std::string& instance,
                                TargetSocketBase& next,
                                uint64_t limit_bytes) -> std::unique_ptr<MemoryBlock> {
        const std::string& kind = P.memory_path[size_t(position)];
        const MemoryBlockEntry& entry = MemoryBlockRegistry::at(kind);
        if (!entry.make || P.sim.ideal_memory) return nullptr;
        MemoryBlockSetting setting;
        setting.position = position;
        setting.level = position == MemoryPathPosition::kBelowL1 ? kLevelL2 : kLevelDram;
        setting.address_limit_bytes = limit_bytes;
        const nlohmann::json config = P.memory_block_config.contains(kind)
                                          ? P.memory_block_config.at(kind)
                                          : nlohmann::json::object();
        std::unique_ptr<MemoryBlock> block = entry.make(instance.c_str(), config, setting);
        block->bind_below(next);
        block->set_stage_queue(&stages);
        block->register_stats(stats);
        return block;
    };
    CacheParams l2p = P.l2;
    l2p.address_limit_bytes = address_limit(layout);
    // The traversal's own data (spilled stacks, ray records, hit records) lives above the BVH.
    if (P.core.short_stack_entries > 0 || P.core.hit_record_bytes > 0 || P.ray_buffer.in_memory)
        l2p.address_limit_bytes = std::max(l2p.address_limit_bytes, kLocalRegionsEnd);
    below_l2 = path_block(MemoryPathPosition::kBelowL2, "below_l2", dram_port->up,
                          l2p.address_limit_bytes);
    l2 = std::make_unique<Cache>("l2", l2p, below_l2 ? &below_l2->target_socket() : &dram_port->up,
                                 kLevelL2);
    l2->set_stage_queue(&stages);
    // A sampled run regresses the DRAM traffic on the BVH's compulsory misses
    // (sim/sampling/sampler.h).
    // With a prefetcher, lines come that no ray asks for: the first fills are then the lines a
    // ray first asks for at its core's first cache, as the frame's profile counts them.
    const bool prefetching = P.l1.prefetcher != "none" || P.l2.prefetcher != "none";
    if (P.sim.sampled && !prefetching)
        l2->count_first_fills(layout.fetch_begin(), layout.fetch_end());
    if (P.sim.sampled && prefetching) {
        first_demands = std::make_unique<LineFirstTouches>(layout.fetch_begin(), layout.fetch_end(),
                                                           uint32_t(l2p.line_bytes));
        stats.add("l2", "first_fills", &first_demands->count,
                  "lines of the BVH a ray asked for first in the frame (its first fills)");
    }
    l2->register_stats(stats);
    l2->set_series(series.l2_fill_bytes.get());
    TargetSocketBase* below_l1 = &l2->up;
    if (P.crossbar_bytes_per_cycle > 0) {
        crossbar = std::make_unique<Crossbar>("crossbar", P.crossbar_bytes_per_cycle, &l2->up);
        crossbar->register_stats(stats);
        crossbar->set_stage_queue(&stages);
        below_l1 = &crossbar->up;
    }

    CoreParams cp = P.core;
    const TraversalModeEntry& mode = TraversalModeRegistry::at(P.traversal.mode);
    const uint64_t treelet_cache_bytes = mode.ray_buffer ? P.traversal.treelet_cache_bytes : 0;
    // (A treelet cache needs a unified L1: the config's cross-field checks refuse it before.)
    if (mode.packets) cp.packet_lanes = P.traversal.packet_size;
    if (mode.ray_buffer) {
        ray_buffer =
            std::make_unique<RayBuffer>("ray_buffer", P.ray_buffer, treelet_spans(layout), source);
        ray_buffer->register_stats(stats);
    }
    CacheParams l1p = P.l1;
    l1p.address_limit_bytes = address_limit(layout);
    // A core's L1 lookups follow its one in-order issue port, except a treelet load (at the
    // cycle a batch starts, which may precede a step's lookup issued just before).
    l1p.in_order_requests = mode.l1_in_order;
    if (P.sim.ideal_memory) {
        ideal_memory = std::make_unique<IdealMemory>("ideal_memory", l1p.hit_latency_cycles);
        ideal_memory->set_stage_queue(&stages);
    }
    // A treelet loader's lines count the misses on their way to the caches it loads into.
    const bool treelet_loads = mode.ray_buffer && cp.treelet_prefetch;
    const auto add_cache = [&](std::vector<std::unique_ptr<Cache>>& caches, const char* kind, int i,
                               const CacheParams& params, TargetSocketBase& next) -> Cache& {
        Cache& c =
            *caches.emplace_back(std::make_unique<Cache>(indexed(kind, i).c_str(), params, &next));
        c.register_stats(stats);
        c.count_first_demands(first_demands.get());
        c.set_stage_queue(&stages);
        if (treelet_loads) c.set_treelet_loads();
        return c;
    };
    // Where the cores' own traffic below their L1s goes (stacks, hit records, ray records).
    TargetSocketBase* const below_l1s = ideal_memory ? &ideal_memory->up : below_l1;
    const int n = P.core_count;
    // Per step kind, its unit kind's units; they may serve several cores (shared_by): core i
    // uses unit i / shared_by.
    cp.units_shared = false;
    for (int k = 0; k < kStepKinds; ++k) {
        UnitParams up = P.unit[size_t(k)];
        up.unlimited = P.sim.ideal_units;
        const int share = P.unit_shared_by[size_t(k)];
        cp.units_shared = cp.units_shared || share > 1;
        series.unit_busy[size_t(k)] =
            P.sim.window_cycles > 0 ? std::make_unique<TimeSeries>(P.sim.window_cycles) : nullptr;
        for (int u = 0; u < (n + share - 1) / share; ++u) {
            auto& unit = units[size_t(k)].emplace_back(
                std::make_unique<PipelinedUnit>(indexed(step_kind_info(k).unit, u).c_str(), up));
            unit->register_stats(stats);
            unit->set_series(series.unit_busy[size_t(k)].get());
        }
    }
    for (int i = 0; i < n; ++i) {
        // The core's L1s miss into its below_l1 block when there is one.
        TargetSocketBase* l1_next = below_l1;
        if (auto block = path_block(MemoryPathPosition::kBelowL1, indexed("below_l1", i), *l1_next,
                                    l1p.address_limit_bytes)) {
            l1_next = &block->target_socket();
            below_l1_blocks.push_back(std::move(block));
        }
        add_cache(l1, "l1", i, l1p, *l1_next).set_series(series.l1_fill_bytes.get());
        if (P.l1_split)
            add_cache(l1_tri, "l1_tri", i, l1p, *l1_next).set_series(series.l1_fill_bytes.get());
        // Per step kind, the block a core's fetches enter the hierarchy at, and it as a cache.
        std::array<MemoryPort*, kStepKinds> memories;
        std::array<TargetSocketBase*, kStepKinds> memory_sockets;
        std::array<Cache*, kStepKinds> first_caches{};
        if (ideal_memory) {
            memories.fill(ideal_memory.get());
            memory_sockets.fill(&ideal_memory->up);
        } else if (treelet_cache_bytes > 0) {
            // A dedicated treelet cache in front of the L1: batches load their treelet into it.
            CacheParams tp = l1p;
            tp.size_bytes = treelet_cache_bytes;
            tp.hit_latency_cycles = P.traversal.treelet_cache_latency_cycles;
            tp.mshrs = 0;            // its misses are bounded by the L1's MSHRs
            tp.prefetcher = "none";  // batches load it whole; the L1 behind it prefetches
            tp.banks = 1;
            Cache& treelet = add_cache(treelet_caches, "treelet_cache", i, tp, l1.back()->up);
            treelet.take_mshrs_of(l1.back().get());
            first_caches.fill(&treelet);
        } else {
            first_caches.fill(l1.back().get());
        }
        // Triangle fetches go to the split L1's triangle cache when there is one.
        if (!l1_tri.empty()) first_caches[size_t(StepKind::Triangle)] = l1_tri.back().get();
        for (size_t k = 0; k < kStepKinds; ++k)
            if (first_caches[k]) {
                memories[k] = first_caches[k];
                memory_sockets[k] = &first_caches[k]->up;
            }
        // Their warm() reaches the L2 through nothing but the crossbar (a sampled run's replay).
        if (!ideal_memory && treelet_caches.empty() && below_l1_blocks.empty())
            l1s_over_l2.push_back(first_caches);
        std::array<TargetSocketBase*, kStepKinds> core_units;
        for (int k = 0; k < kStepKinds; ++k)
            core_units[size_t(k)] = &units[size_t(k)][size_t(i / P.unit_shared_by[size_t(k)])]->up;
        core_memories.push_back(memories);
        cores.push_back(std::make_unique<Core>(indexed("core", i).c_str(), cp, memory_sockets,
                                               core_units, source));
        cores.back()->set_first_caches(first_caches);
        if (ray_buffer) cores.back()->set_ray_buffer(&ray_buffer->up);
        cores.back()->set_local_memory(below_l1s, uint64_t(i) * uint64_t(cp.ray_slots));
        cores.back()->register_stats(stats);
        cores.back()->set_series(series.rays.get());
    }
    std::vector<Core*> core_ptrs;
    for (auto& c : cores) core_ptrs.push_back(c.get());
    DriverSetup setup;
    setup.cores = std::move(core_ptrs);
    setup.stages = &stages;
    // Parked slots wake when the ray buffer has work for them, or (a sampled run's drained
    // windows) when the source lets its held ray go.
    setup.wake = ray_buffer ? static_cast<WakeSource*>(ray_buffer.get())
                            : (source ? source->wakes() : nullptr);
    if (ray_buffer && P.ray_buffer.in_memory)  // (a driver may then defer its requests)
        ray_buffer->down.bind(*below_l1s);
    driver = FidelityRegistry::at(P.sim.fidelity).make("core_driver", setup);
    for (int i = 0; i < n; ++i) {
        // A core's private blocks forget what lies behind the floor of its own requests.
        const TimeFloor* own = driver->private_floor(size_t(i));
        l1[size_t(i)]->follow(own);
        if (!l1_tri.empty()) l1_tri[size_t(i)]->follow(own);
        if (!treelet_caches.empty()) treelet_caches[size_t(i)]->follow(own);
        if (!below_l1_blocks.empty()) below_l1_blocks[size_t(i)]->follow(own);
        for (int k = 0; k < kStepKinds; ++k)
            if (P.unit_shared_by[size_t(k)] == 1) units[size_t(k)][size_t(i)]->follow(own);
    }
    // Shared blocks forget what lies behind the earliest request any core may still send.
    const TimeFloor* shared = driver->shared_floor();
    l2->follow(shared);
    dram->follow(shared);
    if (crossbar) crossbar->follow(shared);
    if (below_l2) below_l2->follow(shared);
    for (int k = 0; k < kStepKinds; ++k)
        if (P.unit_shared_by[size_t(k)] > 1)
            for (auto& u : units[size_t(k)]) u->follow(shared);
    g_calendar_late_requests = 0;  // one chip per run; counted from here
    stats.add("sim", "late_requests", &g_calendar_late_requests,
              "requests that came before their block's time floor (a model bug if not 0)");
}

Cycle Chip::total_cycles() const {
    Cycle c = 0;
    for (const auto& core : cores) c = std::max<Cycle>(c, core->last_cycle);
    return c;
}

namespace {
template <typename T>
std::vector<const T*> views(const std::vector<std::unique_ptr<T>>& blocks) {
    std::vector<const T*> out;
    for (const auto& b : blocks) out.push_back(b.get());
    return out;
}
}  // namespace

std::vector<const Cache*> Chip::all_l1() const {
    std::vector<const Cache*> out = views(l1);  // unified, or node and triangle caches
    for (const auto& c : l1_tri) out.push_back(c.get());
    return out;
}

nlohmann::json Chip::out_of_order_report() const {
    const std::vector<const Cache*> l1s = all_l1();
    uint64_t issue = 0;
    for (const auto& c : cores) issue += c->issue_port_out_of_order();
    nlohmann::json out = {{"l1_lookups", sum_of(l1s, &Cache::lookup_out_of_order)},
                          {"l1_mshr_requests", sum_of(l1s, &Cache::mshr_out_of_order)},
                          {"l2_lookups", l2->lookup_out_of_order},
                          {"l2_mshr_requests", l2->mshr_out_of_order},
                          {"dram_requests", dram->out_of_order_requests()},
                          {"issue_port_requests", issue},
                          {"calendar_late_requests", g_calendar_late_requests}};
    if (ray_buffer) out["ray_buffer_port_requests"] = ray_buffer->port_out_of_order();
    if (below_l2) out["below_l2_requests"] = below_l2->out_of_order_requests();
    uint64_t below_l1_requests = 0;
    for (const auto& b : below_l1_blocks) below_l1_requests += b->out_of_order_requests();
    if (!below_l1_blocks.empty()) out["below_l1_requests"] = below_l1_requests;
    return out;
}

nlohmann::json Chip::report(const ReportContext& ctx) const {
    using nlohmann::json;
    json out;
    json unit_sections = json::object();
    for (int k = 0; k < kStepKinds; ++k) {
        for (const auto& u : units[size_t(k)]) unit_sections[u->name()] = u->report(ctx);
        unit_sections[std::string(step_kind_info(k).unit) + "_total"] =
            PipelinedUnit::report_total(views(units[size_t(k)]), ctx);
    }
    out["units"] = unit_sections;

    json caches = json::object();
    const std::vector<const Cache*> l1s = all_l1();
    for (const Cache* c : l1s) caches[c->name()] = c->report(ctx);
    caches["l1_total"] = Cache::report_total(l1s, ctx);
    if (!treelet_caches.empty()) {
        for (const auto& c : treelet_caches) caches[c->name()] = c->report(ctx);
        caches["treelet_cache_total"] = Cache::report_total(views(treelet_caches), ctx);
    }
    caches[l2->name()] = l2->report(ctx);
    out["caches"] = caches;

    // Bytes crossing each boundary: core<-L1 (requested), L1<-L2 (L1 fills), L2<-DRAM.
    const uint64_t l1_bytes = sum_of(l1s, &Cache::bytes_requested);
    const uint64_t l2_bytes = sum_of(l1s, &Cache::fill_bytes);
    out["bandwidth"] = {{"l1", {{"bytes", l1_bytes}, {"gbps", ctx.gbps(l1_bytes)}}},
                        {"l2", {{"bytes", l2_bytes}, {"gbps", ctx.gbps(l2_bytes)}}},
                        {"dram", dram_regions->report(ctx)}};
    if (crossbar) out["bandwidth"]["crossbar"] = crossbar->report(ctx);
    if (below_l2 || !below_l1_blocks.empty()) {
        json path = json::object();
        // Every block's section also says how many requests it served and how many of them came
        // after one later in simulated time (sim/fidelity_check.cpp reads the share).
        const auto section = [&](const MemoryBlock& b) {
            json s = b.report(ctx);
            s["requests"] = b.requests();
            s["out_of_order_requests"] = b.out_of_order_requests();
            return s;
        };
        for (const auto& b : below_l1_blocks) path[b->name()] = section(*b);
        if (below_l2) path[below_l2->name()] = section(*below_l2);
        out["memory_path"] = path;
    }

    // Stall attribution: every ray-slot cycle charged to one cause, per core and in total.
    json stalls = json::object();
    for (const auto& c : cores) stalls[c->name()] = c->stall_report(ctx);
    stalls["total"] = Core::stall_report_total(views(cores), ctx);
    out["stalls"] = stalls;

    if (ray_buffer)
        out["ray_buffer"] = ray_buffer->report(ctx, sum_of(views(cores), &Core::treelet_loads),
                                               sum_of(views(cores), &Core::treelet_load_bytes));
    if (cores[0]->params().packet_lanes > 0) out["packets"] = Core::packet_report(views(cores));
    out["out_of_order"] = out_of_order_report();
    return out;
}

}  // namespace rtsim

#include "models/ray_buffer.h"

#include <algorithm>
#include <limits>

namespace rtsim {

RayBuffer::RayBuffer(sc_core::sc_module_name name, const RayBufferParams& params,
                     std::vector<TreeletSpan> treelets, RayWorkSource* source)
    : sc_core::sc_module(name),
      up("up"),
      down("down"),
      params_(params),
      treelets_(std::move(treelets)),
      source_(source),
      entries_(params.capacity_rays),
      queues_(std::max<size_t>(1, treelets_.size())) {
    up.register_b_transport<&RayBuffer::b_transport>(this);
    ports_.per_cycle = params.ports;
    TreeletSchedulerParams sp;
    sp.treelets = uint32_t(queues_.size());
    sp.max_wait_batches = params.max_wait_batches;
    scheduler_ = TreeletSchedulerRegistry::at(params.scheduler).make(sp);
    free_.reserve(params.capacity_rays);
    for (uint32_t h = params.capacity_rays; h-- > 0;) free_.push_back(h);
}

// The SRAM's ports: `ports` record accesses start per cycle, each done `latency_cycles` later.
Cycle RayBuffer::port(Cycle now) {
    const Cycle start = ports_.take(now);
    port_wait_cycles += start - now;
    return start + params_.latency_cycles;
}

Cycle RayBuffer::write_record(uint32_t handle, Cycle now) {
    ++writes;
    if (!params_.in_memory) return port(now);
    if (defer_) {
        deferred_writes_.push_back(record_address(handle));
        return now;
    }
    // Readable from now: the memory serves a later read of the record after this write (the
    // time-ordered reference posts it at now too).
    below_.write(record_address(handle), params_.ray_bytes, now);
    return now;
}

void RayBuffer::recount(uint32_t treelet, size_t before) {
    const std::deque<uint32_t>& q = queues_[treelet];
    scheduler_->changed(treelet, before, q.size(), q.empty() ? 0 : entries_[q.front()].seq);
}

void RayBuffer::enqueue(uint32_t handle, uint32_t treelet, Cycle now) {
    const size_t before = queues_[treelet].size();
    entries_[handle].seq = next_seq_++;
    queues_[treelet].push_back(handle);
    recount(treelet, before);
    // Cores that found nothing to do may now have work.
    if (!wake_ || now < wake_cycle_) wake_cycle_ = now;
    wake_ = true;
}

// Admits up to a batch of new rays while there is room: rays enter as cores ask for work, not
// all at once, so admissions share the ports with the traffic around them.
void RayBuffer::admit(Cycle now) {
    bool blocked = false;
    for (uint32_t n = 0; n < params_.batch_rays && !source_done_; ++n) {
        if (free_.empty()) {
            blocked = true;
            break;
        }
        const uint32_t h = free_.back();
        Entry& e = entries_[h];
        if (!source_->next(e.work, now)) {
            source_done_ = true;
            break;
        }
        free_.pop_back();
        e.pos = 0;
        ++occupancy_;
        ++admitted;
        peak_rays = std::max<uint64_t>(peak_rays, occupancy_);
        // A ray that misses the scene has no step; it still passes through a core to finish.
        const uint32_t treelet = e.work.steps.empty() ? 0 : e.work.steps[0].treelet;
        e.written = write_record(h, now);
        enqueue(h, treelet, e.written);
    }
    if (blocked) ++admission_blocked;
}

bool RayBuffer::next_batch(Cycle now, uint32_t& treelet, std::deque<uint32_t>& rays) {
    admit(now);
    if (!scheduler_->pick(treelet)) return false;
    std::deque<uint32_t>& q = queues_[treelet];
    const size_t before = q.size();
    const size_t take = std::min<size_t>(before, std::max<uint32_t>(1, params_.batch_rays));
    for (size_t i = 0; i < take; ++i) {
        rays.push_back(q.front());
        q.pop_front();
    }
    recount(treelet, before);
    ++batches;
    batch_rays += take;
    return true;
}

Cycle RayBuffer::read(uint32_t handle, Cycle now, RayWork& work, size_t& pos) {
    Entry& e = entries_[handle];
    work.steps.swap(e.work.steps);
    work.ray_id = e.work.ray_id;
    work.kind = e.work.kind;
    work.rays = e.work.rays;
    pos = e.pos;
    ++reads;
    const Cycle from = std::max(now, e.written);
    if (!params_.in_memory) return port(from);
    if (defer_) return from;
    return below_.read(record_address(handle), params_.ray_bytes, from);
}

Cycle RayBuffer::requeue(uint32_t handle, RayWork& work, size_t pos, uint32_t treelet, Cycle now) {
    Entry& e = entries_[handle];
    e.work.steps.swap(work.steps);
    e.pos = pos;
    ++crossings;
    e.written = write_record(handle, now);
    enqueue(handle, treelet, e.written);
    return e.written;
}

void RayBuffer::release(uint32_t handle) {
    free_.push_back(handle);
    --occupancy_;
    // The last ray leaving lets idle cores see that everything is done.
    if (finished()) {
        wake_ = true;
        wake_cycle_ = 0;
    }
}

void RayBuffer::register_stats(StatsRegistry& reg) {
    const std::string block = name();
    reg.add(block, "reads", &reads, "ray records read by cores");
    reg.add(block, "writes", &writes, "ray records written (admissions and treelet crossings)");
    reg.add(block, "port_wait_cycles", &port_wait_cycles, "cycles accesses waited for a port");
    reg.add(block, "peak_rays", &peak_rays, "most rays held at once");
    reg.add(block, "admitted", &admitted, "rays that entered the buffer");
    reg.add(block, "admission_blocked", &admission_blocked,
            "batch requests that found the buffer full while new rays waited");
    reg.add(block, "batches", &batches, "treelet batches handed to cores");
    reg.add(block, "batch_rays", &batch_rays, "rays handed out in batches");
    reg.add(block, "crossings", &crossings, "rays queued again for another treelet");
    reg.add(block, "port_out_of_order", &ports_.out_of_order,
            "record accesses ready before an earlier access's ready cycle (served out of order)");
}

nlohmann::json RayBuffer::report(const ReportContext& ctx, uint64_t treelet_loads,
                                 uint64_t treelet_load_bytes) const {
    using R = ReportContext;
    const uint64_t capacity = params_.capacity_rays, record = params_.ray_bytes;
    const uint64_t moved = (reads + writes) * record;
    return {{"capacity_rays", capacity},
            {"storage", params_.in_memory ? "memory" : "sram"},
            {"size_bytes", capacity * record},
            {"reads", reads},
            {"writes", writes},
            {"bytes", moved},
            {"gbps", ctx.gbps(moved)},
            {"peak_rays", peak_rays},
            {"admission_blocked", admission_blocked},
            {"port_wait_cycles", port_wait_cycles},
            {"batches", batches},
            {"rays_per_batch", R::ratio(double(batch_rays), double(batches))},
            {"crossings", crossings},
            {"crossings_per_ray", R::ratio(double(crossings), double(ctx.rays))},
            {"treelet_loads", treelet_loads},
            {"treelet_load_bytes", treelet_load_bytes}};
}

}  // namespace rtsim

// dram.model = command: the command-level controller (models/dram_command.h) as the chip's
// main memory. The chip's cycles convert to the device's clock and back; dram.latency_cycles
// covers the path to the controller and back (chip cycles).
//
// A request's completion is needed when it is made (the fast model) or at its next stage (the
// time-ordered reference), but under FR-FCFS it depends on what arrives later. So the
// controller runs up to each arrival, takes the request, and a copy of it runs on alone until
// the request's data is back: that is the completion the requester sees. In the reference
// (advance), the request then polls the real controller at that cycle and finishes when the
// real controller, having seen every later arrival in time order, has served it. In the fast
// model (access, write), requests reach it out of time order (a core's multi-line fetch sends its
// second line's miss when its one MSHR frees, hundreds of cycles ahead of other cores' requests).
// Entered as they came, each earlier request that followed would wait for the controller's clock:
// 64 cores with one L1 MSHR each ran +171% against the time-ordered reference. So requests are
// held, in time order, until the time floor (the earliest cycle any core may still send at) has
// passed them, and enter the controller then; a request's completion is predicted on a copy of
// the controller given the held requests that arrived before it. Requests that still enter
// behind the controller's clock are counted (late_requests, late_device_cycles).
#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <vector>

#include "models/dram.h"
#include "models/dram_device.h"

namespace rtsim {

namespace {

constexpr Cycle kNoFloorCycle = ~Cycle(0);  // releases every held request

class CommandDram final : public sc_core::sc_module, public DramModel {
  public:
    CommandDram(sc_core::sc_module_name name, const DramParams& p)
        : sc_core::sc_module(name),
          params_(p),
          spec_(command_dram_spec(p)),
          ctrl_(spec_),
          chip_ns_(p.chip_clock_ghz > 0 ? 1.0 / p.chip_clock_ghz : 1.0) {}

    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* bd = nullptr) override {
        const Cycle done = hold({now, held_seq_++, addr, size_bytes, false});
        if (bd) bd->cycles[kLevelDram] += done - now;
        return done;
    }

    // Posted: the bursts enter the write queue (waiting for room in a full one) and nothing
    // waits for them to drain; returns the cycle the last one entered.
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        return hold({now, held_seq_++, addr, size_bytes, true});
    }

    Cycle advance(DramRequest& r, Cycle now, bool& done) override {
        if (r.write) {
            done = true;
            return enqueue(r, now);
        }
        if (r.stage == 0) {
            done = false;
            return arrive(r, now);
        }
        // Poll: run the real controller up to (not through) now, since requests may still arrive
        // at now, and see whether every burst is back (a burst's completion is known from its
        // column command, which precedes its data by CL).
        const uint64_t t = to_device(now);
        if (t > 0) ctrl_.run_until(t - 1);
        collect();
        const uint64_t first = r.state[0], count = r.state[1];
        uint64_t last = 0;
        for (uint64_t id = first; id < first + count; ++id) {
            auto it = finished_.find(id);
            if (it == finished_.end()) {
                done = false;
                return std::max(now + 1, predict(first, count));
            }
            last = std::max(last, it->second);
        }
        for (uint64_t id = first; id < first + count; ++id) finished_.erase(id);
        done = true;
        return std::max(now, to_chip(last) + params_.latency_cycles);
    }

    void register_stats(StatsRegistry& reg) override {
        const std::string block = name();
        reg.add(block, "reads", &reads_, "read bursts");
        reg.add(block, "writes", &writes_, "write bursts");
        reg.add(block, "bytes", &bytes_, "bytes read and written");
        reg.add(block, "write_bytes", &write_bytes_, "bytes written");
        // The controller's own counters, read where they live (ctrl_ is never moved).
        const DramCounters& k = ctrl_.counters();
        reg.add(block, "row_hits", &k.row_hits, "column commands to an already open row");
        reg.add(block, "row_empty", &k.row_misses, "column commands that needed an activate");
        reg.add(block, "row_conflicts", &k.row_conflicts,
                "column commands that needed a precharge and an activate");
        reg.add(block, "activates", &k.acts, "ACT commands");
        reg.add(block, "refreshes", &k.refs, "REF commands (all banks of a rank)");
        reg.add(block, "bank_refreshes", &k.refs_per_bank, "REFpb commands (one bank)");
        reg.add(block, "late_requests", &late_,
                "requests that arrived behind one later in simulated time (fast model)");
        reg.add(block, "late_device_cycles", &late_device_cycles_,
                "device cycles requests entered the controller after their time, behind the "
                "controller's clock (fast model; not in read_latency)");
        reg.add(block, "queue_full_waits", &queue_full_waits_,
                "device cycles requests waited for room in a full controller queue");
    }

    nlohmann::json report(const ReportContext& ctx) const override {
        // Held requests enter first; refresh and background energy run to the frame's end.
        const_cast<CommandDram*>(this)->release(kNoFloorCycle);
        ctrl_.run_until(to_device(ctx.total_cycles));
        ctrl_.settle_background();
        const DramCounters& k = ctrl_.counters();
        const double device_cycles = double(std::max<uint64_t>(1, ctrl_.now()));
        const double ns = device_cycles * spec_.tck_ns;
        using R = ReportContext;
        return {
            {"bytes", bytes_},
            {"gbps", ctx.gbps(bytes_)},
            {"write_bytes", write_bytes_},
            {"device", spec_.name},
            {"row_hits", k.row_hits},
            {"row_empty", k.row_misses},
            {"row_conflicts", k.row_conflicts},
            {"row_hit_rate", R::ratio(double(k.row_hits), double(k.reads + k.writes))},
            {"commands",
             {{"act", k.acts}, {"pre", k.pres}, {"ref", k.refs}, {"ref_pb", k.refs_per_bank}}},
            {"read_latency_device_cycles", R::ratio(double(k.read_latency_sum), double(k.reads))},
            {"utilization", R::ratio(double(k.reads + k.writes) * spec_.burst_cycles,
                                     device_cycles * spec_.data_channels())},
            {"energy_pj", dram_energy_json(k)},
            {"average_power_mw", ns > 0 ? k.total_pj() / ns : 0.0}};
    }

    uint64_t out_of_order_requests() const override { return late_; }
    uint64_t bytes_moved(uint32_t size_bytes) const override {
        const uint32_t burst = spec_.burst_bytes();
        return std::max<uint64_t>(1, (size_bytes + burst - 1) / burst) * burst;
    }
    void set_series(TimeSeries* bytes) override { series_ = bytes; }
    void follow(const TimeFloor* floor) override { floor_ = floor; }

  private:
    uint64_t to_device(Cycle chip) const {
        return uint64_t(std::ceil(double(chip) * chip_ns_ / spec_.tck_ns - 1e-9));
    }
    Cycle to_chip(uint64_t device) const {
        return Cycle(std::ceil(double(device) * spec_.tck_ns / chip_ns_ - 1e-9));
    }

    // A fast-model request: held in time order until the floor passes it (below); returns when
    // its data is back (a read: predicted on a copy of the controller given the requests held
    // before it) or, for a write, when its last burst entered the write queue.
    struct Held {
        Cycle chip;
        uint64_t seq;  // arrival order, for ties
        uint64_t addr;
        uint32_t size_bytes;
        bool write;
        bool operator<(const Held& o) const { return chip != o.chip ? chip < o.chip : seq < o.seq; }
    };
    Cycle hold(const Held& h) {
        release(floor_ ? floor_->cycle : kNoFloorCycle);
        const auto at = std::upper_bound(held_.begin(), held_.end(), h);
        const size_t before = size_t(at - held_.begin());
        held_.insert(at, h);
        // Snapshots that counted held requests from `before` on lack this one.
        while (!snapshots_.empty() && snapshots_.back().held_count > before) snapshots_.pop_back();
        // The controller as this request finds it: a copy given the held requests before it,
        // started from the latest snapshot at or before them.
        DramController copy = snapshots_.empty() ? ctrl_ : snapshots_.back().ctrl;
        uint64_t id = snapshots_.empty() ? next_id_ : snapshots_.back().next_id;
        const size_t from = snapshots_.empty() ? 0 : snapshots_.back().held_count;
        for (size_t k = from; k < before; ++k) put(copy, id, held_[k]);
        if (before - from >= kSnapshotSpacing) {
            snapshots_.push_back({before, id, copy});
            snapshots_.back().ctrl.completions().clear();
        }
        copy.completions().clear();
        Cycle result;
        const uint64_t first = id;
        const uint64_t entered = put(copy, id, h);
        if (h.write) {
            result = std::max(h.chip, to_chip(entered));
        } else {
            const uint64_t last = run_until_back(copy, first, id - first, 0, 0);
            result = std::max(h.chip + 1, to_chip(last) + params_.latency_cycles);
        }
        if (!floor_) release(kNoFloorCycle);  // no floor to wait for: it enters now
        return result;
    }

    // Puts a request's bursts in `c` from device cycle `t` on (waiting for room in a full queue,
    // each cycle counted in `full_waits` if given), numbering them from `id`; returns the device
    // cycle the last one entered.
    uint64_t put(DramController& c, uint64_t& id, uint64_t addr, uint32_t size_bytes, bool write,
                 uint64_t t, uint64_t* full_waits = nullptr) const {
        const uint32_t burst = spec_.burst_bytes();
        const uint64_t count = std::max<uint64_t>(1, (size_bytes + burst - 1) / burst);
        const uint64_t base = addr / burst * burst;
        uint64_t entered = t;
        for (uint64_t k = 0; k < count; ++k) {
            uint64_t at = std::max(t, c.now());
            while (!c.enqueue(id, base + k * burst, write, at)) {
                at = c.now() + 1;
                if (full_waits) ++*full_waits;
            }
            entered = std::max(entered, at);
            ++id;
        }
        return entered;
    }
    uint64_t put(DramController& c, uint64_t& id, const Held& h) const {
        return put(c, id, h.addr, h.size_bytes, h.write, to_device(h.chip));
    }

    // The held requests that arrived before chip cycle `below` enter the controller, in time
    // order.
    void release(Cycle below) {
        size_t k = 0;
        for (; k < held_.size() && held_[k].chip < below; ++k) {
            DramRequest r;
            r.addr = held_[k].addr;
            r.size_bytes = held_[k].size_bytes;
            r.write = held_[k].write;
            enqueue(r, held_[k].chip);
        }
        held_.erase(held_.begin(), held_.begin() + std::ptrdiff_t(k));
        // A snapshot past the released requests is the controller now plus the held requests
        // after them (entering a request is deterministic); one before them is behind it.
        size_t behind = 0;
        while (behind < snapshots_.size() && snapshots_[behind].held_count <= k) ++behind;
        snapshots_.erase(snapshots_.begin(), snapshots_.begin() + std::ptrdiff_t(behind));
        for (Snapshot& s : snapshots_) s.held_count -= k;
        ctrl_.completions().clear();  // the fast model uses the predictions only
    }

    // Enqueues the request's bursts at `now` and returns when a copy of the controller, run on
    // alone, has its data back (plus the path latency).
    Cycle arrive(DramRequest& r, Cycle now) {
        const uint64_t first = next_id_;
        enqueue(r, now);
        const uint64_t count = next_id_ - first;
        r.state[0] = first;
        r.state[1] = count;
        r.stage = 1;
        return std::max(now + 1, predict(first, count));
    }

    // Puts the request's bursts in the controller's queues from `now` on; returns the chip cycle
    // the last one entered (later than `now` when a queue was full).
    Cycle enqueue(DramRequest& r, Cycle now) {
        r.arrived = now;
        const uint64_t t = to_device(now);
        // Out of time order: behind a request that arrived later in simulated time (the fast
        // model's cores run ahead of each other within a horizon). A full queue also makes a
        // request enter after its time; that is the queue's back-pressure, counted apart.
        late_ += t < latest_arrival_;
        late_device_cycles_ += std::max(t, ctrl_.now()) - t;
        latest_arrival_ = std::max(latest_arrival_, t);
        const uint64_t first = next_id_;
        const uint64_t entered =
            put(ctrl_, next_id_, r.addr, r.size_bytes, r.write, t, &queue_full_waits_);
        const uint64_t count = next_id_ - first;
        const uint32_t burst = spec_.burst_bytes();
        (r.write ? writes_ : reads_) += count;
        bytes_ += count * burst;
        if (r.write) write_bytes_ += count * burst;
        if (series_) series_->add(now, count * burst);
        return std::max(now, to_chip(entered));
    }

    // The chip cycle the bursts [first, first + count) are back, if nothing else arrives.
    Cycle predict(uint64_t first, uint64_t count) {
        DramController copy = ctrl_;
        copy.completions().clear();
        uint64_t last = 0, seen = 0;
        // Already finished in the real controller?
        for (uint64_t id = first; id < first + count; ++id) {
            auto it = finished_.find(id);
            if (it != finished_.end()) {
                last = std::max(last, it->second);
                ++seen;
            }
        }
        for (const auto& c : ctrl_.completions())
            if (c.id >= first && c.id < first + count) {
                last = std::max(last, c.cycle);
                ++seen;
            }
        return to_chip(run_until_back(copy, first, count, last, seen)) + params_.latency_cycles;
    }

    // Runs `copy` on until bursts [first, first + count) are back, `seen` of them already (the
    // last at `last`); returns the device cycle the last one is back.
    static uint64_t run_until_back(DramController& copy, uint64_t first, uint64_t count,
                                   uint64_t last, uint64_t seen) {
        while (seen < count && copy.pending() > 0) {
            copy.run_until(copy.now());
            for (const auto& c : copy.completions())
                if (c.id >= first && c.id < first + count) {
                    last = std::max(last, c.cycle);
                    ++seen;
                }
            copy.completions().clear();
        }
        return last;
    }

    void collect() {
        for (const auto& c : ctrl_.completions())
            if (!c.write) finished_[c.id] = c.cycle;  // nothing waits for a write
        ctrl_.completions().clear();
    }

    DramParams params_;
    DramDeviceSpec spec_;
    mutable DramController ctrl_;  // report() runs it to the frame's end
    double chip_ns_;
    uint64_t next_id_ = 0;
    std::unordered_map<uint64_t, uint64_t> finished_;  // burst id -> device cycle (reference)
    TimeSeries* series_ = nullptr;
    uint64_t reads_ = 0, writes_ = 0, bytes_ = 0, write_bytes_ = 0, late_ = 0,
             queue_full_waits_ = 0, late_device_cycles_ = 0;
    uint64_t latest_arrival_ = 0;  // device cycle
    const TimeFloor* floor_ = nullptr;
    std::vector<Held> held_;  // fast model: arrived, not yet in the controller; in time order
    // The controller with the first held_count held requests entered, every kSnapshotSpacing or
    // more of them, so that predicting a request replays the few held since the last one and
    // not every one held (hundreds when the cores run far apart in time).
    struct Snapshot {
        size_t held_count;
        uint64_t next_id;
        DramController ctrl;
    };
    static constexpr size_t kSnapshotSpacing = 16;
    std::vector<Snapshot> snapshots_;  // by held_count, ascending
    uint64_t held_seq_ = 0;
};

std::unique_ptr<DramModel> make_command(const char* module_name, const DramParams& p) {
    return std::make_unique<CommandDram>(module_name, p);
}

}  // namespace

RTSIM_REGISTER(DramModelEntry,
               {"command",
                "command-level controller: ACT/RD/WR/PRE/REF under JEDEC timings, bank groups, "
                "ranks, FR-FCFS queues, refresh, energy from device currents (configs/dram)",
                {"latency_cycles", "device", "page_policy", "address_mapping", "refresh"},
                &make_command})

}  // namespace rtsim

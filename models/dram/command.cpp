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
// model, requests that reach it behind the controller's time enter late (counted).
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "models/dram.h"
#include "models/dram_device.h"

namespace rtsim {

namespace {

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
        DramRequest r;
        r.addr = addr;
        r.size_bytes = size_bytes;
        const Cycle done = arrive(r, now);
        ctrl_.completions().clear();  // the fast model uses the prediction only
        if (bd) bd->cycles[kLevelDram] += done - now;
        return done;
    }

    // Posted: the bursts enter the write queue (waiting for room in a full one) and nothing
    // waits for them to drain.
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        DramRequest r;
        r.addr = addr;
        r.size_bytes = size_bytes;
        r.write = true;
        return enqueue(r, now);
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
        reg.add(block, "refreshes", &k.refs, "REF commands");
        reg.add(block, "late_requests", &late_,
                "requests that arrived behind one later in simulated time (fast model)");
        reg.add(block, "queue_full_waits", &queue_full_waits_,
                "device cycles requests waited for room in a full controller queue");
    }

    nlohmann::json report(const ReportContext& ctx) const override {
        // Refresh and background energy run to the frame's end.
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
            {"commands", {{"act", k.acts}, {"pre", k.pres}, {"ref", k.refs}}},
            {"read_latency_device_cycles", R::ratio(double(k.read_latency_sum), double(k.reads))},
            {"utilization", R::ratio(double(k.reads + k.writes) * spec_.burst_cycles,
                                     device_cycles * spec_.channels)},
            {"energy_pj", dram_energy_json(k)},
            {"average_power_mw", ns > 0 ? k.total_pj() / ns : 0.0}};
    }

    uint64_t out_of_order_requests() const override { return late_; }
    uint64_t bytes_moved(uint32_t size_bytes) const override {
        const uint32_t burst = spec_.burst_bytes();
        return std::max<uint64_t>(1, (size_bytes + burst - 1) / burst) * burst;
    }
    void set_series(TimeSeries* bytes) override { series_ = bytes; }
    void follow(const TimeFloor*) override {}

  private:
    uint64_t to_device(Cycle chip) const {
        return uint64_t(std::ceil(double(chip) * chip_ns_ / spec_.tck_ns - 1e-9));
    }
    Cycle to_chip(uint64_t device) const {
        return Cycle(std::ceil(double(device) * spec_.tck_ns / chip_ns_ - 1e-9));
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
        latest_arrival_ = std::max(latest_arrival_, t);
        const uint32_t burst = spec_.burst_bytes();
        const uint64_t count = std::max<uint64_t>(1, (r.size_bytes + burst - 1) / burst);
        const uint64_t base = r.addr / burst * burst;
        uint64_t entered = t;
        for (uint64_t k = 0; k < count; ++k) {
            uint64_t at = std::max(t, ctrl_.now());
            while (!ctrl_.enqueue(next_id_, base + k * burst, r.write, at)) {
                at = ctrl_.now() + 1;
                ++queue_full_waits_;
            }
            entered = std::max(entered, at);
            ++next_id_;
        }
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
        while (seen < count && copy.pending() > 0) {
            copy.run_until(copy.now());
            for (const auto& c : copy.completions())
                if (c.id >= first && c.id < first + count) {
                    last = std::max(last, c.cycle);
                    ++seen;
                }
            copy.completions().clear();
        }
        return to_chip(last) + params_.latency_cycles;
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
             queue_full_waits_ = 0;
    uint64_t latest_arrival_ = 0;  // device cycle
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

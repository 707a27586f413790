// Work sources: the chip's shared queue of ray work, filled a few batches ahead on a helper thread,
// from rays generated and traced on the fly (GeneratedWorkSource) or from a recorded trace
// (TraceWorkSource). They count rays, hits and steps for the report and show progress.
#pragma once

#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <mutex>
#include <string>
#include <systemc>
#include <thread>
#include <utility>
#include <vector>

#include "models/core.h"
#include "sim/errors.h"
#include "sim/interrupt.h"
#include "sim/progress.h"
#include "sim/sampling/sampler.h"
#include "workloads/bvh.h"
#include "workloads/error.h"
#include "workloads/packet.h"
#include "workloads/raygen.h"
#include "workloads/tile_queue.h"
#include "workloads/trace_file.h"
#include "workloads/tracer.h"

namespace rtsim {

using WorkClock = std::chrono::steady_clock;

// The chip's shared work queue. Counts what it hands out and shows progress on a terminal;
// subclasses produce the rays.
class CountingSource : public RayWorkSource, public WakeSource {
  public:
    explicit CountingSource(bool progress) : progress_(progress) {}

    bool next(RayWork& work, Cycle now) override {
        if (!held_) {
            if (!produce_next(work)) return false;
            if (hold_ == WindowHold::None || !sampler_ || !sampler_->window_start() ||
                !start_hold(now)) {
                hand_out(now);
                return true;
            }
            held_work_ = std::move(work);
            held_ = true;
            sampler_->held(now);
        }
        if (failed()) {  // the held ray goes nowhere: the slots retire
            held_ = false;
            return false;
        }
        // Drain: the window waits for every ray before it to finish, and from the cycle the
        // last of them does. Predicted: until hold_until_, or until no more than
        // hold_release_in_flight_ rays before it are still running. A slot that asks earlier
        // parks, and is woken when a ray finishes past that point (finished()).
        if (hold_ == WindowHold::Drain ? draining(now) : !released(now)) {
            if (in_flight_ == 0) wake_at(hold_ == WindowHold::Drain ? last_done_ : hold_until_);
            return false;
        }
        held_ = false;
        work = std::move(held_work_);
        hand_out(now);
        return true;
    }
    bool holding() const override { return held_ && !failed(); }
    void finished(uint32_t /*rays*/, Cycle done) override {
        --in_flight_;
        last_done_ = std::max(last_done_, done);
        if (!held_) return;
        if (hold_ == WindowHold::Drain) {
            if (in_flight_ == 0) wake_at(last_done_);
        } else if (released(done)) {
            wake_at(done);
        } else if (in_flight_ == 0) {
            wake_at(hold_until_);
        }
    }
    WakeSource* wakes() override { return hold_ != WindowHold::None ? this : nullptr; }
    const bool* wake_pending() const override {
        return hold_ != WindowHold::None ? &wake_pending_ : nullptr;
    }
    bool take_wake(Cycle& at) override {
        if (!wake_pending_) return false;
        wake_pending_ = false;
        at = wake_cycle_;
        return true;
    }

    // Sampled simulation: rays pass through `sampler` (sim/sampling/sampler.h), which keeps most of
    // them from the cores.
    void set_sampler(Sampler* sampler) { sampler_ = sampler; }
    // Sampled simulation (sim.sample_window_hold), before the chip is built: the first ray of
    // a detailed window after fast-forwarded rays is held for the cycles the sampler predicts
    // the skipped work would have taken (Predicted) or until the rays in flight have finished
    // (Drain). Fast-forwarded rays take no simulated time, so the rays of the window before
    // would otherwise share the cores with the new window's warm-up and measured unit, where
    // in the full run the skipped work's cycles lay between them.
    enum class WindowHold { None, Predicted, Drain };
    void hold_windows(WindowHold hold, uint64_t release_in_flight = 0) {
        hold_ = hold;
        hold_release_in_flight_ = release_in_flight;
    }

    void finish_progress() {
        if (progress_ && printed_) std::fprintf(stderr, "\r%100s\r", "");
    }

    std::array<uint64_t, kRayKindCount> rays_by_kind{}, hits_by_kind{};
    uint64_t steps = 0;
    double functional_seconds = 0;  // time the simulation waited for rays to be produced
                                    // (subclasses measure it where they block)
    // Bad input found mid-run (a damaged trace chunk) stops the simulation; run_command reports
    // it after the kernel returns, without throwing (exceptions must not cross SystemC's
    // coroutine stacks, which AddressSanitizer cannot follow either).
    std::string failure;
    bool failure_is_input = false;
    int interrupted_by = 0;  // the signal that stopped the run (sim/interrupt.h), or 0
    bool failed() const { return !failure.empty(); }

  protected:
    Sampler* sampler_ = nullptr;
    // The tile the work item produce() filled last came from (-1: not known, a trace replay).
    virtual int64_t current_tile() const { return -1; }
    // Fills the next work item (a ray, or a packet of work.rays rays); `hits`: how many hit.
    virtual bool produce(RayWork& work, uint32_t& hits) = 0;

    void report_progress(double fraction, const char* what) {
        if (!progress_) return;
        const auto now = WorkClock::now();
        if (printed_ && now - last_print_ < std::chrono::milliseconds(250)) return;
        last_print_ = now;
        printed_ = true;
        if (!started_) {
            started_ = true;
            start_ = now;
        }
        uint64_t rays = 0;
        for (uint64_t r : rays_by_kind) rays += r;
        const std::string left =
            time_left(std::chrono::duration<double>(now - start_).count(), fraction);
        std::fprintf(stderr, "\r[rtsim] %5.1f%% of %s, %llu rays, %.4g simulated us%s%s   ",
                     100.0 * fraction, what, (unsigned long long)rays,
                     sc_core::sc_time_stamp().to_seconds() * 1e6, left.empty() ? "" : ", ",
                     left.c_str());
        std::fflush(stderr);
    }

  private:
    bool progress_, printed_ = false, started_ = false;
    WorkClock::time_point last_print_, start_;
    // The next work item that reaches a core (a sampled run fast-forwards the others); false
    // when none is left or the run stopped.
    bool produce_next(RayWork& work) {
        // SIGINT or SIGTERM: no more rays (the slots finish the ones they hold, then the run
        // reports the interruption and writes nothing).
        if (!failed() && interrupt_signal()) {
            interrupted_by = interrupt_signal();
            failure = "interrupted";
        }
        for (;;) {
            uint32_t hit = 0;
            const bool more = failed() ? false : produce(work, hit);
            if (!more) return false;
            rays_by_kind[static_cast<int>(work.kind)] += work.rays;
            hits_by_kind[static_cast<int>(work.kind)] += hit;
            steps += work.steps.size();
            // A sampled run fast-forwards most rays here: they warm the caches, no core runs them.
            if (!sampler_ || !sampler_->fast_forward(work, current_tile())) return true;
        }
    }
    // Rays handed out before now are still running (a core reports a ray finished once it
    // knows when, so `done` may be ahead of `now`).
    bool draining(Cycle now) const { return in_flight_ > 0 || last_done_ > now; }
    bool released(Cycle now) const {
        return now >= hold_until_ || in_flight_ <= hold_release_in_flight_;
    }
    // Whether the window starting at `now` waits (and until when, if predicted).
    bool start_hold(Cycle now) {
        if (hold_ == WindowHold::Drain) return draining(now);
        hold_until_ = now + Cycle(std::llround(sampler_->window_hold_cycles()));
        return !released(now);
    }
    void hand_out(Cycle now) {
        if (sampler_) sampler_->handed_out(now);
        ++in_flight_;
    }
    void wake_at(Cycle at) {
        wake_pending_ = true;
        wake_cycle_ = at;
    }
    // Held windows: how, work items handed out and not finished (and how few of them release
    // a predicted hold), the latest finish reported (a drained hold's item goes from then), the
    // end of a predicted hold, the held item.
    WindowHold hold_ = WindowHold::None;
    bool held_ = false, wake_pending_ = false;
    uint64_t in_flight_ = 0, hold_release_in_flight_ = 0;
    Cycle last_done_ = 0, wake_cycle_ = 0, hold_until_ = 0;
    RayWork held_work_;
};

// Work prepared on a helper thread, up to kAheadBatches batches ahead of the simulation: while a
// second host core is free, the simulation waits for ray generation, tracing or trace decoding
// only where they are slower than it over that many batches (one batch ahead, a 1-in-50 sampled
// run of a 1080p diffuse frame, whose rays come in bursts between long cache replays, waited 17
// ms for its first 4,148 rays). Errors (a damaged trace chunk) surface on that thread, never
// inside a SystemC process (whose coroutine stacks exceptions must not cross, and which
// AddressSanitizer cannot follow).
class PrefetchingSource : public CountingSource {
  public:
    PrefetchingSource(bool progress, const char* unit) : CountingSource(progress), unit_(unit) {}
    // Derived destructors stop the helper first (see prefetch); this only makes sure no thread
    // is left joinable.
    ~PrefetchingSource() override { stop_helper(); }

  protected:
    struct Batch {
        std::vector<TraceRecord> records;
        // Packet mode: per record (a packet), its rays and how many of them hit.
        std::vector<uint8_t> packet_rays;
        std::vector<uint32_t> packet_hits;
        // Per record, the tile it came from (filled when a sampled run skips tiles).
        std::vector<uint32_t> tiles;
        double progress = 0;  // fraction of the work done once this batch is used
        bool last = false;    // nothing follows
        std::string error;
        bool input_error = false;
    };
    // Fills the next batch, on the helper thread. It starts with the records of a used batch
    // (their contents are stale; only their memory is worth keeping).
    virtual void fill(Batch& batch) = 0;

    // Derived constructors start the first batch; derived destructors call stop_helper() first, so
    // fill() never runs on a half-destroyed object.
    // `used`: the batch just consumed. Its records (holding the step vectors the ray slots gave
    // back) start the next batch, so a fill may reuse their memory instead of allocating per
    // ray; whatever it does not reuse is freed on the helper thread, which allocated it (a
    // free on another thread's arena costs the simulation thread a lock).
    // One helper thread serves every batch (batches are small, and a thread per batch cost
    // more than decoding one).
    void prefetch() { prefetch(Batch{}); }
    void prefetch(Batch used) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!helper_.joinable()) helper_ = std::thread([this] { help(); });
        if (!used.records.empty()) recycled_.push_back(std::move(used));
        cv_.notify_all();
    }
    // Stops the helper thread once it has finished the batch it may be filling.
    void stop_helper() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stopping_ = true;
            cv_.notify_all();
        }
        if (helper_.joinable()) helper_.join();
    }

    bool produce(RayWork& work, uint32_t& hits) override {
        while (pos_ == batch_.records.size()) {
            if (batch_.last) return false;
            const auto t0 = WorkClock::now();
            Batch used = std::exchange(batch_, take());
            functional_seconds += std::chrono::duration<double>(WorkClock::now() - t0).count();
            pos_ = 0;
            if (!batch_.error.empty()) {
                failure = batch_.error;
                failure_is_input = batch_.input_error;
                batch_.last = true;
                sc_core::sc_stop();
                return false;
            }
            report_progress(batch_.progress, unit_);
            if (!batch_.last) prefetch(std::move(used));  // its memory, back to the helper
        }
        // The next rays' steps were written on the helper thread: start moving them into this
        // core's caches before a ray slot needs them.
        if (pos_ + kPrefetchAheadRays < batch_.records.size()) {
            const auto& ahead = batch_.records[pos_ + kPrefetchAheadRays].steps;
            const char* p = reinterpret_cast<const char*>(ahead.data());
            for (size_t b = 0; b < ahead.size() * sizeof(Step); b += 64) __builtin_prefetch(p + b);
        }
        TraceRecord& r = batch_.records[pos_++];
        work.ray_id = r.ray_id;
        work.kind = r.kind;
        work.steps.swap(r.steps);
        work.rays = 1;
        hits = r.prim != kInvalidPrim;
        if (pos_ <= batch_.tiles.size()) tile_ = batch_.tiles[pos_ - 1];
        if (pos_ <= batch_.packet_hits.size()) {
            work.rays = batch_.packet_rays[pos_ - 1];
            hits = batch_.packet_hits[pos_ - 1];
        }
        return true;
    }
    int64_t current_tile() const override { return tile_; }

  private:
    // The helper thread: fills batches while fewer than kAheadBatches wait, until the last one
    // (or one that failed) or until stopped.
    void help() {
        std::unique_lock<std::mutex> lock(mutex_);
        for (;;) {
            cv_.wait(lock, [this] {
                return stopping_ || (!filled_last_ && filled_.size() < kAheadBatches);
            });
            if (stopping_) return;
            Batch b;
            if (!recycled_.empty()) {
                b.records = std::move(recycled_.back().records);
                recycled_.pop_back();
            }
            lock.unlock();
            try {
                fill(b);
            } catch (const InputError& e) {
                b.error = e.what();
                b.input_error = true;
            } catch (const std::exception& e) {
                b.error = e.what();
            }
            lock.lock();
            filled_last_ = b.last || !b.error.empty();
            filled_.push_back(std::move(b));
            cv_.notify_all();
        }
    }
    // The next batch, once the helper has filled it.
    Batch take() {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait(lock, [this] { return !filled_.empty(); });
        Batch b = std::move(filled_.front());
        filled_.pop_front();
        cv_.notify_all();
        return b;
    }

    static constexpr size_t kPrefetchAheadRays = 4;
    static constexpr size_t kAheadBatches = 3;
    const char* unit_;
    Batch batch_;
    size_t pos_ = 0;
    int64_t tile_ = -1;
    std::thread helper_;
    std::mutex mutex_;  // guards what follows
    std::condition_variable cv_;
    std::deque<Batch> filled_;  // filled, in order, not taken yet
    // Used batches, whole: their records' memory starts the next fills, and the rest (tiles,
    // packet counts) is freed here on the helper thread, which allocated it.
    std::vector<Batch> recycled_;
    bool filled_last_ = false;  // the helper filled the last batch (or one that failed)
    bool stopping_ = false;
};

// Rays from the generator, traced a batch of tiles at a time: only a few batches of rays (the
// one in use and up to kAheadBatches filled) hold step streams at any time. With `threads` > 1,
// tiles are generated and traced that many at a time, on the helper thread and threads - 1 more (a
// sampled run traces every ray but times a few: the functional side is what it waits for). The
// stream is the same for any thread count: tiles are handed on in order, ray ids numbered through
// the frame as one thread would, and a batch is whole tiles up to kBatchRays rays as before
// (packets never span batches).
class GeneratedWorkSource : public PrefetchingSource {
  public:
    // packet_size > 0: runs of consecutive rays of one kind are traced as packets of up to
    // that many rays, each packet one work item.
    // `want_tile` (optional): tiles it refuses are never generated (a sampled run's skip design),
    // and each ray's tile is then passed on with it.
    GeneratedWorkSource(const Bvh& bvh, RayGenerator& gen, bool progress, int packet_size = 0,
                        int threads = 1, std::function<bool(int)> want_tile = {})
        : PrefetchingSource(progress, "tiles"),
          bvh_(&bvh),
          gen_(gen),
          packet_size_(packet_size),
          record_tiles_(bool(want_tile)),
          tiles_(gen, threads, packet_size > 0 ? TraceRays() : tracer_of(bvh),
                 std::move(want_tile)) {
        gen_.set_record_steps(packet_size_ == 0);  // packets trace their own way
        prefetch();
    }
    // Over a two-level scene (single rays: packets trace one level).
    GeneratedWorkSource(const TwoLevelBvh& bvh, RayGenerator& gen, bool progress, int threads = 1,
                        std::function<bool(int)> want_tile = {})
        : PrefetchingSource(progress, "tiles"),
          gen_(gen),
          packet_size_(0),
          record_tiles_(bool(want_tile)),
          tiles_(gen, threads, tracer_of(bvh), std::move(want_tile)) {
        gen_.set_record_steps(true);
        prefetch();
    }
    ~GeneratedWorkSource() override { stop_helper(); }

  protected:
    void fill(Batch& b) override {
        b.records.clear();  // steps are moved in from the tracer: nothing to reuse
        // The first batches are small and grow to kBatchRays: the simulation waits for the
        // first one whole (a 1-in-50 sampled run of a 1080p diffuse frame traces about two
        // batches' rays in all, and waited for the first on most of its simulation time).
        // Packets never span batches, so their batches keep one size.
        const size_t batch_rays = packet_size_ > 0 ? kBatchRays : next_batch_rays_;
        next_batch_rays_ = std::min(kBatchRays, 2 * next_batch_rays_);
        // Kept from batch to batch: a fresh vector grown to a batch's rays was hundreds of
        // fresh pages each time (page faults cost about 5 us each on these VMs).
        std::vector<GeneratedRay>& rays = rays_;
        rays.clear();
        b.tiles.clear();
        bool more = true;
        while (rays.size() < batch_rays && (more = tiles_.next(rays)))
            if (record_tiles_) b.tiles.resize(rays.size(), uint32_t(tiles_.last_tile()));
        if (packet_size_ > 0) {
            fill_packets(rays, b);
        } else {
            b.records.resize(rays.size());
            for (size_t i = 0; i < rays.size(); ++i) {
                TraceRecord& r = b.records[i];
                r.ray_id = rays[i].id;
                r.kind = rays[i].kind;
                r.steps = std::move(rays[i].steps);
                r.prim = rays[i].prim;
            }
        }
        b.progress = double(tiles_.tiles_handed_on()) / std::max(1, gen_.tile_count());
        b.last = !more;
    }

  private:
    static constexpr size_t kBatchRays = 4096, kFirstBatchRays = 256;
    std::vector<GeneratedRay> rays_;            // fill's, on the helper thread
    size_t next_batch_rays_ = kFirstBatchRays;  // fill's: the next batch's rays
    void fill_packets(const std::vector<GeneratedRay>& rays, Batch& b) {
        Ray packet[kMaxPacketSize];
        Hit hits[kMaxPacketSize];
        PacketOptions po;
        po.size = packet_size_;
        PacketStats ps;
        for (const auto& [i, e] :
             packet_runs(rays.size(), packet_size_, [&](size_t k) { return rays[k].kind; })) {
            const int n = int(e - i);
            for (int k = 0; k < n; ++k) packet[k] = rays[i + size_t(k)].ray;
            TraceRecord r;
            r.ray_id = rays[i].id;
            r.kind = rays[i].kind;
            trace_packet(*bvh_, packet, n, rays[i].query, hits, po, ps, &r.steps);
            uint32_t hit_count = 0;
            for (int k = 0; k < n; ++k) hit_count += hits[k].valid();
            b.records.push_back(std::move(r));
            b.packet_rays.push_back(uint8_t(n));
            b.packet_hits.push_back(hit_count);
        }
    }

    const Bvh* bvh_ = nullptr;  // packets only
    RayGenerator& gen_;
    int packet_size_;
    bool record_tiles_;
    TileQueue tiles_;  // used by the helper thread only (and the tile threads it starts)
};

// Rays replayed from a trace file, a chunk at a time.
class TraceWorkSource : public PrefetchingSource {
  public:
    TraceWorkSource(TraceReader& reader, bool progress)
        : PrefetchingSource(progress, "chunks"), reader_(reader) {
        prefetch();
    }
    ~TraceWorkSource() override { stop_helper(); }

  protected:
    void fill(Batch& b) override {
        // A batch is at most kBatchRays of a chunk: its steps (~300 bytes a ray) stay in the
        // host's caches until the cores run them, even with the decoding on the same core.
        constexpr size_t kBatchRays = 1024;
        if (reader_.chunk_rays_left() == 0 && next_chunk_ < reader_.chunk_count())
            reader_.open_chunk(next_chunk_++);
        reader_.read_records(kBatchRays, b.records);
        b.progress = double(next_chunk_) / double(std::max<size_t>(1, reader_.chunk_count()));
        b.last = next_chunk_ == reader_.chunk_count() && reader_.chunk_rays_left() == 0;
    }

  private:
    TraceReader& reader_;
    size_t next_chunk_ = 0;  // touched by the helper thread only
};

}  // namespace rtsim

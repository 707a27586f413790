// A stream buffer (Jouppi, ISCA 1990): a small FIFO of lines read ahead of the misses that pass
// through it. A read that misses goes on to the next level, and the block reads the `depth` lines
// after it ahead into the buffer; a read that finds its line (arrived, or still on its way) takes
// it from the buffer after hit_latency_cycles and reads one more line ahead, so a stream stays
// `depth` lines ahead of its reader. A full buffer drops its oldest line. Writes pass through and
// drop the lines they overlap. Lines are the size of the reads that reach it (the caches' lines
// above it), and no line at or past the caches' address limit is read ahead.
//
// Both engines run the same rules. Loosely timed (fast), a line read ahead carries the cycle the
// next level said it will be there; a read finding it waits until then. Time-ordered (accurate), a
// read is looked up at its arrival cycle, and one finding a line still on its way is answered when
// that line's own answer comes. In stall attribution the buffer's cycles (its hit latency, and a
// wait for a line on its way) go to the level it stands in front of.
#include <algorithm>
#include <deque>

#include "models/memory_block.h"

namespace rtsim {
namespace {

class StreamBuffer final : public MemoryBlock, public MemoryPort, private StageHandler {
  public:
    StreamBuffer(sc_core::sc_module_name name, const nlohmann::json& config,
                 const MemoryBlockSetting& setting)
        : MemoryBlock(name),
          up("up"),
          down("down"),
          entries_(config.at("entries").get<size_t>()),
          // (A stream deeper than the buffer would drop its own lines before they are read.)
          depth_(std::min(config.at("depth").get<uint64_t>(), uint64_t(entries_))),
          hit_latency_(config.at("hit_latency_cycles").get<Cycle>()),
          setting_(setting) {
        up.register_b_transport<&StreamBuffer::b_transport>(this);
        up.register_nb_transport_fw<&StreamBuffer::nb_transport_fw>(this);
        down.register_nb_transport_bw(this, &StreamBuffer::nb_transport_bw);
    }

    TargetSocket<StreamBuffer> up;
    InitiatorSocket<StreamBuffer> down;
    TargetSocketBase& target_socket() override { return up; }
    void set_stage_queue(StageQueue* queue) override { stages_ = queue; }
    void bind_below(TargetSocketBase& below) override { down.bind(below); }

    // ---- Loosely timed (MemoryPort, through b_transport) ----
    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now, AccessBreakdown* bd) override {
        count_read(now);
        // (A line read ahead at a later cycle than `now`, by a read the fast engine met first,
        // was not yet asked for at `now`: the read misses, as it would in time order.)
        if (const int s = find(addr, size_bytes);
            s >= 0 && lines_[slots_[size_t(s)]].issued <= now) {
            const Cycle ready = lines_[slots_[size_t(s)]].ready;
            const Cycle done = std::max(now, ready) + hit_latency_;
            if (bd) bd->cycles[setting_.level] += done - now;
            take(s, ready > now);
            read_ahead_lt(addr + depth_ * size_bytes, size_bytes, now);
            return done;
        }
        const Cycle done = below_.read(addr, size_bytes, now, bd);
        for (uint64_t k = 1; k <= depth_; ++k)
            read_ahead_lt(addr + k * size_bytes, size_bytes, now);
        return done;
    }
    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        ++writes_;
        drop_overlapping(addr, size_bytes);
        return below_.write(addr, size_bytes, now);
    }
    // Functional warming leaves the lines a read would have left, counting nothing.
    void warm(uint64_t addr, uint32_t size_bytes) override {
        if (const int s = find(addr, size_bytes); s >= 0) {
            take(s, false, /*counted=*/false);
            warm_ahead(addr + depth_ * size_bytes, size_bytes);
            return;
        }
        below_.warm(addr, size_bytes);
        for (uint64_t k = 1; k <= depth_; ++k) warm_ahead(addr + k * size_bytes, size_bytes);
    }
    void warm_write(uint64_t addr, uint32_t size_bytes) override {
        drop_overlapping(addr, size_bytes, /*counted=*/false);
        below_.warm(addr, size_bytes, true);
    }

    void register_stats(StatsRegistry& reg) override {
        const std::string block = name();
        reg.add(block, "reads", &reads_, "reads that reached the buffer");
        reg.add(block, "hits", &hits_, "reads that found their line in the buffer");
        reg.add(block, "late_hits", &late_hits_,
                "of the hits, lines still on their way (the read waited for them)");
        reg.add(block, "read_aheads", &read_aheads_, "lines read ahead from the next level");
        reg.add(block, "unused_read_aheads", &unused_,
                "lines read ahead and dropped (buffer full, or written) before any read took them");
        reg.add(block, "writes", &writes_, "writes passed through");
        reg.add(block, "out_of_order_reads", &out_of_order_reads_,
                "reads that came after a read later in simulated time (the fast engine's order; "
                "its lines read ahead depend on it)");
    }
    uint64_t out_of_order_requests() const override { return out_of_order_reads_; }
    uint64_t requests() const override { return reads_ + writes_; }
    nlohmann::json report(const ReportContext&) const override {
        return {{"block", "stream_buffer"},
                {"reads", reads_},
                {"hits", hits_},
                {"late_hits", late_hits_},
                {"hit_rate", ReportContext::ratio(double(hits_), double(reads_))},
                {"read_aheads", read_aheads_},
                // Of the lines read ahead, the share a read took.
                {"accuracy", ReportContext::ratio(double(hits_), double(read_aheads_))},
                {"writes", writes_}};
    }

  private:
    // A line read ahead. Kept by id while it is in the buffer or on its way with reads waiting.
    struct Line {
        uint64_t addr = 0;
        uint32_t size_bytes = 0;
        Cycle issued = 0;     // the cycle it was read ahead at
        Cycle ready = 0;      // the cycle it is (or will be) there
        bool arrived = true;  // time-ordered: false while its read is on its way
        bool in_buffer = false;
        bool taken = false;                      // a read took it
        tlm::tlm_generic_payload* gp = nullptr;  // time-ordered: its read, while on its way
        std::vector<uint32_t> waiting;           // time-ordered: reads waiting for it (held ids)
    };

    void count_read(Cycle t) {
        ++reads_;
        out_of_order_reads_ += t < latest_read_;
        latest_read_ = std::max(latest_read_, t);
    }
    // The slot holding (addr, size_bytes), or -1.
    int find(uint64_t addr, uint32_t size_bytes) {
        for (size_t s = 0; s < slots_.size(); ++s) {
            const Line& l = lines_[slots_[s]];
            if (l.addr == addr && l.size_bytes == size_bytes) return int(s);
        }
        return -1;
    }
    // Whether a line may be read ahead: below the address limit, not already held.
    bool wanted(uint64_t addr, uint32_t size_bytes) {
        return addr + size_bytes <= setting_.address_limit_bytes && find(addr, size_bytes) < 0;
    }
    // A new line in the buffer, its oldest line dropped if full; returns its id.
    uint32_t insert(uint64_t addr, uint32_t size_bytes, bool counted) {
        if (slots_.size() == entries_) leave(0, counted);
        const uint32_t id = lines_.take();
        Line& l = lines_[id];
        l = Line{};
        l.addr = addr;
        l.size_bytes = size_bytes;
        l.in_buffer = true;
        slots_.push_back(id);
        return id;
    }
    // A read takes the line in slot `s` (`late`: before the line is there).
    void take(int s, bool late, bool counted = true) {
        Line& l = lines_[slots_[size_t(s)]];
        l.taken = true;
        if (counted) {
            ++hits_;
            late_hits_ += late;
        }
        leave(size_t(s), counted);
    }
    // The line in slot `s` leaves the buffer; its record goes once nothing waits on it.
    void leave(size_t s, bool counted) {
        const uint32_t id = slots_[s];
        slots_.erase(slots_.begin() + std::ptrdiff_t(s));
        Line& l = lines_[id];
        l.in_buffer = false;
        if (counted && !l.taken) ++unused_;
        if (l.arrived) lines_.remove(id);
    }
    void drop_overlapping(uint64_t addr, uint32_t size_bytes, bool counted = true) {
        for (size_t s = slots_.size(); s-- > 0;) {
            const Line& l = lines_[slots_[s]];
            if (l.addr < addr + size_bytes && addr < l.addr + l.size_bytes) leave(s, counted);
        }
    }
    void read_ahead_lt(uint64_t addr, uint32_t size_bytes, Cycle now) {
        if (!wanted(addr, size_bytes)) return;
        ++read_aheads_;
        const Cycle ready = below_.read(addr, size_bytes, now);
        Line& l = lines_[insert(addr, size_bytes, true)];
        l.issued = now;
        l.ready = ready;
    }
    void warm_ahead(uint64_t addr, uint32_t size_bytes) {
        if (!wanted(addr, size_bytes)) return;
        below_.warm(addr, size_bytes);
        insert(addr, size_bytes, false);
    }
    void b_transport(int, tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
        serve_loosely_timed(*this, gp, delay);
    }

    // ---- Time-ordered (nb_transport, stages on the StageQueue) ----
    enum Stage : uint32_t { kArriveStage, kAnswerStage };

    tlm::tlm_sync_enum nb_transport_fw(int id, tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time& delay) {
        MemoryRequest& r = memory_request(gp);
        r.push_route(id);
        if (gp.is_write()) {  // drops what it overlaps and goes on at once
            ++writes_;
            drop_overlapping(gp.get_address(), gp.get_data_length());
            const tlm::tlm_sync_enum status = down->nb_transport_fw(gp, phase, delay);
            if (status == tlm::TLM_COMPLETED) r.pop_route();
            return status;
        }
        const uint32_t h = held_.add(&gp);
        const Cycle at = stages_->now() + delay_cycles(delay);
        if (r.queued)
            stages_->schedule(at, StageQueue::kMemoryOrder, this, kArriveStage, h);
        else
            arrive(h, at);
        phase = tlm::END_REQ;
        return tlm::TLM_UPDATED;
    }

    // A read reaches the buffer at `t`: found, it is answered from it (now or when its line comes);
    // not found, it goes on to the next level.
    void arrive(uint32_t h, Cycle t) {
        tlm::tlm_generic_payload& gp = *held_[h];
        const uint64_t addr = gp.get_address();
        const uint32_t size_bytes = gp.get_data_length();
        count_read(t);
        if (const int s = find(addr, size_bytes); s >= 0) {
            const uint32_t id = slots_[size_t(s)];
            const bool late = !lines_[id].arrived;
            if (late)
                lines_[id].waiting.push_back(h);
            else
                answer(h, t);
            take(s, late);
            read_ahead_at(addr + depth_ * size_bytes, size_bytes, t);
            return;
        }
        held_.remove(h);
        tlm::tlm_phase phase = tlm::BEGIN_REQ;
        sc_core::sc_time delay = cycles_delay(t - stages_->now());
        down->nb_transport_fw(gp, phase, delay);  // its answer passes up through nb_transport_bw
        for (uint64_t k = 1; k <= depth_; ++k) read_ahead_at(addr + k * size_bytes, size_bytes, t);
    }
    // Held read `h`, its line there at `t`: answered after the hit latency.
    void answer(uint32_t h, Cycle t) {
        memory_request(*held_[h]).timeline.add(t + hit_latency_, setting_.level);
        // The answer completes a fill above: first in its cycle.
        stages_->schedule(t + hit_latency_, StageQueue::kFillOrder, this, kAnswerStage, h);
    }
    void read_ahead_at(uint64_t addr, uint32_t size_bytes, Cycle t) {
        if (!wanted(addr, size_bytes)) return;
        ++read_aheads_;
        const uint32_t id = insert(addr, size_bytes, true);
        lines_[id].issued = t;
        tlm::tlm_generic_payload& gp =
            payloads_.acquire(tlm::TLM_READ_COMMAND, addr, size_bytes, t);
        memory_request(gp).owner_id = id;
        lines_[id].arrived = false;
        lines_[id].gp = &gp;
        tlm::tlm_phase phase = tlm::BEGIN_REQ;
        sc_core::sc_time delay = cycles_delay(t - stages_->now());
        down->nb_transport_fw(gp, phase, delay);
    }
    void run_stage(uint32_t kind, uint32_t h, uint32_t, Cycle t) override {
        if (kind == kArriveStage) {
            arrive(h, t);
            return;
        }
        tlm::tlm_generic_payload& gp = *held_[h];
        held_.remove(h);
        pass_up(gp);
    }
    // The next level's answer: a line read ahead is there (its waiting reads are answered), or a
    // read or write that went on is passed up as it came.
    tlm::tlm_sync_enum nb_transport_bw(tlm::tlm_generic_payload& gp, tlm::tlm_phase& phase,
                                       sc_core::sc_time&) {
        const uint32_t id = memory_request(gp).owner_id;
        if (!gp.is_write() && id < lines_.size() && lines_[id].gp == &gp) {
            Line& l = lines_[id];
            const Cycle t = stages_->now();
            l.arrived = true;
            l.ready = t;
            l.gp = nullptr;
            for (const uint32_t h : l.waiting) {
                memory_request(*held_[h]).timeline.add(t, setting_.level);
                answer(h, t);
            }
            l.waiting.clear();
            if (!l.in_buffer) lines_.remove(id);
            payloads_.release(gp);
        } else {
            pass_up(gp);
        }
        phase = tlm::END_RESP;
        return tlm::TLM_COMPLETED;
    }
    void pass_up(tlm::tlm_generic_payload& gp) {
        gp.set_response_status(tlm::TLM_OK_RESPONSE);
        tlm::tlm_phase phase = tlm::BEGIN_RESP;
        sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
        up[memory_request(gp).pop_route()]->nb_transport_bw(gp, phase, delay);
    }

    const size_t entries_;
    const uint64_t depth_;
    const Cycle hit_latency_;
    const MemoryBlockSetting setting_;
    IdPool<Line> lines_;
    std::deque<uint32_t> slots_;  // the buffer, oldest first
    StageQueue* stages_ = nullptr;
    IdPool<tlm::tlm_generic_payload*> held_;  // reads answered from the buffer
    PayloadPool payloads_;                    // lines read ahead
    uint64_t reads_ = 0, hits_ = 0, late_hits_ = 0, read_aheads_ = 0, unused_ = 0, writes_ = 0;
    uint64_t out_of_order_reads_ = 0;
    Cycle latest_read_ = 0;
    LtPort below_{down};
};

std::unique_ptr<MemoryBlock> make_stream_buffer(const char* module_name,
                                                const nlohmann::json& config,
                                                const MemoryBlockSetting& setting) {
    return std::make_unique<StreamBuffer>(module_name, config, setting);
}

}  // namespace

RTSIM_REGISTER(MemoryBlockEntry,
               {"stream_buffer",
                "a FIFO of lines read ahead of the misses through it (Jouppi 1990): a miss reads "
                "the next depth lines ahead, a hit takes its line and reads one more",
                {"memory_path.stream_buffer.entries", "memory_path.stream_buffer.depth",
                 "memory_path.stream_buffer.hit_latency_cycles"},
                &make_stream_buffer})

}  // namespace rtsim

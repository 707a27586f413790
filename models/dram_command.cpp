#include "models/dram_command.h"

#include <algorithm>
#include <limits>

#include <fmt/format.h>

namespace rtsim {

namespace {

// The same bank of the same rank (and channel: requests are per channel's queues).
bool same_bank(const DramAddress& x, const DramAddress& y) {
    return x.rank == y.rank && x.bankgroup == y.bankgroup && x.bank == y.bank;
}

bool power_of_two(int64_t v) {
    return v > 0 && (v & (v - 1)) == 0;
}
int log2i(int64_t v) {
    int n = 0;
    while ((int64_t(1) << n) < v) ++n;
    return n;
}

}  // namespace

const char* dram_command_name(DramCommand c) {
    switch (c) {
        case DramCommand::Act:
            return "ACT";
        case DramCommand::Rd:
            return "RD";
        case DramCommand::Wr:
            return "WR";
        case DramCommand::Pre:
            return "PRE";
        case DramCommand::Ref:
            return "REF";
        case DramCommand::RefPb:
            return "REFpb";
    }
    return "?";
}

uint64_t DramDeviceSpec::capacity_bytes() const {
    return uint64_t(data_channels()) * uint64_t(ranks) * uint64_t(banks_per_rank()) *
           uint64_t(rows) * uint64_t(columns) * uint64_t(bus_width_bits / 8);
}

std::string DramDeviceSpec::check() const {
    const std::pair<const char*, int64_t> pow2[] = {
        {"channels", channels},     {"pseudo_channels", pseudo_channels}, {"ranks", ranks},
        {"bankgroups", bankgroups}, {"banks_per_group", banks_per_group}, {"rows", rows},
        {"columns", columns},       {"burst_length", burst_length}};
    for (const auto& [field, v] : pow2)
        if (!power_of_two(v)) return fmt::format("{}: expected a power of two, got {}", field, v);
    if (device_width_bits <= 0 || bus_width_bits <= 0 || bus_width_bits % device_width_bits != 0)
        return fmt::format("bus_width_bits ({}) must be a multiple of device_width_bits ({})",
                           bus_width_bits, device_width_bits);
    if (!power_of_two(bus_width_bits / 8 * burst_length))
        return fmt::format(
            "a burst of {} bytes (bus_width_bits / 8 x burst_length) is not a power "
            "of two",
            bus_width_bits / 8 * burst_length);
    if (columns < burst_length)
        return fmt::format("columns ({}) must be at least burst_length ({})", columns,
                           burst_length);
    if (burst_cycles < 1)
        return fmt::format("burst_cycles: expected 1 or more, got {}", burst_cycles);
    if (!(tck_ns > 0)) return fmt::format("tck_ns: expected a positive period, got {}", tck_ns);
    const std::pair<const char*, int> timing[] = {{"cl", cl},
                                                  {"cwl", cwl},
                                                  {"t_rcd", t_rcd},
                                                  {"t_rp", t_rp},
                                                  {"t_ras", t_ras},
                                                  {"t_rtp", t_rtp},
                                                  {"t_wr", t_wr},
                                                  {"t_wtr_s", t_wtr_s},
                                                  {"t_wtr_l", t_wtr_l},
                                                  {"t_ccd_s", t_ccd_s},
                                                  {"t_ccd_l", t_ccd_l},
                                                  {"t_rrd_s", t_rrd_s},
                                                  {"t_rrd_l", t_rrd_l},
                                                  {"t_faw", t_faw},
                                                  {"t_rtrs", t_rtrs},
                                                  {"t_refi", t_refi},
                                                  {"t_rfc", t_rfc},
                                                  {"t_32aw", t_32aw},
                                                  {"t_rcd_wr", t_rcd_wr},
                                                  {"wck_sync_cycles", wck_sync_cycles},
                                                  {"wck_postamble_cycles", wck_postamble_cycles},
                                                  {"t_refi_pb", t_refi_pb},
                                                  {"t_rfc_pb", t_rfc_pb},
                                                  {"t_pbr2pbr", t_pbr2pbr},
                                                  {"t_pbr2act", t_pbr2act}};
    for (const auto& [field, v] : timing)
        if (v < 0) return fmt::format("{}: expected 0 or more cycles, got {}", field, v);
    if (!(bankwise_rho >= 0 && bankwise_rho <= 1))
        return fmt::format("bankwise_rho: expected a number from 0 to 1, got {}", bankwise_rho);
    if (refresh_mode != "all_bank" && refresh_mode != "per_bank")
        return fmt::format("refresh_mode: expected all_bank or per_bank, got '{}'", refresh_mode);
    if (refresh && !per_bank_refresh() && t_refi <= t_rfc)
        return fmt::format("t_refi ({}) must exceed t_rfc ({})", t_refi, t_rfc);
    if (refresh && per_bank_refresh()) {
        if (t_rfc_pb < 1)
            return "refresh_mode per_bank needs t_rfc_pb, the per-bank refresh cycle (tRFCpb)";
        if (refresh_pb_banks < 1 || banks_per_rank() % refresh_pb_banks != 0)
            return fmt::format("refresh_pb_banks ({}) must divide the {} banks of a rank",
                               refresh_pb_banks, banks_per_rank());
        // Every bank must be refreshable in turn faster than they fall due.
        if (int64_t(refresh_interval_pb()) * refreshes_per_round() <= t_rfc_pb)
            return fmt::format(
                "per-bank refresh: t_refi_pb ({}) x {} refreshes a round must exceed t_rfc_pb "
                "({})",
                refresh_interval_pb(), refreshes_per_round(), t_rfc_pb);
    }
    if (read_queue < 1 || write_queue < 1)
        return "read_queue and write_queue need at least one entry each";
    if (write_low < 0 || write_high > write_queue || write_low >= write_high)
        return fmt::format("expected 0 <= write_low < write_high <= write_queue, got {} {} {}",
                           write_low, write_high, write_queue);
    // The mapping: six two-letter fields, each once, and the pseudo-channel (pc) with
    // pseudo-channels.
    const size_t fields = pseudo_channels > 1 ? 7 : 6;
    if (address_mapping.size() != 2 * fields)
        return fmt::format(
            "address_mapping '{}': expected {} two-letter fields (ro ch{} ra bg ba co in some "
            "order)",
            address_mapping, fields, pseudo_channels > 1 ? " pc" : "");
    for (const char* f : {"ro", "ch", "pc", "ra", "bg", "ba", "co"}) {
        if (fields == 6 && std::string(f) == "pc") continue;
        int seen = 0;
        for (size_t i = 0; i < 2 * fields; i += 2) seen += address_mapping.compare(i, 2, f) == 0;
        if (seen != 1)
            return fmt::format("address_mapping '{}': field '{}' appears {} times, expected once",
                               address_mapping, f, seen);
    }
    return "";
}

DramAddressMap::DramAddressMap(const DramDeviceSpec& s) {
    shift_ = log2i(int64_t(s.burst_bytes()));
    pseudo_channels_ = s.pseudo_channels;
    auto width = [&](const std::string& f) {
        if (f == "ch") return log2i(s.channels);
        if (f == "pc") return log2i(s.pseudo_channels);
        if (f == "ra") return log2i(s.ranks);
        if (f == "bg") return log2i(s.bankgroups);
        if (f == "ba") return log2i(s.banks_per_group);
        if (f == "ro") return log2i(s.rows);
        return log2i(s.columns) - log2i(s.burst_length);  // co: bursts within a row
    };
    int pos = 0;
    // The mapping names fields from the most significant down: assign from its end.
    for (int i = int(s.address_mapping.size()) - 2; i >= 0; i -= 2) {
        const std::string f = s.address_mapping.substr(size_t(i), 2);
        const int w = width(f);
        Field field{pos, (uint64_t(1) << w) - 1};
        if (f == "ch")
            ch_ = field;
        else if (f == "pc")
            pc_ = field;
        else if (f == "ra")
            ra_ = field;
        else if (f == "bg")
            bg_ = field;
        else if (f == "ba")
            ba_ = field;
        else if (f == "ro")
            ro_ = field;
        else
            co_ = field;
        pos += w;
    }
}

DramAddress DramAddressMap::map(uint64_t addr) const {
    const uint64_t a = addr >> shift_;
    auto get = [a](const Field& f) { return (a >> f.pos) & f.mask; };
    DramAddress d;
    // Pseudo-channels of a channel are adjacent data channels.
    d.channel = int(get(ch_)) * pseudo_channels_ + int(get(pc_));
    d.rank = int(get(ra_));
    d.bankgroup = int(get(bg_));
    d.bank = int(get(ba_));
    d.row = uint32_t(get(ro_));
    d.column = uint32_t(get(co_));
    return d;
}

DramController::DramController(const DramDeviceSpec& spec)
    : spec_(spec),
      per_bank_refresh_(spec.per_bank_refresh()),
      refresh_step_(spec.refreshes_per_round()),
      map_(spec),
      channels_(size_t(spec.data_channels())) {
    const uint64_t interval =
        uint64_t(per_bank_refresh_ ? spec_.refresh_interval_pb() : spec_.t_refi);
    for (Channel& c : channels_) {
        c.banks.resize(size_t(spec_.ranks * spec_.banks_per_rank()));
        c.ranks.resize(size_t(spec_.ranks));
        // Ranks refresh staggered across the interval.
        for (int r = 0; r < spec_.ranks; ++r)
            c.ranks[size_t(r)].next_ref_due = interval * uint64_t(r + 1) / uint64_t(spec_.ranks);
    }
    // DRAMPower's increments as DRAMsim3 applies them: mA x V x ns = pJ, for every device of a
    // rank (a command reaches them all). Currents are a channel's: a pseudo-channel, half the
    // banks' background, half a page per activate and half the bits per burst, is charged its
    // share.
    const double k = spec_.vdd * spec_.tck_ns * spec_.devices_per_rank() / spec_.pseudo_channels;
    const int t_rc = spec_.t_ras + spec_.t_rp;
    e_act_ = k * (spec_.idd0 * t_rc - (spec_.idd3n * spec_.t_ras + spec_.idd2n * spec_.t_rp));
    e_rd_ = k * (spec_.idd4r - spec_.idd3n) * spec_.burst_cycles;
    e_wr_ = k * (spec_.idd4w - spec_.idd3n) * spec_.burst_cycles;
    e_ref_ = k * (spec_.idd5ab - spec_.idd3n) * spec_.t_rfc;
    e_ref_pb_ = spec_.idd5pb > 0 ? k * (spec_.idd5pb - spec_.idd2n) * spec_.refresh_interval_pb()
                                 : e_ref_ / spec_.refreshes_per_round();
    e_act_stby_ = k * spec_.idd3n;
    e_pre_stby_ = k * spec_.idd2n;
    if (spec_.bankwise_rho < 1) {
        const double i_rho = spec_.idd2n + spec_.bankwise_rho * (spec_.idd3n - spec_.idd2n);
        e_act_stby_ = k * i_rho;
        const int n = spec_.idd3n_open_banks > 0 ? spec_.idd3n_open_banks : spec_.banks_per_rank();
        e_open_bank_ = k * (spec_.idd3n - i_rho) / n;
    }
}

uint64_t DramController::pending() const {
    uint64_t n = 0;
    for (const Channel& c : channels_) n += c.reads.size() + c.writes.size();
    return n;
}

bool DramController::enqueue(uint64_t id, uint64_t addr, bool write, uint64_t cycle) {
    if (cycle > now_) run_until(cycle - 1);
    const DramAddress a = map_.map(addr);
    Channel& c = channels_[size_t(a.channel)];
    const uint64_t at = std::max(cycle, now_);
    if (write) {
        if (int(c.writes.size()) >= spec_.write_queue) return false;
        c.writes.push_back({id, at, a, true});
        return true;
    }
    if (int(c.reads.size()) >= spec_.read_queue) return false;
    // A read of data still waiting in the write queue is served from it.
    for (const Request& w : c.writes)
        if (same_bank(w.a, a) && w.a.row == a.row && w.a.column == a.column) {
            done_.push_back({id, at + 1, false});
            ++counters_.reads;
            counters_.read_latency_sum += 1;
            counters_.read_latency_max = std::max<uint64_t>(counters_.read_latency_max, 1);
            return true;
        }
    c.reads.push_back({id, at, a, false});
    return true;
}

void DramController::run_until(uint64_t cycle) {
    while (now_ <= cycle) {
        // Nothing queued: jump to the next refresh, or to the end.
        if (pending() == 0) {
            uint64_t next = cycle + 1;
            if (spec_.refresh)
                for (const Channel& c : channels_)
                    for (const Rank& r : c.ranks)
                        next = std::min(next, r.refresh_pending ? now_ : r.next_ref_due);
            if (next > now_) {
                now_ = std::min(next, cycle + 1);
                continue;
            }
        }
        // The pseudo-channels of a channel share its command buses; which goes first rotates.
        const auto pcs = size_t(spec_.pseudo_channels);
        for (size_t ch = 0; ch < channels_.size(); ch += pcs) {
            CommandSlots slots;
            for (size_t j = 0; j < pcs; ++j) {
                const size_t i = ch + (j + now_) % pcs;
                step(channels_[i], int(i), now_, slots);
            }
        }
        ++now_;
    }
}

uint64_t DramController::drain() {
    while (pending() > 0) run_until(now_);
    return now_ == 0 ? 0 : now_ - 1;
}

void DramController::settle_background() {
    for (Channel& c : channels_)
        for (Rank& r : c.ranks) account_background(r, now_);
}

void DramController::account_background(Rank& r, uint64_t until) {
    if (until <= r.bg_since) return;
    counters_.background_pj +=
        double(until - r.bg_since) *
        (r.open_banks > 0 ? e_act_stby_ + r.open_banks * e_open_bank_ : e_pre_stby_);
    r.bg_since = until;
}

void DramController::log(uint64_t t, DramCommand cmd, int ch, int ra, int bg, int ba,
                         uint32_t row) {
    if (record_) log_.push_back({t, cmd, ch, ra, bg, ba, row});
}

void DramController::step(Channel& c, int channel, uint64_t t, CommandSlots& slots) {
    // Refresh owed by a rank comes first.
    if (spec_.refresh)
        for (Rank& r : c.ranks)
            if (!r.refresh_pending && t >= r.next_ref_due) r.refresh_pending = true;
    if (slots.row && try_refresh(c, channel, t)) {
        take(slots, true);
        if (!slots.column) return;
    }
    // Writes drain between watermarks, or whenever no read waits.
    if (!c.draining &&
        (int(c.writes.size()) >= spec_.write_high || (c.reads.empty() && !c.writes.empty()))) {
        c.draining = true;
        ++counters_.write_drains;
    } else if (c.draining && (c.writes.empty() ||
                              (!c.reads.empty() && int(c.writes.size()) <= spec_.write_low))) {
        c.draining = false;
    }
    std::deque<Request>& q = c.draining ? c.writes : c.reads;
    if (q.empty()) return;
    // FR-FCFS: the oldest ready column command to an open row, else the oldest row command.
    if (slots.column && try_column(c, channel, q, t)) {
        take(slots, false);
        if (!slots.row) return;
    }
    if (slots.row && try_row(c, channel, q, t)) take(slots, true);
}

bool DramController::try_refresh(Channel& c, int channel, uint64_t t) {
    for (int ri = 0; ri < spec_.ranks; ++ri) {
        Rank& r = c.ranks[size_t(ri)];
        if (!r.refresh_pending) continue;
        if (per_bank_refresh_) {
            if (try_refresh_bank(c, channel, ri, t)) return true;
            continue;
        }
        // Close every open bank first, then REF once all may take it.
        bool ready = t >= r.busy_until;
        for (int bg = 0; bg < spec_.bankgroups; ++bg)
            for (int ba = 0; ba < spec_.banks_per_group; ++ba) {
                Bank& b =
                    c.banks[size_t((ri * spec_.bankgroups + bg) * spec_.banks_per_group + ba)];
                if (b.open) {
                    if (t >= b.next_pre) {
                        issue_pre(c, channel, ri, b, bg, ba, t);
                        return true;
                    }
                    ready = false;
                } else if (t < b.next_act) {
                    ready = false;  // tRP (or an auto-precharge) still running
                }
            }
        if (!ready) continue;
        account_background(r, t);
        const uint64_t end = t + uint64_t(spec_.t_rfc);
        for (int k = 0; k < spec_.banks_per_rank(); ++k) {
            Bank& b = c.banks[size_t(ri * spec_.banks_per_rank() + k)];
            b.next_act = std::max(b.next_act, end);
        }
        r.busy_until = end;
        r.refresh_pending = false;
        r.next_ref_due += uint64_t(spec_.t_refi);
        ++counters_.refs;
        counters_.refresh_pj += e_ref_;
        log(t, DramCommand::Ref, channel, ri, -1, -1, 0);
        return true;
    }
    return false;
}

bool DramController::try_refresh_bank(Channel& c, int channel, int rank_index, uint64_t t) {
    Rank& r = c.ranks[size_t(rank_index)];
    Bank* rank_banks = &c.banks[size_t(rank_index * spec_.banks_per_rank())];
    // The banks this refresh covers (in_bank_refresh) must each be closed (precharge an open
    // one), then past tRP, tRC or their own last refresh.
    bool ready = t >= r.next_ref_pb;  // tpbR2pbR
    for (int k = r.refresh_bank; k < spec_.banks_per_rank(); k += refresh_step_) {
        Bank& b = rank_banks[k];
        if (b.open) {
            if (t < b.next_pre) {
                ready = false;
                continue;
            }
            issue_pre(c, channel, rank_index, b, k / spec_.banks_per_group,
                      k % spec_.banks_per_group, t);
            return true;
        }
        if (t < b.next_act) ready = false;
    }
    if (!ready) return false;
    for (int o = 0; o < spec_.banks_per_rank(); ++o)
        rank_banks[o].next_act =
            std::max(rank_banks[o].next_act,
                     t + uint64_t(in_bank_refresh(r, o) ? spec_.t_rfc_pb : spec_.t_pbr2act));
    const int k = r.refresh_bank;
    r.next_ref_pb = t + uint64_t(spec_.t_pbr2pbr);
    r.refresh_pending = false;
    r.next_ref_due += uint64_t(spec_.refresh_interval_pb());
    r.refresh_bank = (k + 1) % refresh_step_;
    ++counters_.refs_per_bank;
    counters_.refresh_pj += e_ref_pb_;
    log(t, DramCommand::RefPb, channel, rank_index, k / spec_.banks_per_group,
        k % spec_.banks_per_group, 0);
    return true;
}

bool DramController::try_column(Channel& c, int channel, std::deque<Request>& q, uint64_t t) {
    // The queue holds one kind (reads or writes): while the data bus is taken past this one's
    // data start, no column command can issue (a busy channel spends most cycles here).
    const uint64_t data_latency = uint64_t(!q.empty() && q.front().write ? spec_.cwl : spec_.cl);
    if (t + data_latency < c.data_free) return false;
    if (still_idle(c, c.idle_column, q, t)) return false;
    // Banks whose open row a starving request waits to close: no more hits there. (Starving
    // only grows with time, so it never lets a remembered idle scan end sooner.)
    auto blocked = [&](const Request& hit) {
        if (spec_.starvation_cycles == 0) return false;
        for (const Request& o : q) {
            if (&o == &hit) return false;  // only older requests block it
            if (same_bank(o.a, hit.a) && o.a.row != hit.a.row && starving(o, t)) return true;
        }
        return false;
    };
    uint64_t idle_until = ~uint64_t(0);  // the earliest cycle a skipped request may be ready
    for (auto it = q.begin(); it != q.end(); ++it) {
        const uint64_t scheduled = it->arrival + uint64_t(spec_.frontend_cycles);
        if (t < scheduled) {  // not yet scheduled
            idle_until = std::min(idle_until, scheduled);
            continue;
        }
        Bank& b = bank(c, it->a);
        if (!b.open || b.row != it->a.row) continue;
        if (refresh_blocks(c, it->a)) continue;  // its bank is closing for a refresh
        if (blocked(*it)) continue;
        const uint64_t bank_ready = it->write ? b.next_wr : b.next_rd;
        if (t < bank_ready) {
            idle_until = std::min(idle_until, bank_ready);
            continue;
        }
        // The data bus: one burst at a time, with a switch gap between ranks.
        const uint64_t gap =
            c.last_data_rank >= 0 && c.last_data_rank != it->a.rank ? uint64_t(spec_.t_rtrs) : 0;
        if (t + data_latency < c.data_free + gap) {
            idle_until = std::min(idle_until, c.data_free + gap - data_latency);
            continue;
        }
        if (spec_.wck_sync_cycles > 0 && t >= c.wck_until) {
            // The data clock has stopped: a CAS with WCK sync takes this cycle's command slot
            // unless one is under way, and every column command waits for it.
            if (c.wck_sync_done <= c.wck_until) {
                c.wck_sync_done = t + uint64_t(spec_.wck_sync_cycles);
                ++counters_.wck_syncs;
                return true;
            }
            if (t < c.wck_sync_done) {
                remember_idle(c, c.idle_column, q, std::min(idle_until, c.wck_sync_done));
                return false;
            }
        }
        issue_column(c, channel, *it, t);
        q.erase(it);
        return true;
    }
    remember_idle(c, c.idle_column, q, idle_until);
    return false;
}

bool DramController::try_row(Channel& c, int channel, std::deque<Request>& q, uint64_t t) {
    if (still_idle(c, c.idle_row, q, t)) return false;
    // Whether a queued request still wants a bank's open row, found in one pass over the queue
    // when the first conflict asks (a pass per conflict was quadratic in the queue's length, and
    // the fast model runs copies of the controller per request).
    bool wanted_known = false;
    auto row_wanted = [&](const Bank& b) {
        if (!wanted_known) {
            for (Bank& k : c.banks) k.row_wanted = false;
            for (const Request& o : q) {
                Bank& ob = bank(c, o.a);
                if (ob.open && ob.row == o.a.row) ob.row_wanted = true;
            }
            wanted_known = true;
        }
        return b.row_wanted;
    };
    uint64_t idle_until = ~uint64_t(0);  // the earliest cycle a skipped request may be ready
    for (Request& r : q) {
        const uint64_t scheduled = r.arrival + uint64_t(spec_.frontend_cycles);
        if (t < scheduled) {  // not yet scheduled
            idle_until = std::min(idle_until, scheduled);
            continue;
        }
        Rank& rank = c.ranks[size_t(r.a.rank)];
        Bank& b = bank(c, r.a);
        if (b.open && b.row == r.a.row) continue;  // waits for its column command
        if (refresh_blocks(c, r.a)) continue;      // no new rows while a refresh is owed
        if (b.open) {
            // A conflict: close the row, unless a queued request still wants it.
            const bool held_open = row_wanted(b) && !starving(r, t);
            if (held_open && spec_.starvation_cycles > 0)
                idle_until = std::min(idle_until, r.arrival + uint64_t(spec_.starvation_cycles));
            if (t < b.next_pre) idle_until = std::min(idle_until, b.next_pre);
            if (held_open || t < b.next_pre) continue;
            r.conflict = true;
            issue_pre(c, channel, r.a.rank, b, r.a.bankgroup, r.a.bank, t);
            return true;
        }
        if (t < b.next_act) {
            idle_until = std::min(idle_until, b.next_act);
            continue;
        }
        // tRRD (per bank group) is folded into each bank's next_act at issue; the activate windows
        // look back through the rank's last activates: tFAW to the fourth-last, t_32aw to the
        // 32nd-last.
        const auto& acts = rank.acts;
        if (acts.count >= 4 && t < acts.back(4) + uint64_t(spec_.t_faw)) {
            idle_until = std::min(idle_until, acts.back(4) + uint64_t(spec_.t_faw));
            continue;
        }
        if (spec_.t_32aw > 0 && acts.count >= 32 && t < acts.back(32) + uint64_t(spec_.t_32aw)) {
            idle_until = std::min(idle_until, acts.back(32) + uint64_t(spec_.t_32aw));
            continue;
        }
        r.caused_act = true;
        issue_act(c, channel, r.a, t);
        return true;
    }
    remember_idle(c, c.idle_row, q, idle_until);
    return false;
}

void DramController::issue_act(Channel& c, int channel, const DramAddress& a, uint64_t t) {
    Rank& rank = c.ranks[size_t(a.rank)];
    account_background(rank, t);
    Bank& b = bank(c, a);
    b.open = true;
    b.row = a.row;
    ++rank.open_banks;
    b.next_rd = std::max(b.next_rd, t + uint64_t(spec_.t_rcd));
    b.next_wr =
        std::max(b.next_wr, t + uint64_t(spec_.t_rcd_wr > 0 ? spec_.t_rcd_wr : spec_.t_rcd));
    b.next_pre = std::max(b.next_pre, t + uint64_t(spec_.t_ras));
    b.next_act = std::max(b.next_act, t + uint64_t(spec_.t_ras + spec_.t_rp));  // tRC
    // tRRD: the same bank group waits longer than the others.
    for (int bg = 0; bg < spec_.bankgroups; ++bg)
        for (int ba = 0; ba < spec_.banks_per_group; ++ba) {
            Bank& o =
                c.banks[size_t((a.rank * spec_.bankgroups + bg) * spec_.banks_per_group + ba)];
            o.next_act = std::max(o.next_act,
                                  t + uint64_t(bg == a.bankgroup ? spec_.t_rrd_l : spec_.t_rrd_s));
        }
    rank.acts.push(t);
    ++counters_.acts;
    counters_.act_pj += e_act_;
    log(t, DramCommand::Act, channel, a.rank, a.bankgroup, a.bank, a.row);
}

void DramController::issue_pre(Channel& c, int channel, int rank_index, Bank& b, int bg, int ba,
                               uint64_t t) {
    Rank& rank = c.ranks[size_t(rank_index)];
    account_background(rank, t);
    b.open = false;
    --rank.open_banks;
    b.next_act = std::max(b.next_act, t + uint64_t(spec_.t_rp));
    ++counters_.pres;
    log(t, DramCommand::Pre, channel, rank_index, bg, ba, b.row);
}

void DramController::issue_column(Channel& c, int channel, Request& r, uint64_t t) {
    const auto burst = uint64_t(spec_.burst_cycles);
    const uint64_t latency = uint64_t(r.write ? spec_.cwl : spec_.cl);
    const uint64_t data_end = t + latency + burst;
    c.data_free = data_end;
    c.last_data_rank = r.a.rank;
    if (spec_.wck_sync_cycles > 0)
        c.wck_until = std::max(c.wck_until, data_end + uint64_t(spec_.wck_postamble_cycles));
    Bank& b = bank(c, r.a);
    // Column-to-column constraints within the rank (other ranks are kept apart by the data
    // bus and tRTRS).
    const auto ccd_l = uint64_t(std::max(spec_.t_ccd_l, spec_.burst_cycles));
    const auto ccd_s = uint64_t(std::max(spec_.t_ccd_s, spec_.burst_cycles));
    for (int bg = 0; bg < spec_.bankgroups; ++bg) {
        const bool same_bg = bg == r.a.bankgroup;
        for (int ba = 0; ba < spec_.banks_per_group; ++ba) {
            Bank& o =
                c.banks[size_t((r.a.rank * spec_.bankgroups + bg) * spec_.banks_per_group + ba)];
            const uint64_t ccd = same_bg ? ccd_l : ccd_s;
            if (r.write) {
                o.next_wr = std::max(o.next_wr, t + ccd);
                // Write to read: tWTR after the write's last data.
                o.next_rd = std::max(o.next_rd,
                                     data_end + uint64_t(same_bg ? spec_.t_wtr_l : spec_.t_wtr_s));
            } else {
                o.next_rd = std::max(o.next_rd, t + ccd);
                // Read to write: the write's data follows the read's on the bus, with a gap.
                const uint64_t rtw = uint64_t(spec_.cl) + burst + uint64_t(spec_.t_rtrs);
                o.next_wr = std::max(
                    o.next_wr, t + (rtw > uint64_t(spec_.cwl) ? rtw - uint64_t(spec_.cwl) : 0));
            }
        }
    }
    // Precharge after the column command: read to precharge tRTP, write recovery tWR.
    const uint64_t pre_ok = r.write ? data_end + uint64_t(spec_.t_wr) : t + uint64_t(spec_.t_rtp);
    b.next_pre = std::max(b.next_pre, pre_ok);
    if (r.write) {
        ++counters_.writes;
        counters_.write_pj += e_wr_;
    } else {
        ++counters_.reads;
        counters_.read_pj += e_rd_;
        const uint64_t latency_cycles = data_end - r.arrival;
        counters_.read_latency_sum += latency_cycles;
        counters_.read_latency_max = std::max(counters_.read_latency_max, latency_cycles);
    }
    if (r.caused_act)
        ++(r.conflict ? counters_.row_conflicts : counters_.row_misses);
    else
        ++counters_.row_hits;
    done_.push_back({r.id, data_end, r.write});
    log(t, r.write ? DramCommand::Wr : DramCommand::Rd, channel, r.a.rank, r.a.bankgroup, r.a.bank,
        r.a.row);
    if (!spec_.open_page) {
        // Auto-precharge: the bank closes once the precharge may start, and is ready tRP later.
        Rank& rank = c.ranks[size_t(r.a.rank)];
        const uint64_t pre_at = std::max(b.next_pre, pre_ok);
        account_background(rank, t);
        b.open = false;
        --rank.open_banks;
        b.next_act = std::max(b.next_act, pre_at + uint64_t(spec_.t_rp));
        ++counters_.pres;
    }
}

}  // namespace rtsim

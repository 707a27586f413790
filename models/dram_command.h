// A command-level DRAM model: a channel controller with read and write queues that
// issues ACT, RD, WR, PRE and REF commands one per cycle on a command bus, under the JEDEC
// timing constraints between them, with one burst at a time on each channel's data bus.
//
// Organisation: channels x ranks x bank groups x banks, rows and columns; an address maps to
// them by a field order (DRAMsim3's notation, e.g. "rochrababgco": row, channel, rank, bank,
// bank group and column from the most significant bits down, below them the burst's bytes).
// Scheduling is FR-FCFS (the oldest request whose row is open first, else the oldest request),
// with writes buffered and drained between watermarks; pages stay open (open page) or close
// with the column command (closed page: read/write with auto-precharge); each rank refreshes
// every tREFI (all banks precharged, then REF, then tRFC before the next activate).
// Energy follows DRAMPower's current-based model as DRAMsim3 applies it: per command
// (activate-precharge pair, read and write bursts, refresh) and per cycle of background
// (active standby while a bank is open, precharge standby otherwise).
//
// Time is in the device's clock cycles (tCK). This class is the controller's state machine and
// knows nothing of SystemC; it runs ahead request by request (tick until a request's data is
// back), so a trace replay (rtsim dram) and a timing model can both drive it.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

namespace rtsim {

// A DRAM device and its system: organisation, timings (in tCK), currents, controller policy.
// Defaults are the DDR4-3200 8Gb x8 device (configs/dram/DDR4_8Gb_x8_3200.json names sources).
struct DramDeviceSpec {
    std::string name = "DDR4_8Gb_x8_3200";
    std::string protocol = "DDR4";  // DDR4, DDR5, LPDDR5, GDDR6, HBM2, ... (burst timing below)
    // Organisation. A channel may be split into pseudo-channels (HBM2's pseudo-channel mode, HBM3):
    // each has its own banks, data bus (bus_width_bits wide), activate windows and refresh, and
    // the pseudo-channels of a channel share its command bus.
    int channels = 1, pseudo_channels = 1, ranks = 1, bankgroups = 4, banks_per_group = 4;
    int rows = 65536, columns = 1024;
    int device_width_bits = 8, bus_width_bits = 64;
    int burst_length = 8;   // beats per burst (BL)
    int burst_cycles = 4;   // data-bus cycles per burst (BL / 2 at double data rate)
    double tck_ns = 0.625;  // clock period
    std::string address_mapping = "rochrababgco";
    // Timings, in tCK
    int cl = 22, cwl = 16;                  // read and write latency (AL = 0)
    int t_rcd = 22, t_rp = 22, t_ras = 52;  // tRC = tRAS + tRP
    int t_rtp = 12, t_wr = 24;              // read/write recovery before precharge
    int t_wtr_s = 4, t_wtr_l = 12;          // end of write data to read, other/same bank group
    int t_ccd_s = 4, t_ccd_l = 8;           // column to column, other/same bank group
    int t_rrd_s = 4, t_rrd_l = 8;           // activate to activate, other/same bank group
    int t_faw = 34;                         // at most four activates per rank in this window
    // Graphics memories also allow at most 32 activates per rank in any window of t_32aw cycles
    // (GDDR5, GDDR5X, GDDR6). 0: no such window.
    int t_32aw = 0;
    // Activate to write when it differs from activate to read (GDDR and HBM: tRCDWR against
    // tRCDRD, which t_rcd holds). 0: t_rcd.
    int t_rcd_wr = 0;
    int t_rtrs = 1;                   // rank to rank switch on the data bus
    int t_refi = 12480, t_rfc = 560;  // refresh interval and refresh cycle (all banks)
    // "all_bank": every t_refi a rank closes all its banks and refreshes them together (REFab).
    // "per_bank": every t_refi_pb one bank of each rank, in bank order (group 0's banks, then
    // group 1's, ...), is closed and refreshed alone (REFpb) while the others keep serving
    // (LPDDR4, LPDDR5, HBM). LPDDR5 with 16 banks refreshes a pair per command, bank k with bank
    // k + 8 (refresh_pb_banks 2). Its timings: t_rfc_pb the refresh cycle of those banks;
    // t_pbr2pbr between per-bank refreshes (tpbR2pbR); t_pbr2act from a per-bank refresh to an
    // activate of another bank of the rank (LPDDR5 tpbR2act, HBM tRREFD). t_refi_pb 0: t_refi
    // over the refreshes a round takes (banks per rank / refresh_pb_banks).
    std::string refresh_mode = "all_bank";
    int t_refi_pb = 0, t_rfc_pb = 0, t_pbr2pbr = 0, t_pbr2act = 0;
    int refresh_pb_banks = 1;
    // Currents (mA) and supply (V), per device
    double vdd = 1.2;
    double idd0 = 57, idd2n = 37, idd3n = 52, idd4r = 168, idd4w = 150, idd5ab = 250;
    // Per-bank refresh current (IDD5PB): as JEDEC measures it and DRAMPower applies it, the
    // average current with a per-bank refresh every t_refi_pb, so each costs (IDD5PB - IDD2N)
    // over t_refi_pb above precharge standby. 0: each costs the all-bank refresh's energy over
    // the refreshes of a round (the same rows, refreshed a bank or a pair at a time).
    double idd5pb = 0;
    // Active standby as DRAMPower's bank-wise model charges it: with n banks open a rank draws
    // I_rho + n (IDD3N - I_rho) / N, I_rho = IDD2N + rho (IDD3N - IDD2N), where IDD3N is the
    // current with N banks open: all of a rank's (idd3n_open_banks 0; DRAMPower's DDR4 and DDR5)
    // or one (1; its LPDDR4 and LPDDR5). rho 1: IDD3N however many banks are open (DRAMsim3, and
    // DRAMPower before its bank-wise model).
    double bankwise_rho = 1;
    int idd3n_open_banks = 0;
    // Controller
    bool open_page = true;  // false: closed page (auto-precharge with every column command)
    int read_queue = 32;    // entries per channel
    int write_queue = 32;   // entries per channel
    int write_high = 24;    // start draining writes at this many
    int write_low = 8;      // stop draining at this many (once reads wait)
    // FR-FCFS with a cap (Mutlu & Moscibroda 2007): once a request to a closed or other row has
    // waited this long, row hits to its bank stop overtaking it and its row is opened even if
    // younger requests still want the open one. 0: no cap (plain FR-FCFS, as DRAMsim3).
    int starvation_cycles = 0;
    // Device cycles from a request's arrival until the scheduler may issue its first command:
    // the controller's front end. 0: the same cycle. DRAMsim3 takes 1 (its tick issues that
    // cycle's command before it moves newly arrived transactions into its command queues), and
    // its device files are imported so.
    int frontend_cycles = 0;
    // LPDDR5's data clock (WCK) runs only around bursts. A column command issued after it has
    // stopped follows a CAS command with WCK sync, this many cycles earlier (JESD209-5; Ramulator
    // 2 issues that CAS one cycle before the RD or WR). 0: a free-running data clock (every other
    // standard). The clock keeps running wck_postamble_cycles past a burst's last data (tWCKPST).
    int wck_sync_cycles = 0;
    int wck_postamble_cycles = 0;
    // Separate row and column command buses (HBM): a row command (ACT, PRE, REF) and a column
    // command may issue in the same cycle. false: one command per cycle.
    bool dual_command_bus = false;
    bool refresh = true;

    int banks_per_rank() const { return bankgroups * banks_per_group; }
    // Channels with their own data bus and banks: channels x pseudo-channels.
    int data_channels() const { return channels * pseudo_channels; }
    bool per_bank_refresh() const { return refresh_mode == "per_bank"; }
    // Per-bank refreshes in a round over a rank's banks.
    int refreshes_per_round() const { return banks_per_rank() / std::max(1, refresh_pb_banks); }
    int refresh_interval_pb() const {
        return t_refi_pb > 0 ? t_refi_pb : std::max(1, t_refi / refreshes_per_round());
    }
    int devices_per_rank() const { return bus_width_bits / device_width_bits; }
    uint32_t burst_bytes() const { return uint32_t(bus_width_bits / 8 * burst_length); }
    double peak_bytes_per_cycle() const {  // per data channel
        return double(burst_bytes()) / double(burst_cycles);
    }
    uint64_t capacity_bytes() const;
    // An empty string if consistent; else what is wrong, for a one-line error.
    std::string check() const;
};

enum class DramCommand : uint8_t { Act, Rd, Wr, Pre, Ref, RefPb };
const char* dram_command_name(DramCommand c);

struct DramAddress {
    int channel = 0, rank = 0, bankgroup = 0, bank = 0;  // channel: the data channel
    uint32_t row = 0, column = 0;
};

// Splits byte addresses into DramAddress fields by the spec's mapping.
class DramAddressMap {
  public:
    explicit DramAddressMap(const DramDeviceSpec& spec);
    DramAddress map(uint64_t addr) const;

  private:
    int shift_ = 0;
    struct Field {
        int pos = 0;
        uint64_t mask = 0;
    };
    Field ch_, pc_, ra_, bg_, ba_, ro_, co_;
    int pseudo_channels_ = 1;
};

struct DramCounters {
    uint64_t reads = 0, writes = 0;  // bursts
    uint64_t acts = 0, pres = 0, refs = 0, wck_syncs = 0;
    uint64_t refs_per_bank = 0;  // REFpb commands (refresh_mode per_bank)
    uint64_t row_hits = 0;       // column commands whose row was open for an earlier request
    uint64_t row_misses = 0;     // to a precharged bank (activate only)
    uint64_t row_conflicts = 0;  // another row was open (precharge, then activate)
    uint64_t read_latency_sum = 0, read_latency_max = 0;  // arrival to last data beat, tCK
    uint64_t write_drains = 0;  // times the controller turned to draining writes
    // Energy in pJ
    double act_pj = 0, read_pj = 0, write_pj = 0, refresh_pj = 0, background_pj = 0;
    double total_pj() const { return act_pj + read_pj + write_pj + refresh_pj + background_pj; }
};

// One issued command, for tests and command traces.
struct DramCommandRecord {
    uint64_t cycle;
    DramCommand cmd;
    int channel, rank, bankgroup, bank;
    uint32_t row;
};

class DramController {
  public:
    explicit DramController(const DramDeviceSpec& spec);

    // A request arriving at `cycle` (not before the last one's). Returns false if the channel's
    // queue for its kind is full at that cycle; the caller runs the controller on (run_until)
    // and offers it again.
    bool enqueue(uint64_t id, uint64_t addr, bool write, uint64_t cycle);
    // Runs every channel up to and including `cycle`; completed reads and writes are appended
    // to completions() as (id, cycle its data finished).
    void run_until(uint64_t cycle);
    // Runs until every queued request has completed; returns the last cycle run.
    uint64_t drain();

    struct Completion {
        uint64_t id, cycle;
        bool write;
    };
    std::vector<Completion>& completions() { return done_; }
    const DramCounters& counters() const { return counters_; }
    uint64_t now() const { return now_; }
    uint64_t pending() const;
    const DramDeviceSpec& spec() const { return spec_; }
    const DramAddressMap& address_map() const { return map_; }
    // Keeps every issued command (off by default).
    void record_commands(bool on) { record_ = on; }
    const std::vector<DramCommandRecord>& commands() const { return log_; }
    // Background energy up to now (call before reading counters at the end).
    void settle_background();

  private:
    struct Request {
        uint64_t id, arrival;
        DramAddress a;
        bool write;
        bool caused_act = false;  // needed an activate of its own
        bool conflict = false;    // found another row open
    };
    struct Bank {
        bool open = false;
        uint32_t row = 0;
        uint64_t next_act = 0, next_pre = 0, next_rd = 0, next_wr = 0;
        bool row_wanted = false;  // try_row's scratch: a queued request wants the open row
    };
    struct Rank {
        // The last 32 activates, for the activate windows (tFAW, t_32aw). A fixed ring, not a
        // container that allocates: the fast engine copies the controller per held request.
        struct ActHistory {
            std::array<uint64_t, 32> at{};
            int count = 0;  // activates stored, at most 32
            int next = 0;   // the slot the next one takes
            void push(uint64_t t) {
                at[size_t(next)] = t;
                next = (next + 1) % 32;
                count = std::min(count + 1, 32);
            }
            uint64_t back(int n) const { return at[size_t((next - n + 32) % 32)]; }  // 1: last
        } acts;
        uint64_t next_ref_due = 0;  // the next refresh is owed from this cycle
        uint64_t busy_until = 0;    // refreshing until
        int open_banks = 0;
        bool refresh_pending = false;
        int refresh_bank = 0;      // per-bank refresh: the step of the round owed
        uint64_t next_ref_pb = 0;  // per-bank refresh: tpbR2pbR since the last one
        uint64_t bg_since = 0;     // background energy accounted up to this cycle
    };
    struct Channel {
        std::deque<Request> reads, writes;
        std::vector<Bank> banks;  // rank-major, then bank group, then bank
        std::vector<Rank> ranks;
        bool draining = false;
        uint64_t data_free = 0;  // the data bus is free from this cycle
        int last_data_rank = -1;
        uint64_t wck_until = 0;      // the data clock runs until this cycle
        uint64_t wck_sync_done = 0;  // the last WCK sync completes at this cycle
        // A scan of the queue that found no command to issue, and the cycle before which none
        // can issue while nothing changes (no command issued, the queue as it was).
        struct IdleScan {
            uint64_t until = 0, commands = 0;
            size_t queued = 0;
            bool draining = false;
        } idle_column, idle_row;
    };
    // Commands issued so far (any kind, any channel): a scan's state is unchanged while this and
    // its queue's length are.
    uint64_t commands_issued() const {
        return counters_.reads + counters_.writes + counters_.acts + counters_.pres +
               counters_.refs + counters_.refs_per_bank + counters_.wck_syncs;
    }
    bool still_idle(const Channel& c, const Channel::IdleScan& s, const std::deque<Request>& q,
                    uint64_t t) const {
        return t < s.until && s.commands == commands_issued() && s.queued == q.size() &&
               s.draining == c.draining;
    }
    void remember_idle(const Channel& c, Channel::IdleScan& s, const std::deque<Request>& q,
                       uint64_t until) const {
        s = {until, commands_issued(), q.size(), c.draining};
    }

    Bank& bank(Channel& c, const DramAddress& a) {
        return c.banks[size_t((a.rank * spec_.bankgroups + a.bankgroup) * spec_.banks_per_group +
                              a.bank)];
    }
    // The command buses of a channel in one cycle (shared by its pseudo-channels).
    struct CommandSlots {
        bool row = true, column = true;
    };
    // Issues at most one command on data channel `c` at cycle `t` (or one row and one column
    // command with dual_command_bus) in the slots still free.
    void step(Channel& c, int channel, uint64_t t, CommandSlots& slots);
    void take(CommandSlots& slots, bool row_command) const {
        if (!spec_.dual_command_bus)
            slots.row = slots.column = false;
        else
            (row_command ? slots.row : slots.column) = false;
    }
    bool try_refresh(Channel& c, int channel, uint64_t t);
    bool try_refresh_bank(Channel& c, int channel, int rank_index, uint64_t t);
    // Per-bank refresh: whether the rank's refresh owed covers bank `k` (its index in the
    // rank): the step's bank and every refresh_step_-th one after it.
    bool in_bank_refresh(const Rank& r, int k) const { return k % refresh_step_ == r.refresh_bank; }
    // A refresh owed by this request's rank (all-bank) or bank (per-bank): no new commands to it.
    bool refresh_blocks(const Channel& c, const DramAddress& a) const {
        const Rank& r = c.ranks[size_t(a.rank)];
        if (!r.refresh_pending) return false;
        return !per_bank_refresh_ ||
               in_bank_refresh(r, a.bankgroup * spec_.banks_per_group + a.bank);
    }
    bool try_column(Channel& c, int channel, std::deque<Request>& q, uint64_t t);
    bool try_row(Channel& c, int channel, std::deque<Request>& q, uint64_t t);
    // Over the cap: waited starvation_cycles for a row other than its bank's open one.
    bool starving(const Request& r, uint64_t t) const {
        return spec_.starvation_cycles > 0 && t >= r.arrival + uint64_t(spec_.starvation_cycles);
    }
    void issue_act(Channel& c, int channel, const DramAddress& a, uint64_t t);
    void issue_pre(Channel& c, int channel, int rank, Bank& b, int bg, int ba, uint64_t t);
    void issue_column(Channel& c, int channel, Request& r, uint64_t t);
    void account_background(Rank& r, uint64_t until);
    void log(uint64_t t, DramCommand cmd, int ch, int ra, int bg, int ba, uint32_t row);

    DramDeviceSpec spec_;
    // From the spec, read on every scheduling pass: refresh_mode is text.
    bool per_bank_refresh_ = false;
    int refresh_step_ = 1;  // per-bank refreshes in a round
    DramAddressMap map_;
    std::vector<Channel> channels_;
    DramCounters counters_;
    std::vector<Completion> done_;
    uint64_t now_ = 0;  // cycles up to now_ - 1 have run
    bool record_ = false;
    std::vector<DramCommandRecord> log_;
    // Energy increments (pJ) per command, and per cycle of background per rank.
    double e_act_ = 0, e_rd_ = 0, e_wr_ = 0, e_ref_ = 0, e_ref_pb_ = 0, e_act_stby_ = 0,
           e_pre_stby_ = 0;
    double e_open_bank_ = 0;  // bank-wise model: each open bank's share above I_rho, per cycle
};

}  // namespace rtsim

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
    // Organisation
    int channels = 1, ranks = 1, bankgroups = 4, banks_per_group = 4;
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
    // Currents (mA) and supply (V), per device
    double vdd = 1.2;
    double idd0 = 57, idd2n = 37, idd3n = 52, idd4r = 168, idd4w = 150, idd5ab = 250;
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
    bool refresh = true;

    int banks_per_rank() const { return bankgroups * banks_per_group; }
    int devices_per_rank() const { return bus_width_bits / device_width_bits; }
    uint32_t burst_bytes() const { return uint32_t(bus_width_bits / 8 * burst_length); }
    double peak_bytes_per_cycle() const {  // per channel
        return double(burst_bytes()) / double(burst_cycles);
    }
    uint64_t capacity_bytes() const;
    // An empty string if consistent; else what is wrong, for a one-line error.
    std::string check() const;
};

enum class DramCommand : uint8_t { Act, Rd, Wr, Pre, Ref };
const char* dram_command_name(DramCommand c);

struct DramAddress {
    int channel = 0, rank = 0, bankgroup = 0, bank = 0;
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
    Field ch_, ra_, bg_, ba_, ro_, co_;
};

struct DramCounters {
    uint64_t reads = 0, writes = 0;  // bursts
    uint64_t acts = 0, pres = 0, refs = 0, wck_syncs = 0;
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
        uint64_t bg_since = 0;  // background energy accounted up to this cycle
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
    };

    Bank& bank(Channel& c, const DramAddress& a) {
        return c.banks[size_t((a.rank * spec_.bankgroups + a.bankgroup) * spec_.banks_per_group +
                              a.bank)];
    }
    // Issues at most one command on channel `c` at cycle `t`.
    void step(Channel& c, int channel, uint64_t t);
    bool try_refresh(Channel& c, int channel, uint64_t t);
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
    DramAddressMap map_;
    std::vector<Channel> channels_;
    DramCounters counters_;
    std::vector<Completion> done_;
    uint64_t now_ = 0;  // cycles up to now_ - 1 have run
    bool record_ = false;
    std::vector<DramCommandRecord> log_;
    // Energy increments (pJ) per command, and per cycle of background per rank.
    double e_act_ = 0, e_rd_ = 0, e_wr_ = 0, e_ref_ = 0, e_act_stby_ = 0, e_pre_stby_ = 0;
};

}  // namespace rtsim

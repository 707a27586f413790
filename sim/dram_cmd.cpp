#include "sim/dram_cmd.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "models/dram_device.h"
#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

std::string trim(const std::string& s) {
    const size_t b = s.find_first_not_of(" \t\r");
    if (b == std::string::npos) return "";
    return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

bool ends_with(const std::string& s, const std::string& tail) {
    return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

std::string read_text(const std::string& path) {
    std::optional<std::string> text = read_file_text(path);
    if (!text) throw InputError(fmt::format("{}: cannot open", path));
    return std::move(*text);
}

}  // namespace

DramDeviceSpec import_dramsim3_ini(const std::string& path) {
    // section.key -> value text
    std::map<std::string, std::string> kv;
    std::istringstream in(read_text(path));
    std::string line, section;
    int line_no = 0;
    while (std::getline(in, line)) {
        ++line_no;
        const size_t comment = line.find_first_of(";#");
        line = trim(line.substr(0, comment));
        if (line.empty()) continue;
        if (line.front() == '[') {
            if (line.back() != ']')
                throw InputError(fmt::format("{}:{}: expected a [section] header, got '{}'", path,
                                             line_no, line));
            section = trim(line.substr(1, line.size() - 2));
            continue;
        }
        const size_t eq = line.find('=');
        if (eq == std::string::npos || section.empty())
            throw InputError(fmt::format("{}:{}: expected 'key = value' inside a section, got '{}'",
                                         path, line_no, line));
        kv[section + "." + trim(line.substr(0, eq))] = trim(line.substr(eq + 1));
    }
    // DRAMsim3's reading rules (its Config class over inih): a key that is missing or empty
    // takes DRAMsim3's default; a number is its leading numeric text, the rest ignored
    // ("0.666 (1/1.5)" reads 0.666); a file that names no protocol is DDR3.
    auto has = [&](const std::string& k) {
        const auto it = kv.find(k);
        return it != kv.end() && !it->second.empty();
    };
    auto number_or = [&](const std::string& k, double fallback) {
        if (!has(k)) return fallback;
        const std::string& text = kv.at(k);
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || !std::isfinite(v))
            throw InputError(fmt::format("{}: {}: expected a number, got '{}'", path, k, text));
        return v;
    };
    auto integer_or = [&](const std::string& k, int fallback) {
        if (!has(k)) return fallback;
        const std::string& text = kv.at(k);
        char* end = nullptr;
        const long long v = std::strtoll(text.c_str(), &end, 0);
        if (end == text.c_str() || v < INT32_MIN || v > INT32_MAX)
            throw InputError(
                fmt::format("{}: {}: expected a whole number, got '{}'", path, k, text));
        return int(v);
    };
    auto text_or = [&](const std::string& k, const std::string& fallback) {
        return has(k) ? kv.at(k) : fallback;
    };
    auto boolean_or = [&](const std::string& k, bool fallback) {
        if (!has(k)) return fallback;
        std::string v = kv.at(k);
        for (char& c : v) c = char(std::tolower(static_cast<unsigned char>(c)));
        if (v == "true" || v == "yes" || v == "on" || v == "1") return true;
        if (v == "false" || v == "no" || v == "off" || v == "0") return false;
        return fallback;
    };

    DramDeviceSpec s;
    s.name = fs::path(path).stem().string();
    s.protocol = text_or("dram_structure.protocol", "DDR3");
    const std::string& p = s.protocol;
    if (p == "HMC")
        throw InputError(fmt::format(
            "{}: protocol HMC: a hybrid memory cube (packetized links, vaults) is not modelled",
            path));
    static const char* const kKnown[] = {"DDR3",  "DDR4",   "GDDR5",  "GDDR5X", "GDDR6",
                                         "LPDDR", "LPDDR3", "LPDDR4", "HBM",    "HBM2"};
    if (std::find(std::begin(kKnown), std::end(kKnown), p) == std::end(kKnown))
        throw InputError(
            fmt::format("{}: protocol {}: not a protocol DRAMsim3 or RTSim knows", path, p));
    const bool gddr = p.rfind("GDDR", 0) == 0, hbm = p.rfind("HBM", 0) == 0;
    s.bankgroups = integer_or("dram_structure.bankgroups", 2);
    s.banks_per_group = integer_or("dram_structure.banks_per_group", 2);
    s.rows = integer_or("dram_structure.rows", 1 << 16);
    s.columns = integer_or("dram_structure.columns", 1 << 10);
    s.device_width_bits = integer_or("dram_structure.device_width", 8);
    s.burst_length = integer_or("dram_structure.BL", 8);
    if (s.burst_length == 0)
        throw InputError(fmt::format(
            "{}: dram_structure.BL = 0 (DRAMsim3's ideal bandwidth, no data bus time) is not "
            "modelled",
            path));
    // DRAMsim3 counts a GDDR column as BL device-width words and an HBM column as two (its
    // prefetch), and turns both into device-width columns before sizing rows and ranks and
    // mapping addresses: a row of GDDR5X_8Gb_x32 holds 64 bursts, not 4 (read as 4, a sequential
    // stream opened 15 times the rows DRAMsim3 opens, and 16 times the ranks refreshed).
    if (gddr) s.columns *= s.burst_length;
    if (hbm) s.columns *= 2;
    s.frontend_cycles = 1;  // DRAMsim3's controller: see DramDeviceSpec::frontend_cycles
    s.channels = integer_or("system.channels", 1);
    s.bus_width_bits = integer_or("system.bus_width", 64);
    s.address_mapping = text_or("system.address_mapping", "chrobabgraco");
    s.open_page = text_or("system.row_buf_policy", "OPEN_PAGE") != "CLOSE_PAGE";
    // DRAMsim3's rule for the data bus cycles of a burst.
    s.burst_cycles = p == "GDDR5"    ? s.burst_length / 4
                     : p == "GDDR5X" ? s.burst_length / 8
                     : p == "GDDR6"  ? s.burst_length / 16
                                     : s.burst_length / 2;
    s.burst_cycles = std::max(1, s.burst_cycles);
    s.tck_ns = number_or("timing.tCK", 1.0);
    // Read and write latencies count the additive latency, as DRAMsim3's RL and WL do.
    const int al = integer_or("timing.AL", 0);
    s.cl = integer_or("timing.CL", 12) + al;
    s.cwl = integer_or("timing.CWL", 12) + al;
    // Graphics and HBM memories time an activate to a read by tRCDRD, the others by tRCD.
    s.t_rcd = gddr || hbm ? integer_or("timing.tRCDRD", 24) : integer_or("timing.tRCD", 10);
    if (gddr || hbm) s.t_rcd_wr = integer_or("timing.tRCDWR", 20);
    // DRAMsim3 applies its 32-activate window to the graphics memories only.
    if (gddr) s.t_32aw = integer_or("timing.t32AW", 330);
    s.t_rp = integer_or("timing.tRP", 10);
    s.t_ras = integer_or("timing.tRAS", 24);
    s.t_rtp = integer_or("timing.tRTP", 5);
    s.t_wr = integer_or("timing.tWR", 10);
    s.t_wtr_s = integer_or("timing.tWTR_S", 5);
    s.t_wtr_l = integer_or("timing.tWTR_L", 5);
    s.t_ccd_s = integer_or("timing.tCCD_S", 4);
    s.t_ccd_l = integer_or("timing.tCCD_L", 6);
    s.t_rrd_s = integer_or("timing.tRRD_S", 4);
    s.t_rrd_l = integer_or("timing.tRRD_L", 4);
    s.t_faw = integer_or("timing.tFAW", 50);
    s.t_rtrs = integer_or("timing.tRTRS", 2);
    s.t_refi = integer_or("timing.tREFI", 7800);
    s.t_rfc = integer_or("timing.tRFC", 74);
    s.vdd = number_or("power.VDD", 1.2);
    s.idd0 = number_or("power.IDD0", 48);
    s.idd2n = number_or("power.IDD2N", 34);
    s.idd3n = number_or("power.IDD3N", 43);
    s.idd4r = number_or("power.IDD4R", 135);
    s.idd4w = number_or("power.IDD4W", 123);
    s.idd5ab = number_or("power.IDD5AB", 250);
    // DRAMsim3's per-bank refresh (no file of its own sets it). Read with the standard's meaning:
    // DRAMsim3's timing table also keeps every other bank from activating for tRFC after each
    // per-bank refresh, which the standards do not.
    if (text_or("system.refresh_policy", "RANK_LEVEL_STAGGERED") == "BANK_LEVEL_STAGGERED") {
        s.refresh_mode = "per_bank";
        s.t_refi_pb = integer_or("timing.tREFIb", 1950);
        s.t_rfc_pb = integer_or("timing.tRFCb", 20);
        s.idd5pb = number_or("power.IDD5PB", 0);
    }
    // DRAMsim3 issues a row and a column command in one cycle on HBM's two command buses.
    if (hbm) s.dual_command_bus = boolean_or("dram_structure.hbm_dual_cmd", true);
    // Bank groups switched off: one group of all the banks, and the _S timings throughout.
    if (!boolean_or("dram_structure.bankgroup_enable", true)) {
        s.banks_per_group *= s.bankgroups;
        s.bankgroups = 1;
    }
    if (s.bankgroups == 1) {
        s.t_ccd_l = s.t_ccd_s;
        s.t_wtr_l = s.t_wtr_s;
        s.t_rrd_l = s.t_rrd_s;
    }
    // Ranks: the channel's size (MB) over a rank's (its devices' capacity).
    if (s.device_width_bits > 0 && s.bus_width_bits % s.device_width_bits == 0) {
        const double device_bytes = double(s.rows) * s.columns * s.device_width_bits / 8.0 *
                                    s.bankgroups * s.banks_per_group;
        const double rank_bytes = device_bytes * (s.bus_width_bits / s.device_width_bits);
        s.ranks = std::max(
            1, int(std::llround(number_or("system.channel_size", 1024) * 1048576.0 / rank_bytes)));
    }
    const std::string why = s.check();
    if (!why.empty()) throw InputError(fmt::format("{}: {}", path, why));
    return s;
}

DramDeviceSpec load_dram_device(const std::string& name_or_path,
                                const std::vector<std::string>& sets) {
    DramDeviceSpec s;
    if (const DramDeviceEntry* e = DramDeviceRegistry::find(name_or_path)) {
        s = dram_device_from_json(json::parse(e->json));
    } else if (ends_with(name_or_path, ".ini")) {
        s = import_dramsim3_ini(name_or_path);
    } else if (ends_with(name_or_path, ".json")) {
        const json j = json::parse(read_text(name_or_path), nullptr, false);
        if (j.is_discarded()) throw InputError(fmt::format("{}: not valid JSON", name_or_path));
        try {
            s = dram_device_from_json(j);
        } catch (const std::invalid_argument& e) {
            throw InputError(fmt::format("{}: {}", name_or_path, e.what()));
        }
    } else {
        std::string known;
        for (const std::string& n : ComponentIndex::names(DramDeviceEntry::kKind))
            known += (known.empty() ? "" : ", ") + n;
        throw InputError(fmt::format(
            "{}: not a DRAM device preset ({}), nor a .json or DRAMsim3 .ini device file",
            name_or_path, known));
    }
    for (const std::string& kv : sets) {
        const size_t eq = kv.find('=');
        if (eq == std::string::npos || eq == 0)
            throw InputError(fmt::format("--set {}: expected FIELD=VALUE, e.g. t_rcd=20", kv));
        try {
            set_dram_device_field(s, kv.substr(0, eq), kv.substr(eq + 1));
        } catch (const std::invalid_argument& e) {
            throw InputError(fmt::format("--set {}: {}", kv, e.what()));
        }
    }
    // Consistency once every setting is in: one field may need another (refresh_mode per_bank
    // needs t_rfc_pb).
    if (!sets.empty()) {
        const std::string why = s.check();
        if (!why.empty())
            throw InputError(
                fmt::format("{} with --set {}: {}", name_or_path, fmt::join(sets, " --set "), why));
    }
    return s;
}

namespace {

struct TraceRequest {
    uint64_t addr, cycle;
    bool write;
};

// The whole trace, checked line by line before anything runs.
std::vector<TraceRequest> read_mem_trace(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw InputError(fmt::format("{}: cannot open", path));
    std::vector<TraceRequest> out;
    std::string line;
    uint64_t line_no = 0;
    while (std::getline(in, line)) {
        ++line_no;
        const std::string t = trim(line);
        if (t.empty() || t[0] == '#') continue;
        std::istringstream ls(t);
        std::string addr, op, cycle, extra;
        ls >> addr >> op >> cycle;
        const bool more = static_cast<bool>(ls >> extra);
        auto bad = [&] {
            return InputError(fmt::format(
                "{}:{}: expected '0x<address> READ|WRITE <cycle>', got '{}'", path, line_no, t));
        };
        if (addr.empty() || cycle.empty() || more) throw bad();
        TraceRequest r;
        char* end = nullptr;
        errno = 0;
        r.addr = std::strtoull(addr.c_str(), &end, 0);
        if (*end != '\0' || errno != 0 || addr[0] == '-') throw bad();
        r.cycle = std::strtoull(cycle.c_str(), &end, 10);
        if (*end != '\0' || errno != 0 || cycle[0] == '-') throw bad();
        if (op == "READ" || op == "read" || op == "R")
            r.write = false;
        else if (op == "WRITE" || op == "write" || op == "W")
            r.write = true;
        else
            throw bad();
        out.push_back(r);
    }
    if (in.bad()) throw InputError(fmt::format("{}: read error", path));
    return out;
}

double percentile(std::vector<uint64_t>& v, double p) {
    if (v.empty()) return 0;
    const size_t k = std::min(v.size() - 1, size_t(std::ceil(p * double(v.size()))) - (p > 0));
    std::nth_element(v.begin(), v.begin() + long(k), v.end());
    return double(v[k]);
}

}  // namespace

int dram_command(const DramTraceOptions& opt) {
    const DramDeviceSpec spec = load_dram_device(opt.device, opt.sets);
    const std::vector<TraceRequest> trace = read_mem_trace(opt.trace_path);
    DramController d(spec);
    d.record_commands(!opt.commands_path.empty());
    // As DRAMsim3's trace-driven CPU: a request enters at its cycle, or once its queue has room.
    std::vector<uint64_t> enter(trace.size(), 0);
    for (size_t i = 0; i < trace.size(); ++i) {
        uint64_t at = std::max(trace[i].cycle, d.now());
        while (!d.enqueue(i, trace[i].addr, trace[i].write, at)) at = d.now() + 1;
        enter[i] = at;
    }
    const uint64_t end = d.drain() + 1;
    d.settle_background();
    // Read latencies: from the cycle a request entered the controller to its last data beat
    // (as DRAMsim3 counts them; waiting for queue room before that is the trace's stall).
    std::vector<uint64_t> lat;
    lat.reserve(trace.size());
    uint64_t last = 0;
    for (const auto& c : d.completions()) {
        last = std::max(last, c.cycle);
        if (!c.write) lat.push_back(c.cycle - std::min(c.cycle, enter[c.id]));
    }
    const DramCounters& k = d.counters();
    const double cycles = double(std::max<uint64_t>(end, last));
    const double ns = cycles * spec.tck_ns;
    const double bytes = double(k.reads + k.writes) * spec.burst_bytes();
    double lat_sum = 0;
    for (uint64_t l : lat) lat_sum += double(l);
    const double mean = lat.empty() ? 0 : lat_sum / double(lat.size());
    const double p50 = percentile(lat, 0.5), p99 = percentile(lat, 0.99),
                 p999 = percentile(lat, 0.999);
    const double maxl = lat.empty() ? 0 : double(*std::max_element(lat.begin(), lat.end()));
    const uint64_t columns = k.reads + k.writes;
    json out = {{"device", dram_device_to_json(spec)},
                {"trace", opt.trace_path},
                {"requests", trace.size()},
                {"reads", k.reads},
                {"writes", k.writes},
                {"cycles", uint64_t(cycles)},
                {"seconds", ns * 1e-9},
                {"bytes", bytes},
                {"bandwidth_gbps", ns > 0 ? bytes / ns : 0.0},
                {"peak_gbps", spec.peak_bytes_per_cycle() * spec.data_channels() / spec.tck_ns},
                {"read_latency_cycles",
                 {{"mean", mean}, {"p50", p50}, {"p99", p99}, {"p999", p999}, {"max", maxl}}},
                {"read_latency_ns", {{"mean", mean * spec.tck_ns}, {"p99", p99 * spec.tck_ns}}},
                {"commands",
                 {{"act", k.acts},
                  {"pre", k.pres},
                  {"ref", k.refs},
                  {"ref_pb", k.refs_per_bank},
                  {"rd", k.reads},
                  {"wr", k.writes},
                  {"wck_sync", k.wck_syncs}}},
                {"row_hits", k.row_hits},
                {"row_misses", k.row_misses},
                {"row_conflicts", k.row_conflicts},
                {"row_hit_rate", columns ? double(k.row_hits) / double(columns) : 0.0},
                {"write_drains", k.write_drains},
                {"energy_pj", dram_energy_json(k)},
                {"energy_pj_per_bit", bytes > 0 ? k.total_pj() / (bytes * 8) : 0.0},
                {"average_power_mw", ns > 0 ? k.total_pj() / ns : 0.0}};
    if (!opt.out_dir.empty()) {
        fs::create_directories(opt.out_dir);
        write_file_atomically((fs::path(opt.out_dir) / "stats.json").string(), out.dump(2) + "\n");
    }
    if (!opt.commands_path.empty()) {
        std::string csv = "cycle,command,channel,rank,bankgroup,bank,row\n";
        for (const DramCommandRecord& c : d.commands())
            csv += fmt::format("{},{},{},{},{},{},{}\n", c.cycle, dram_command_name(c.cmd),
                               c.channel, c.rank, c.bankgroup, c.bank, c.row);
        write_file_atomically(opt.commands_path, csv);
    }
    if (!opt.quiet) {
        fmt::print(
            "rtsim dram  {} on {} ({}, {} channel{}{} x {} rank{}, {} B bursts, tCK {} ns)\n",
            opt.trace_path, spec.name, spec.protocol, spec.channels, spec.channels == 1 ? "" : "s",
            spec.pseudo_channels > 1 ? fmt::format(" x {} pseudo-channels", spec.pseudo_channels)
                                     : "",
            spec.ranks, spec.ranks == 1 ? "" : "s", spec.burst_bytes(), spec.tck_ns);
        fmt::print("  requests   {} ({} reads, {} writes) in {} cycles ({:.3f} us)\n", trace.size(),
                   k.reads, k.writes, uint64_t(cycles), ns * 1e-3);
        fmt::print("  bandwidth  {:.2f} GB/s of {:.2f} peak\n", out["bandwidth_gbps"].get<double>(),
                   out["peak_gbps"].get<double>());
        fmt::print(
            "  read lat.  mean {:.1f}, p50 {:.0f}, p99 {:.0f}, max {:.0f} cycles "
            "(mean {:.1f} ns)\n",
            mean, p50, p99, maxl, mean * spec.tck_ns);
        fmt::print("  rows       {:.1f}% hits; {} ACT, {} PRE, {} REF{}\n",
                   100.0 * out["row_hit_rate"].get<double>(), k.acts, k.pres, k.refs,
                   spec.per_bank_refresh() ? fmt::format(", {} REFpb", k.refs_per_bank) : "");
        fmt::print(
            "  energy     {:.1f} nJ ({:.2f} pJ/bit; act {:.1f}, rd {:.1f}, wr {:.1f}, ref "
            "{:.1f}, background {:.1f} nJ), {:.1f} mW\n",
            k.total_pj() * 1e-3, out["energy_pj_per_bit"].get<double>(), k.act_pj * 1e-3,
            k.read_pj * 1e-3, k.write_pj * 1e-3, k.refresh_pj * 1e-3, k.background_pj * 1e-3,
            out["average_power_mw"].get<double>());
    }
    return 0;
}

}  // namespace rtsim

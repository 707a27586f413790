#include "models/dram_device.h"

#include <fmt/format.h>

#include <functional>
#include <stdexcept>

namespace rtsim {

using nlohmann::json;

namespace {

// One row per field: how to read it from JSON and write it back.
struct FieldRow {
    const char* key;
    std::function<void(DramDeviceSpec&, const json&)> set;
    std::function<json(const DramDeviceSpec&)> get;
};

template <typename T>
FieldRow row(const char* key, T DramDeviceSpec::*member) {
    return {key,
            [key, member](DramDeviceSpec& s, const json& v) {
                if constexpr (std::is_same_v<T, std::string>) {
                    if (!v.is_string())
                        throw std::invalid_argument(fmt::format("{}: expected a string", key));
                    s.*member = v.get<std::string>();
                } else if constexpr (std::is_same_v<T, bool>) {
                    if (!v.is_boolean())
                        throw std::invalid_argument(fmt::format("{}: expected true or false", key));
                    s.*member = v.get<bool>();
                } else if constexpr (std::is_integral_v<T>) {
                    if (!v.is_number_integer() || v.get<int64_t>() < 0 ||
                        v.get<int64_t>() > (int64_t(1) << 30))
                        throw std::invalid_argument(fmt::format(
                            "{}: expected a whole number from 0 to 2^30, got {}", key, v.dump()));
                    s.*member = T(v.get<int64_t>());
                } else {
                    if (!v.is_number() || v.get<double>() < 0)
                        throw std::invalid_argument(fmt::format(
                            "{}: expected a number of 0 or more, got {}", key, v.dump()));
                    s.*member = v.get<double>();
                }
            },
            [member](const DramDeviceSpec& s) { return json(s.*member); }};
}

const std::vector<FieldRow>& rows() {
    using S = DramDeviceSpec;
    static const std::vector<FieldRow> r = {
        row("name", &S::name),
        row("protocol", &S::protocol),
        row("channels", &S::channels),
        row("pseudo_channels", &S::pseudo_channels),
        row("ranks", &S::ranks),
        row("bankgroups", &S::bankgroups),
        row("banks_per_group", &S::banks_per_group),
        row("rows", &S::rows),
        row("columns", &S::columns),
        row("device_width_bits", &S::device_width_bits),
        row("bus_width_bits", &S::bus_width_bits),
        row("burst_length", &S::burst_length),
        row("burst_cycles", &S::burst_cycles),
        row("tck_ns", &S::tck_ns),
        row("address_mapping", &S::address_mapping),
        row("cl", &S::cl),
        row("cwl", &S::cwl),
        row("t_rcd", &S::t_rcd),
        row("t_rp", &S::t_rp),
        row("t_ras", &S::t_ras),
        row("t_rtp", &S::t_rtp),
        row("t_wr", &S::t_wr),
        row("t_wtr_s", &S::t_wtr_s),
        row("t_wtr_l", &S::t_wtr_l),
        row("t_ccd_s", &S::t_ccd_s),
        row("t_ccd_l", &S::t_ccd_l),
        row("t_rrd_s", &S::t_rrd_s),
        row("t_rrd_l", &S::t_rrd_l),
        row("t_faw", &S::t_faw),
        row("t_32aw", &S::t_32aw),
        row("t_rcd_wr", &S::t_rcd_wr),
        row("t_rtrs", &S::t_rtrs),
        row("t_refi", &S::t_refi),
        row("t_rfc", &S::t_rfc),
        row("refresh_mode", &S::refresh_mode),
        row("t_refi_pb", &S::t_refi_pb),
        row("t_rfc_pb", &S::t_rfc_pb),
        row("t_pbr2pbr", &S::t_pbr2pbr),
        row("t_pbr2act", &S::t_pbr2act),
        row("refresh_pb_banks", &S::refresh_pb_banks),
        row("vdd", &S::vdd),
        row("idd0", &S::idd0),
        row("idd2n", &S::idd2n),
        row("idd3n", &S::idd3n),
        row("idd4r", &S::idd4r),
        row("idd4w", &S::idd4w),
        row("idd5ab", &S::idd5ab),
        row("idd5pb", &S::idd5pb),
        row("bankwise_rho", &S::bankwise_rho),
        row("idd3n_open_banks", &S::idd3n_open_banks),
        row("open_page", &S::open_page),
        row("read_queue", &S::read_queue),
        row("write_queue", &S::write_queue),
        row("write_high", &S::write_high),
        row("write_low", &S::write_low),
        row("starvation_cycles", &S::starvation_cycles),
        row("frontend_cycles", &S::frontend_cycles),
        row("wck_sync_cycles", &S::wck_sync_cycles),
        row("wck_postamble_cycles", &S::wck_postamble_cycles),
        row("dual_command_bus", &S::dual_command_bus),
        row("refresh", &S::refresh),
    };
    return r;
}

const FieldRow* find_row(const std::string& key) {
    for (const FieldRow& r : rows())
        if (key == r.key) return &r;
    return nullptr;
}

std::string known_keys() {
    std::string out;
    for (const FieldRow& r : rows()) out += std::string(out.empty() ? "" : ", ") + r.key;
    return out;
}

}  // namespace

DramDeviceSpec dram_device_from_json(const json& j) {
    if (!j.is_object()) throw std::invalid_argument("expected a JSON object of device fields");
    DramDeviceSpec s;
    for (const auto& [key, value] : j.items()) {
        if (key == "description" || key == "source") continue;  // for people
        const FieldRow* r = find_row(key);
        if (!r)
            throw std::invalid_argument(fmt::format(
                "{}: unknown field (known: {}, description, source)", key, known_keys()));
        r->set(s, value);
    }
    const std::string why = s.check();
    if (!why.empty()) throw std::invalid_argument(why);
    return s;
}

json dram_device_to_json(const DramDeviceSpec& s) {
    json j = json::object();
    for (const FieldRow& r : rows()) j[r.key] = r.get(s);
    return j;
}

json dram_energy_json(const DramCounters& k) {
    return {{"activate", k.act_pj},          {"read", k.read_pj},
            {"write", k.write_pj},           {"refresh", k.refresh_pj},
            {"background", k.background_pj}, {"total", k.total_pj()}};
}

DramDeviceSpec command_dram_spec(const DramParams& p) {
    const DramDeviceEntry* e = DramDeviceRegistry::find(p.device);
    if (!e) throw std::invalid_argument(fmt::format("dram.device: unknown device '{}'", p.device));
    DramDeviceSpec s = dram_device_from_json(json::parse(e->json));
    s.open_page = p.page_policy != "closed";
    s.refresh = p.refresh;
    if (!p.address_mapping.empty()) s.address_mapping = p.address_mapping;
    const std::string why = s.check();
    if (!why.empty()) throw std::invalid_argument("dram: " + why);
    return s;
}

void set_dram_device_field(DramDeviceSpec& s, const std::string& key, const std::string& text) {
    const FieldRow* r = find_row(key);
    if (!r)
        throw std::invalid_argument(
            fmt::format("{}: unknown device field (known: {})", key, known_keys()));
    json v = json::parse(text, nullptr, false);
    if (v.is_discarded()) v = text;  // a bare word: a string
    r->set(s, v);
}

}  // namespace rtsim

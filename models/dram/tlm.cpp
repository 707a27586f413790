// dram.model = tlm: any SystemC TLM-2.0 target that follows the base protocol stands in for the
// DRAM model. The target comes from a shared library (dram.tlm_target, a path) exporting
//
//     extern "C" sc_core::sc_module* rtsim_make_tlm_target(const char* name,
//                                                          tlm::tlm_target_socket<32>** socket);
//
// which makes the target module during elaboration and points `socket` at its target socket;
// this block binds its initiator socket to it and owns the module from then on.
//
// Requests go to the target through b_transport, loosely timed with temporal decoupling: the
// engines run ahead of the SystemC kernel's time, so a request at chip cycle `now` is sent with
// the delay from the kernel's current time to `now`, and the target adds what it takes to that
// delay (IEEE 1666-2011, 11.1.3 and 15.2); the data is usable at the kernel's time plus the
// returned delay. A request whose cycle lies behind the kernel's time (the fast engine may send
// one late) is sent with no delay and counted (late_requests). Reads carry a buffer the target
// fills; writes are posted (accepted at their cycle, as the other models'), their delay counted
// but not waited for. A response other than TLM_OK_RESPONSE ends the run with a message naming
// the target, the command and the address.
#include <dlfcn.h>
#include <fmt/format.h>

#include <tlm_utils/simple_initiator_socket.h>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <tlm>
#include <vector>

#include "models/dram.h"
#include "workloads/error.h"

namespace rtsim {

namespace {

using MakeTarget = sc_core::sc_module* (*)(const char*, tlm::tlm_target_socket<32>**);

class TlmDram final : public sc_core::sc_module, public DramModel {
  public:
    TlmDram(sc_core::sc_module_name name, const DramParams& p)
        : sc_core::sc_module(name),
          socket_("socket"),
          params_(p),
          cycle_(sc_core::sc_time(p.chip_clock_ghz > 0 ? 1.0 / p.chip_clock_ghz : 1.0,
                                  sc_core::SC_NS)) {
        if (p.tlm_target.empty())
            throw InputError(
                "dram.tlm_target: dram.model = tlm needs the path of a shared "
                "library that makes a TLM-2.0 target (rtsim_make_tlm_target)");
        library_ = ::dlopen(p.tlm_target.c_str(), RTLD_NOW | RTLD_LOCAL);
        if (!library_)
            throw InputError(
                fmt::format("dram.tlm_target: cannot load {}: {}", p.tlm_target, ::dlerror()));
        const auto make = reinterpret_cast<MakeTarget>(::dlsym(library_, "rtsim_make_tlm_target"));
        if (!make)
            throw InputError(
                fmt::format("dram.tlm_target: {} has no rtsim_make_tlm_target", p.tlm_target));
        tlm::tlm_target_socket<32>* target_socket = nullptr;
        target_.reset(make("target", &target_socket));
        if (!target_ || !target_socket)
            throw InputError(fmt::format("dram.tlm_target: {} made no target", p.tlm_target));
        socket_.bind(*target_socket);
    }

    ~TlmDram() override {
        target_.reset();  // the module's code lives in the library
        if (library_) ::dlclose(library_);
    }

    Cycle access(uint64_t addr, uint32_t size_bytes, Cycle now,
                 AccessBreakdown* bd = nullptr) override {
        const Cycle done = transport(tlm::TLM_READ_COMMAND, addr, size_bytes, now);
        if (bd) bd->cycles[kLevelDram] += done - now;
        return done;
    }

    Cycle write(uint64_t addr, uint32_t size_bytes, Cycle now) override {
        transport(tlm::TLM_WRITE_COMMAND, addr, size_bytes, now);
        return now;
    }

    // One stage: the target answers at once with its delay.
    Cycle advance(DramRequest& r, Cycle now, bool& done) override {
        done = true;
        r.stage = 1;
        if (r.write) return write(r.addr, r.size_bytes, now);
        return access(r.addr, r.size_bytes, now);
    }

    void register_stats(StatsRegistry& reg) override {
        const std::string block = name();
        reg.add(block, "reads", &reads_, "read transactions");
        reg.add(block, "writes", &writes_, "write transactions");
        reg.add(block, "bytes", &bytes_, "bytes read and written");
        reg.add(block, "write_bytes", &write_bytes_, "bytes written");
        reg.add(block, "read_latency_cycles", &read_latency_cycles_,
                "chip cycles from each read's cycle to its data, summed");
        reg.add(block, "late_requests", &late_,
                "requests sent behind the SystemC kernel's time (sent with no delay)");
        reg.add(block, "out_of_order_requests", &out_of_order_,
                "requests sent after one with a later cycle");
    }

    nlohmann::json report(const ReportContext& ctx) const override {
        return {{"bytes", bytes_},
                {"gbps", ctx.gbps(bytes_)},
                {"write_bytes", write_bytes_},
                {"reads", reads_},
                {"writes", writes_},
                {"mean_read_latency_cycles",
                 ReportContext::ratio(double(read_latency_cycles_), double(reads_))},
                {"target", params_.tlm_target}};
    }

    uint64_t out_of_order_requests() const override { return out_of_order_; }
    uint64_t bytes_moved(uint32_t size_bytes) const override { return size_bytes; }
    void set_series(TimeSeries* bytes) override { bytes_series_ = bytes; }
    void follow(const TimeFloor*) override {}

  private:
    Cycle transport(tlm::tlm_command command, uint64_t addr, uint32_t size_bytes, Cycle now) {
        data_.resize(std::max<size_t>(data_.size(), size_bytes));
        tlm::tlm_generic_payload gp;
        gp.set_command(command);
        gp.set_address(addr);
        gp.set_data_ptr(data_.data());
        gp.set_data_length(size_bytes);
        gp.set_streaming_width(size_bytes);
        gp.set_byte_enable_ptr(nullptr);
        gp.set_dmi_allowed(false);
        gp.set_response_status(tlm::TLM_INCOMPLETE_RESPONSE);
        const sc_core::sc_time at = cycle_ * double(now);
        const sc_core::sc_time kernel = sc_core::sc_time_stamp();
        sc_core::sc_time delay = sc_core::SC_ZERO_TIME;
        if (at >= kernel)
            delay = at - kernel;
        else
            ++late_;
        out_of_order_ += now < latest_;
        latest_ = std::max(latest_, now);
        socket_->b_transport(gp, delay);
        if (gp.is_response_error())
            throw std::runtime_error(
                fmt::format("DRAM target {} answered {} to a {} of {} bytes at 0x{:x}",
                            params_.tlm_target, gp.get_response_string(),
                            command == tlm::TLM_READ_COMMAND ? "read" : "write", size_bytes, addr));
        const bool write = command == tlm::TLM_WRITE_COMMAND;
        reads_ += !write;
        writes_ += write;
        bytes_ += size_bytes;
        write_bytes_ += write ? size_bytes : 0;
        if (bytes_series_) bytes_series_->add(now, size_bytes);
        // The data is usable at the first whole cycle at or after the target's time.
        const Cycle done = std::max(now, Cycle(std::ceil((kernel + delay) / cycle_ - 1e-9)));
        if (!write) read_latency_cycles_ += done - now;
        return done;
    }

    tlm_utils::simple_initiator_socket<TlmDram, 32> socket_;
    DramParams params_;
    sc_core::sc_time cycle_;
    void* library_ = nullptr;
    std::unique_ptr<sc_core::sc_module> target_;
    std::vector<unsigned char> data_;
    TimeSeries* bytes_series_ = nullptr;
    Cycle latest_ = 0;
    uint64_t reads_ = 0, writes_ = 0, bytes_ = 0, write_bytes_ = 0, read_latency_cycles_ = 0;
    uint64_t late_ = 0, out_of_order_ = 0;
};

std::unique_ptr<DramModel> make_tlm(const char* module_name, const DramParams& p) {
    return std::make_unique<TlmDram>(module_name, p);
}

}  // namespace

RTSIM_REGISTER(DramModelEntry, {"tlm",
                                "any SystemC TLM-2.0 base-protocol target from a shared library "
                                "(dram.tlm_target), reached through b_transport, loosely timed",
                                {"tlm_target"},
                                &make_tlm})

}  // namespace rtsim

// A memory target written to the TLM-2.0 base protocol's rules (IEEE 1666-2011, chapters 11 and
// 14-15) and to nothing of RTSim's: the stand-in that tests dram.model = tlm. Built as a shared
// library exporting rtsim_make_tlm_target, as any user's target would be.
//
// Its timing, stated so that tests can work results out by hand: one data path moving
// kBytesPerNs bytes per nanosecond, taken in the order transactions arrive; a transaction starts
// when it arrives (the kernel's time plus the annotated delay) or when the path frees, whichever
// is later, and its response is ready kLatencyNs after its last byte has moved. Under the loosely
// timed coding style it answers at once, adding that time to the delay.
//
// The rules it keeps (as a target must, 14.17): TLM_IGNORE_COMMAND succeeds and does nothing;
// an address range past the memory gets TLM_ADDRESS_ERROR_RESPONSE; byte enables, which it does
// not support, TLM_BYTE_ENABLE_ERROR_RESPONSE; a streaming width below the data length (which it
// does not support) TLM_BURST_ERROR_RESPONSE; otherwise a read fills the buffer (byte k of the
// address space reads as k mod 251), a write is taken, and TLM_OK_RESPONSE is set. It grants no
// direct memory interface. nb_transport_fw calls come to b_transport through the socket (a
// simple_target_socket converts them), so it answers both interfaces of the base protocol.
// When it is destroyed it prints what it served to stderr, for end-to-end tests to compare.
#include <tlm_utils/simple_target_socket.h>

#include <cstdio>
#include <systemc>
#include <tlm>

namespace {

constexpr double kBytesPerNs = 16.0;
constexpr double kLatencyNs = 100.0;
constexpr uint64_t kMemoryBytes = uint64_t(1) << 40;

class ReferenceTarget : public sc_core::sc_module {
  public:
    tlm_utils::simple_target_socket<ReferenceTarget, 32> socket;

    explicit ReferenceTarget(sc_core::sc_module_name name)
        : sc_core::sc_module(name), socket("socket") {
        socket.register_b_transport(this, &ReferenceTarget::b_transport);
        socket.register_get_direct_mem_ptr(this, &ReferenceTarget::get_direct_mem_ptr);
        socket.register_transport_dbg(this, &ReferenceTarget::transport_dbg);
    }

    ~ReferenceTarget() override {
        std::fprintf(stderr,
                     "reference target: %llu reads, %llu writes, %llu bytes read, %llu bytes "
                     "written\n",
                     (unsigned long long)reads_, (unsigned long long)writes_,
                     (unsigned long long)bytes_read_, (unsigned long long)bytes_written_);
    }

  private:
    void b_transport(tlm::tlm_generic_payload& gp, sc_core::sc_time& delay) {
        const tlm::tlm_command command = gp.get_command();
        const uint64_t addr = gp.get_address();
        const unsigned length = gp.get_data_length();
        if (command == tlm::TLM_IGNORE_COMMAND) {
            gp.set_response_status(tlm::TLM_OK_RESPONSE);
            return;
        }
        if (addr >= kMemoryBytes || length > kMemoryBytes - addr) {
            gp.set_response_status(tlm::TLM_ADDRESS_ERROR_RESPONSE);
            return;
        }
        if (gp.get_byte_enable_ptr()) {
            gp.set_response_status(tlm::TLM_BYTE_ENABLE_ERROR_RESPONSE);
            return;
        }
        if (gp.get_streaming_width() < length) {
            gp.set_response_status(tlm::TLM_BURST_ERROR_RESPONSE);
            return;
        }
        const sc_core::sc_time arrival = sc_core::sc_time_stamp() + delay;
        const sc_core::sc_time start = arrival > path_free_ ? arrival : path_free_;
        path_free_ = start + sc_core::sc_time(double(length) / kBytesPerNs, sc_core::SC_NS);
        const sc_core::sc_time ready = path_free_ + sc_core::sc_time(kLatencyNs, sc_core::SC_NS);
        delay = ready - sc_core::sc_time_stamp();
        unsigned char* data = gp.get_data_ptr();
        if (command == tlm::TLM_READ_COMMAND) {
            for (unsigned k = 0; k < length; ++k) data[k] = (unsigned char)((addr + k) % 251);
            ++reads_;
            bytes_read_ += length;
        } else {
            ++writes_;
            bytes_written_ += length;
        }
        gp.set_dmi_allowed(false);
        gp.set_response_status(tlm::TLM_OK_RESPONSE);
    }

    bool get_direct_mem_ptr(tlm::tlm_generic_payload&, tlm::tlm_dmi& dmi) {
        dmi.allow_none();
        return false;
    }

    unsigned transport_dbg(tlm::tlm_generic_payload&) { return 0; }

    sc_core::sc_time path_free_ = sc_core::SC_ZERO_TIME;
    unsigned long long reads_ = 0, writes_ = 0, bytes_read_ = 0, bytes_written_ = 0;
};

}  // namespace

extern "C" __attribute__((visibility("default"))) sc_core::sc_module* rtsim_make_tlm_target(
    const char* name, tlm::tlm_target_socket<32>** socket) {
    auto* target = new ReferenceTarget(name);
    *socket = &target->socket;
    return target;
}

// Trace files: header, metadata, index and every chunk decoded, in pieces and whole.
#include <vector>

#include "fuzz/fuzz_input.h"
#include "workloads/error.h"
#include "workloads/trace_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = rtsim::fuzz::write_input(data, size, ".rtt");
    try {
        rtsim::TraceReader reader(path);
        std::vector<rtsim::TraceRecord> records;
        for (size_t k = 0; k < reader.chunk_count(); ++k) {
            reader.open_chunk(k);
            while (reader.chunk_rays_left() > 0 && reader.read_records(5, records) > 0) {
            }
        }
        for (size_t k = 0; k < reader.chunk_count(); ++k) reader.read_chunk(k, records);
    } catch (const rtsim::InputError&) {
    }
    return 0;
}

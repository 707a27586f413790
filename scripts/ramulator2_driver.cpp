// Runs one Ramulator 2 simulation for scripts/compare_dram.py: Ramulator 2 has no executable of
// its own (its front end is Python), so this links its library, reads a fully specified config
// (JSON written by its Python package), runs the front end until every request is sent, then keeps
// ticking the memory for DRAIN cycles so that every request completes, and prints the statistics.
//
//   g++ -std=c++20 -O2 -I RAMULATOR2/src scripts/ramulator2_driver.cpp -L RAMULATOR2 -lramulator \
//       -lfmt -Wl,-rpath,RAMULATOR2 -o ramulator2_driver
//   ramulator2_driver CONFIG.json DRAIN
#include <iostream>
#include <string>

#include "ramulator/base/config.h"
#include "ramulator/base/factory.h"
#include "ramulator/frontend/i_frontend.h"
#include "ramulator/memory_system/i_memory_system.h"

int main(int argc, char** argv) {
    if (argc != 3) {
        std::cerr << "usage: ramulator2_driver CONFIG.json DRAIN_CYCLES\n";
        return 2;
    }
    using namespace Ramulator;
    const long long drain_cycles = std::stoll(argv[2]);
    const ConfigNode config = Config::parse_config_file(argv[1]);
    IFrontEnd* frontend = Factory::create_frontend(config);
    IMemorySystem* memory = Factory::create_memory_system(config);
    frontend->connect_memory_system(memory);
    memory->connect_frontend(frontend);
    // The two clock ratios as Ramulator 2's own simulation loop applies them: the front end ticks
    // once per `memory ratio` base ticks, the memory once per `front-end ratio`.
    const int frontend_ratio = frontend->get_clock_ratio(),
              memory_ratio = memory->get_clock_ratio();
    int frontend_count = memory_ratio - 1, memory_count = frontend_ratio - 1;
    for (;;) {
        if (++frontend_count >= memory_ratio) {
            frontend_count = 0;
            frontend->tick();
        }
        if (frontend->is_finished()) break;
        if (++memory_count >= frontend_ratio) {
            memory_count = 0;
            memory->tick();
        }
    }
    for (long long i = 0; i < drain_cycles; ++i) memory->tick();
    frontend->finalize();
    memory->finalize();
    frontend->update_stats_recursive();
    memory->update_stats_recursive();
    frontend->print_stats(std::cout);
    memory->print_stats(std::cout);
    return 0;
}

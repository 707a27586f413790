// The protocol the keyed caches' tests share (sim/sampling/frame_profile.h,
// sim/sampling/functional_l2.h): an entry damaged on disk is refused, rebuilt and stored over,
// never used.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "support/file_bytes.h"

namespace rtsim::test {

// Flips a byte of the entry at `entry`, then cuts it to half its size, and loads through the
// cache after each (`load()` returns the cache's outcome): the flip is refused for its checksum
// and the good entry stored over it, the cut is refused too.
template <class Load>
void expect_damaged_entry_rebuilt(const std::filesystem::path& entry, Load&& load) {
    const std::string good = read_file_bytes(entry);
    std::string flipped = good;
    flipped[flipped.size() / 2] ^= 0x10;
    write_file_bytes(entry, flipped);
    EXPECT_EQ(load(), "rebuilt: checksum mismatch");
    EXPECT_EQ(read_file_bytes(entry), good);  // stored over
    write_file_bytes(entry, good.substr(0, good.size() / 2));
    EXPECT_EQ(load().rfind("rebuilt: ", 0), 0u);
}

}  // namespace rtsim::test

// Outputs appear whole or not at all, and never replace what the user named: a symlink stays a
// symlink (`--hits LINK` once replaced the link with a regular file), a pipe or a
// device is written in place.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "support/scratch_dir.h"
#include "workloads/output_file.h"

using namespace rtsim;
namespace fs = std::filesystem;

namespace {
std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}
}  // namespace

TEST(OutputFile, ASymlinkStaysALinkAndItsTargetIsReplaced) {
    const fs::path dir = test::scratch_dir() / "out_link";
    fs::create_directories(dir);
    std::ofstream(dir / "target.csv") << "old\n";
    fs::remove(dir / "link.csv");
    fs::create_symlink("target.csv", dir / "link.csv");
    write_file_atomically((dir / "link.csv").string(), "new\n");
    EXPECT_TRUE(fs::is_symlink(fs::symlink_status(dir / "link.csv")));
    EXPECT_EQ(slurp(dir / "target.csv"), "new\n");
    EXPECT_FALSE(fs::exists(dir / "target.csv.tmp"));
    // A dangling link: its target is created, the link kept.
    fs::remove(dir / "later.csv");
    fs::remove(dir / "dangling.csv");
    fs::create_symlink("later.csv", dir / "dangling.csv");
    write_file_atomically((dir / "dangling.csv").string(), "made\n");
    EXPECT_TRUE(fs::is_symlink(fs::symlink_status(dir / "dangling.csv")));
    EXPECT_EQ(slurp(dir / "later.csv"), "made\n");
}

TEST(OutputFile, AnUncommittedOutputLeavesTheTargetAsItWas) {
    const fs::path dir = test::scratch_dir() / "out_abort";
    fs::create_directories(dir);
    std::ofstream(dir / "keep.csv") << "before\n";
    {
        AtomicOutputFile f((dir / "keep.csv").string());
        f.write("half of something");
    }  // destroyed without commit: an error part-way
    EXPECT_EQ(slurp(dir / "keep.csv"), "before\n");
    EXPECT_FALSE(fs::exists(dir / "keep.csv.tmp"));
}

TEST(OutputFile, APipeIsWrittenInPlaceNotReplaced) {
    const fs::path dir = test::scratch_dir() / "out_fifo";
    fs::create_directories(dir);
    const fs::path fifo = dir / "fifo";
    fs::remove(fifo);
    ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
    std::string got;
    std::thread reader([&] { got = slurp(fifo); });
    write_file_atomically(fifo.string(), "through the pipe\n");
    reader.join();
    EXPECT_EQ(got, "through the pipe\n");
    EXPECT_TRUE(fs::is_fifo(fs::status(fifo)));
}

// Running the rtsim binary from end-to-end tests: its exit status, stdout and stderr.
#pragma once

#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "support/scratch_dir.h"

namespace rtsim::test {

struct Result {
    int status;
    std::string out, err;
};

inline const std::filesystem::path& work_dir() {
    return scratch_dir();
}

inline std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

inline Result run_rtsim(const std::string& args) {
    const std::filesystem::path out = work_dir() / "stdout.txt", err = work_dir() / "stderr.txt";
    const std::string cmd = fmt::format("'{}' {} >'{}' 2>'{}' </dev/null", RTSIM_BINARY, args,
                                        out.string(), err.string());
    const int raw = std::system(cmd.c_str());
    return {WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, slurp(out), slurp(err)};
}

// Bad input: exit status 2 and exactly one line on stderr, holding `fragment`.
inline void expect_one_line_error(const Result& r, const std::string& fragment) {
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(fragment), std::string::npos) << r.err;
}

}  // namespace rtsim::test

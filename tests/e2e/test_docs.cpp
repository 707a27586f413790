// The documentation agrees with the program: every subcommand and option that `--help` lists is
// documented in README.md or docs/, every `build/rtsim` command line shown there parses, every
// relative link resolves, and every recorded benchmark result is linked from docs/benchmarks.md.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "support/run_rtsim.h"

namespace fs = std::filesystem;
using namespace rtsim::test;

namespace {

const fs::path kSource = RTSIM_SOURCE_DIR;

std::vector<fs::path> doc_files() {
    std::vector<fs::path> files{kSource / "README.md"};
    for (const auto& e : fs::directory_iterator(kSource / "docs"))
        if (e.path().extension() == ".md") files.push_back(e.path());
    std::sort(files.begin(), files.end());
    return files;
}

std::string all_docs() {
    std::string text;
    for (const fs::path& f : doc_files()) text += slurp(f) + "\n";
    return text;
}

// The names listed under a help text's "Subcommands:" heading, up to the next blank line.
std::vector<std::string> subcommands(const std::string& help) {
    std::vector<std::string> names;
    const size_t at = help.find("Subcommands:");
    if (at == std::string::npos) return names;
    std::istringstream in(help.substr(at));
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line) && !line.empty()) {
        std::smatch m;
        if (std::regex_search(line, m, std::regex(R"(^\s+([a-z][a-z-]*)\s)")))
            names.push_back(m[1]);
    }
    return names;
}

// The long options a help text lists (`  -o,--out TEXT ...`, `  --config TEXT`).
std::set<std::string> long_options(const std::string& help) {
    std::set<std::string> out;
    const std::regex opt(R"(^\s+(?:-[A-Za-z],)?(--[a-z][a-z0-9-]*))");
    std::istringstream in(help);
    std::string line;
    while (std::getline(in, line)) {
        std::smatch m;
        if (std::regex_search(line, m, opt)) out.insert(m[1]);
    }
    return out;
}

bool mentions(const std::string& text, const std::string& word) {
    size_t at = 0;
    while ((at = text.find(word, at)) != std::string::npos) {
        const size_t end = at + word.size();
        const bool word_end = end == text.size() || !(std::isalnum(uint8_t(text[end])) ||
                                                      text[end] == '-' || text[end] == '_');
        if (word_end) return true;
        at = end;
    }
    return false;
}

struct CommandLine {
    fs::path file;
    std::string env;   // the shell variables set earlier in the same file (F="...")
    std::string line;  // starting with build/rtsim, continuations joined
};

// Indented code lines of a Markdown file that run build/rtsim, with the variable assignments
// that precede them.
std::vector<CommandLine> command_lines(const fs::path& file) {
    std::vector<CommandLine> out;
    std::istringstream in(slurp(file));
    std::string line, env;
    const std::regex assignment(R"(^[A-Z_]+=)");
    while (std::getline(in, line)) {
        if (line.rfind("    ", 0) != 0) continue;
        std::string cmd = line.substr(4);
        while (!cmd.empty() && cmd.back() == '\\' && std::getline(in, line)) {
            cmd.pop_back();
            cmd += " " + line.substr(line.find_first_not_of(' '));
        }
        if (std::regex_search(cmd, assignment))
            env += cmd + "\n";
        else if (cmd.rfind("build/rtsim ", 0) == 0 || cmd == "build/rtsim")
            out.push_back({file, env, cmd});
    }
    return out;
}

Result run_shell(const std::string& script) {
    const fs::path sh = work_dir() / "doc_line.sh";
    std::ofstream(sh) << script;
    const fs::path out = work_dir() / "doc_out.txt", err = work_dir() / "doc_err.txt";
    const int raw = std::system(
        fmt::format("sh '{}' >'{}' 2>'{}' </dev/null", sh.string(), out.string(), err.string())
            .c_str());
    return {WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, slurp(out), slurp(err)};
}

}  // namespace

TEST(Docs, EverySubcommandInHelpIsDocumented) {
    const Result r = run_rtsim("--help");
    ASSERT_EQ(r.status, 0);
    const std::vector<std::string> names = subcommands(r.out);
    ASSERT_GE(names.size(), 9u) << "the help lists fewer subcommands than rtsim has:\n" << r.out;
    const std::string docs = all_docs();
    for (const std::string& n : names)
        EXPECT_TRUE(mentions(docs, "rtsim " + n))
            << "`rtsim " << n << "` is not in README or docs/";
}

TEST(Docs, EveryOptionOfEverySubcommandIsDocumented) {
    const std::string docs = all_docs();
    const Result top = run_rtsim("--help");
    size_t checked = 0;
    for (const std::string& sub : subcommands(top.out)) {
        const Result r = run_rtsim(sub + " --help");
        ASSERT_EQ(r.status, 0) << sub;
        for (const std::string& o : long_options(r.out)) {
            ++checked;
            EXPECT_TRUE(mentions(docs, o)) << "rtsim " << sub << " " << o << " is not documented";
        }
    }
    EXPECT_GE(checked, 50u);
}

TEST(Docs, EveryDocumentedCommandLineParses) {
    // The check can fail: a misspelt option or an unknown subcommand does not parse.
    EXPECT_EQ(run_rtsim("--parse-only run --no-such-option").status, 2);
    EXPECT_EQ(run_rtsim("--parse-only no-such-command").status, 2);
    EXPECT_EQ(run_rtsim("--parse-only run --set l1.ways=2").status, 0);

    size_t lines = 0, readme_lines = 0;
    for (const fs::path& f : doc_files()) {
        for (const CommandLine& c : command_lines(f)) {
            ++lines;
            if (f.filename() == "README.md") ++readme_lines;
            const std::string cmd = std::string("'") + RTSIM_BINARY + "' --parse-only" +
                                    c.line.substr(std::string("build/rtsim").size());
            const Result r = run_shell(c.env + cmd + "\n");
            EXPECT_EQ(r.status, 0) << c.file.filename().string() << ": " << c.line << "\n" << r.err;
        }
    }
    EXPECT_GE(readme_lines, 10u);
    EXPECT_GE(lines, 30u);
}

TEST(Docs, RelativeLinksResolve) {
    const std::regex link(R"(\]\(([^)#:\s]+)(#[^)]*)?\))");
    size_t checked = 0;
    for (const fs::path& f : doc_files()) {
        const std::string text = slurp(f);
        for (std::sregex_iterator it(text.begin(), text.end(), link), end; it != end; ++it) {
            ++checked;
            const fs::path target = f.parent_path() / (*it)[1].str();
            EXPECT_TRUE(fs::exists(target)) << f.filename().string() << " links to " << (*it)[1];
        }
    }
    EXPECT_GE(checked, 20u);
}

TEST(Docs, EveryRecordedResultIsLinkedFromBenchmarks) {
    const std::string bench = slurp(kSource / "docs" / "benchmarks.md");
    size_t files = 0, bytes = 0;
    for (const auto& e : fs::recursive_directory_iterator(kSource / "bench" / "results")) {
        if (!e.is_regular_file()) continue;
        ++files;
        bytes += e.file_size();
        const std::string name = e.path().filename().string();
        EXPECT_NE(bench.find("../bench/results/" + name + ")"), std::string::npos)
            << name << " is not linked from docs/benchmarks.md";
    }
    EXPECT_GE(files, 5u);
    // Summaries, not raw dumps: the scripts write every run's figures to out/bench/ instead.
    EXPECT_LT(bytes, 5u << 20);
}

#include "sim/bound.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cerrno>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "workloads/error.h"
#include "workloads/output_file.h"

namespace rtsim {

namespace fs = std::filesystem;
using nlohmann::json;

std::vector<std::string> child_arguments(const std::vector<std::string>& argv,
                                         const std::vector<std::string>& flags,
                                         const std::vector<std::string>& valued) {
    auto in = [](const std::vector<std::string>& names, const std::string& a) {
        return std::find(names.begin(), names.end(), a) != names.end();
    };
    std::vector<std::string> out;
    for (size_t i = 1; i < argv.size(); ++i) {
        const std::string& a = argv[i];
        if (in(flags, a)) continue;
        if (a == "--set" && in(valued, a)) {  // --set takes one or more values
            while (i + 1 < argv.size() && argv[i + 1].rfind("-", 0) != 0) ++i;
            continue;
        }
        if (in(valued, a)) {
            ++i;  // and its value
            continue;
        }
        const size_t eq = a.find('=');
        if (eq != std::string::npos && in(valued, a.substr(0, eq))) continue;
        out.push_back(a);
    }
    return out;
}

json run_child(const RunOptions& opt, const std::vector<std::string>& extra, const char* what) {
    std::vector<std::string> args =
        child_arguments(opt.argv, {"--bound", "--quiet", "-q"}, {"--out", "-o", "--target-error"});
    args.insert(args.end(), extra.begin(), extra.end());
    return run_rtsim_child(args, what);
}

pid_t spawn_rtsim(const std::vector<std::string>& arguments, const std::string& stderr_path,
                  bool discard_stdout) {
    std::vector<std::string> args = {"/proc/self/exe"};
    args.insert(args.end(), arguments.begin(), arguments.end());
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t files;
    posix_spawn_file_actions_init(&files);
    posix_spawn_file_actions_addopen(&files, 2, stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
    if (discard_stdout) posix_spawn_file_actions_addopen(&files, 1, "/dev/null", O_WRONLY, 0);
    pid_t pid;
    const int rc = posix_spawn(&pid, argv[0], &files, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&files);
    return rc == 0 ? pid : -1;
}

bool wait_rtsim(pid_t pid, int& status) {
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR) return false;
    return true;
}

json run_rtsim_child(const std::vector<std::string>& arguments, const char* what,
                     std::string* units_csv) {
    char tmpl[] = "/tmp/rtsim-child-XXXXXX";
    const char* dir = mkdtemp(tmpl);
    if (!dir) throw std::runtime_error(std::string(what) + ": cannot create a temporary folder");
    std::vector<std::string> args = arguments;
    args.insert(args.end(), {"--quiet", "--out", dir});
    // The child's messages go to a file: on failure its error becomes part of this run's one
    // line; on success its warnings (a cache entry rebuilt, say) are passed on.
    const std::string err_path = (fs::path(dir) / "stderr.txt").string();
    const pid_t pid = spawn_rtsim(args, err_path, false);
    if (pid < 0) {
        std::error_code ec;
        fs::remove_all(dir, ec);
        throw std::runtime_error(std::string(what) + ": cannot start the run");
    }
    int status = 0;
    const bool lost = !wait_rtsim(pid, status);
    const std::string messages = read_file_text(err_path).value_or("");
    const std::string path = (fs::path(dir) / "stats.json").string();
    std::ifstream in(path);
    json b = json::parse(in, nullptr, false);
    bool csv_ok = true;
    if (units_csv) {
        std::optional<std::string> csv =
            read_file_text((fs::path(dir) / "sampled_units.csv").string());
        csv_ok = bool(csv);
        *units_csv = csv.value_or("");
    }
    std::error_code ec;
    fs::remove_all(dir, ec);
    if (lost || !WIFEXITED(status) || WEXITSTATUS(status) != 0 || b.is_discarded() || !csv_ok) {
        // Its last line says why (rtsim's errors are one line).
        std::string why;
        std::istringstream lines(messages);
        for (std::string line; std::getline(lines, line);)
            if (!line.empty()) why = line;
        if (why.rfind("rtsim: ", 0) == 0) why.erase(0, 7);
        if (why.rfind("error: ", 0) == 0) why.erase(0, 7);
        const std::string message =
            std::string(what) + ": the run failed" +
            (why.empty()           ? std::string()
             : WIFSIGNALED(status) ? fmt::format(" (signal {}): {}", WTERMSIG(status), why)
                                   : ": " + why);
        // Refused input in the child (exit status 2) is refused input here too.
        if (WIFEXITED(status) && WEXITSTATUS(status) == 2) throw InputError(message);
        throw std::runtime_error(message);
    }
    std::fputs(messages.c_str(), stderr);
    return b;
}

json run_bound(const RunOptions& opt) {
    return run_child(opt, {"--set", "sim.ideal_memory=true", "--set", "sim.ideal_units=true"},
                     "--bound");
}

json bound_section(const json& run, const json& ideal) {
    const double bound_rps = ideal["rays_per_second"].get<double>();
    return {{"sim", {{"ideal_memory", true}, {"ideal_units", true}}},
            {"total_cycles", ideal["total_cycles"]},
            {"rays_per_second", bound_rps},
            {"achieved_over_bound",
             bound_rps > 0 ? run["rays_per_second"].get<double>() / bound_rps : 0.0}};
}

}  // namespace rtsim

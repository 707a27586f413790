#include "sim/bound.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

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

json run_rtsim_child(const std::vector<std::string>& arguments, const char* what,
                     std::string* units_csv) {
    std::vector<std::string> args = {"/proc/self/exe"};
    args.insert(args.end(), arguments.begin(), arguments.end());
    char tmpl[] = "/tmp/rtsim-child-XXXXXX";
    const char* dir = mkdtemp(tmpl);
    if (!dir) throw std::runtime_error(std::string(what) + ": cannot create a temporary folder");
    for (const char* a : {"--quiet", "--out"}) args.push_back(a);
    args.push_back(dir);
    std::vector<char*> cargv;
    for (std::string& a : args) cargv.push_back(a.data());
    cargv.push_back(nullptr);
    pid_t pid;
    if (posix_spawn(&pid, cargv[0], nullptr, nullptr, cargv.data(), environ) != 0)
        throw std::runtime_error(std::string(what) + ": cannot start the run");
    int status = 0;
    waitpid(pid, &status, 0);
    const std::string path = (fs::path(dir) / "stats.json").string();
    std::ifstream in(path);
    json b = json::parse(in, nullptr, false);
    bool csv_ok = true;
    if (units_csv) {
        std::ifstream csv(fs::path(dir) / "sampled_units.csv");
        std::stringstream text;
        text << csv.rdbuf();
        *units_csv = text.str();
        csv_ok = bool(csv);
    }
    std::error_code ec;
    fs::remove_all(dir, ec);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || b.is_discarded() || !csv_ok)
        throw std::runtime_error(std::string(what) + ": the run failed");
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

#include "sim/bound.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace rtsim {

namespace fs = std::filesystem;
using nlohmann::json;

json run_child(const RunOptions& opt, const std::vector<std::string>& extra, const char* what) {
    std::vector<std::string> args;
    for (size_t i = 1; i < opt.argv.size(); ++i) {
        const std::string& a = opt.argv[i];
        if (a == "--bound" || a == "--quiet" || a == "-q") continue;
        if (a == "--out" || a == "-o" || a == "--target-error") {
            ++i;  // and its value
            continue;
        }
        if (a.rfind("--out=", 0) == 0 || a.rfind("--target-error=", 0) == 0) continue;
        args.push_back(a);
    }
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

// rtsim run --bound: the same rays again with ideal memory and unlimited units.
#pragma once

#include <sys/types.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/run.h"

namespace rtsim {

// Runs the command in `opt` again in a child process with ideal memory and unlimited units (a
// SystemC kernel runs once per process) and returns the child's stats.json. Throws
// std::runtime_error if it fails.
nlohmann::json run_bound(const RunOptions& opt);

// The command in `opt` again in a child process, without --bound, --target-error, --out and
// --quiet, with `extra` arguments added; returns its stats.json. `what` names the option that
// needed it in errors. Throws std::runtime_error if it fails.
nlohmann::json run_child(const RunOptions& opt, const std::vector<std::string>& extra,
                         const char* what);

// This process's command line `argv` without argv[0], the `flags` and the options in `valued` with
// their values (also as --option=value; --set with all of its values).
std::vector<std::string> child_arguments(const std::vector<std::string>& argv,
                                         const std::vector<std::string>& flags,
                                         const std::vector<std::string>& valued);

// Starts this rtsim with `arguments` (those after argv[0]), its stderr written to
// `stderr_path` and, with `discard_stdout`, its stdout to /dev/null; returns the child's pid, or
// -1 if it could not be started.
pid_t spawn_rtsim(const std::vector<std::string>& arguments, const std::string& stderr_path,
                  bool discard_stdout);
// Waits for the child `pid` to end, on through the signals that interrupt the wait (SIGINT and
// SIGTERM's handlers have no SA_RESTART; the child stops on the same signal); its status in
// `status`. False if it cannot be waited for.
bool wait_rtsim(pid_t pid, int& status);

// rtsim with `arguments` (and --quiet --out <a temporary folder>) in a child process; returns its
// stats.json, and in `units_csv` (if given) its sampled_units.csv. Throws std::runtime_error
// naming `what` if it fails.
nlohmann::json run_rtsim_child(const std::vector<std::string>& arguments, const char* what,
                               std::string* units_csv = nullptr);

// stats.json's "bound" section from the run's stats and the ideal run's.
nlohmann::json bound_section(const nlohmann::json& run, const nlohmann::json& ideal);

}  // namespace rtsim

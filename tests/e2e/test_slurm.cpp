// rtsim sweep --slurm against a real Slurm: a one-node cluster started on this machine
// (scripts/slurm_local.sh: munge, slurmctld and slurmd on loopback with their own ports and
// folders), a sweep through it whose table equals the local sweep's, a task cancelled so that
// --collect names it, and --resume finishing only that point. Where Slurm cannot start, the test
// says why and is skipped.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include "support/run_rtsim.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace rtsim::test;

namespace {

// The last non-empty line of a text: slurm_local.sh prints the SLURM_CONF path alone on stdout.
std::string last_line(std::string text) {
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
    const size_t nl = text.rfind('\n');
    return nl == std::string::npos ? text : text.substr(nl + 1);
}

// slurm_local.sh start in DIR, run through `prefix` (a shell word or two, e.g. an unshare that
// gives it a host name of its own); stdout and stderr kept apart.
struct Cluster {
    fs::path dir, conf;
    bool up = false;
    std::string out, err;
    Cluster(const std::string& name, int port, const std::string& prefix = "")
        : dir(work_dir() / name) {
        const fs::path out_log = work_dir() / (name + ".out"),
                       err_log = work_dir() / (name + ".err");
        const std::string cmd = fmt::format(
            "{} env RTSIM_SLURM_PORT={} '{}/scripts/slurm_local.sh' start '{}' > '{}' 2> '{}'",
            prefix, port, RTSIM_SOURCE_DIR, dir.string(), out_log.string(), err_log.string());
        up = std::system(cmd.c_str()) == 0;
        out = slurp(out_log);
        err = slurp(err_log);
        if (up) conf = last_line(out);
    }
    ~Cluster() {
        const std::string cmd = fmt::format("'{}/scripts/slurm_local.sh' stop '{}' >/dev/null 2>&1",
                                            RTSIM_SOURCE_DIR, dir.string());
        if (std::system(cmd.c_str()) != 0) ADD_FAILURE() << "could not stop the cluster";
    }
};

// The figures of a sweep's table that depend on the simulation only (not host time).
json table_of(const fs::path& dir) {
    json t = json::parse(slurp(dir / "results.json"));
    json out = json::array();
    for (json& p : t["points"]) {
        p["figures"].erase("host: simulated Mrays/host s");
        out.push_back({{"point", p["point"]}, {"figures", p["figures"]}});
    }
    return out;
}

}  // namespace

TEST(Slurm, ASweepThroughSlurmMatchesTheLocalOneAndResumesACancelledTask) {
    if (std::system("command -v sbatch >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "Slurm is not installed (Debian: slurm-wlm munge): --slurm not tested";
    Cluster cluster("slurm_cluster", 17817);
    if (!cluster.up) GTEST_SKIP() << "Slurm could not start here: " << cluster.err;
    setenv("SLURM_CONF", cluster.conf.c_str(), 1);
    const fs::path file = work_dir() / "slurm_sweep.json";
    std::ofstream(file) << R"({"workload": {"rays": "primary,ao", "res": "24x24"},
                               "vary": {"l1.ways": [1, 2], "core.count": [1, 2]}})";
    const fs::path local = work_dir() / "sw_local", remote = work_dir() / "sw_slurm";
    ASSERT_EQ(
        run_rtsim(fmt::format("sweep -q '{}' -j 2 -o '{}'", file.string(), local.string())).status,
        0);
    Result r = run_rtsim(fmt::format("sweep -q '{}' --slurm --wait --max-parallel 2 -o '{}'",
                                     file.string(), remote.string()));
    ASSERT_EQ(r.status, 0) << r.out << r.err;
    EXPECT_EQ(table_of(remote), table_of(local));
    const std::string script = slurp(remote / "slurm" / "sweep.sbatch");
    EXPECT_NE(script.find("#SBATCH --array=0,1,2,3%2"), std::string::npos) << script;
    EXPECT_TRUE(fs::exists(remote / "slurm" / "task-3.out"));

    // Short runs, several points per task: 4 points in tasks of 3 are tasks 0 and 1.
    const fs::path grouped = work_dir() / "sw_grouped";
    r = run_rtsim(fmt::format("sweep -q '{}' --slurm --wait --points-per-task 3 -o '{}'",
                              file.string(), grouped.string()));
    ASSERT_EQ(r.status, 0) << r.out << r.err;
    EXPECT_NE(slurp(grouped / "slurm" / "sweep.sbatch").find("#SBATCH --array=0,1\n"),
              std::string::npos);
    EXPECT_EQ(table_of(grouped), table_of(local));

    // One task at a time; task 2 cancelled while it waits: --collect names it and writes no
    // table; --resume submits that point alone and the table is complete.
    const fs::path cut = work_dir() / "sw_cancel";
    r = run_rtsim(
        fmt::format("sweep -q '{}' --slurm --max-parallel 1 -o '{}'", file.string(), cut.string()));
    ASSERT_EQ(r.status, 0) << r.err;
    std::string job = slurp(cut / "slurm" / "job_id");
    job = job.substr(0, job.find('\n'));
    ASSERT_FALSE(job.empty());
    ASSERT_EQ(std::system(fmt::format("scancel {}_2", job).c_str()), 0);
    const std::string wait_cmd = fmt::format(
        "for i in $(seq 240); do [ -z \"$(squeue -h -j {} 2>/dev/null)\" ] && exit 0; sleep 0.5; "
        "done; exit 1",
        job);
    ASSERT_EQ(std::system(wait_cmd.c_str()), 0) << "the job did not end";
    r = run_rtsim(fmt::format("sweep --collect '{}'", cut.string()));  // the folder alone
    EXPECT_EQ(r.status, 1);
    EXPECT_NE(r.err.find("1 of 4 points did not finish"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("002_"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(cut / "results.json"));
    r = run_rtsim(
        fmt::format("sweep -q '{}' --slurm --resume --wait -o '{}'", file.string(), cut.string()));
    ASSERT_EQ(r.status, 0) << r.out << r.err;
    EXPECT_NE(slurp(cut / "slurm" / "sweep.sbatch").find("#SBATCH --array=2\n"), std::string::npos);
    EXPECT_EQ(table_of(cut), table_of(local));
    unsetenv("SLURM_CONF");
}

// A host whose name does not resolve: munged warns about it on stderr, and stdout still holds
// the SLURM_CONF path alone (it once took the warning's first line for the path). The cluster
// runs in a UTS namespace of its own, under a name no resolver knows.
TEST(Slurm, StartsOnAHostWhoseNameDoesNotResolve) {
    if (std::system("command -v sbatch >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "Slurm is not installed (Debian: slurm-wlm munge)";
    const std::string name = fmt::format("rtsim-unresolvable-{}", getpid());
    if (std::system(
            fmt::format("unshare --uts sh -c 'hostname {}' >/dev/null 2>&1", name).c_str()) != 0)
        GTEST_SKIP() << "cannot make a UTS namespace here (unshare --uts needs root)";
    ASSERT_NE(std::system(fmt::format("getent hosts {} >/dev/null 2>&1", name).c_str()), 0)
        << name << " resolves here";
    Cluster cluster("slurm_unresolvable", 17917,
                    fmt::format("unshare --uts sh -c 'hostname {} && exec \"$0\" \"$@\"'", name));
    ASSERT_TRUE(cluster.up) << cluster.err;
    EXPECT_EQ(cluster.out, cluster.conf.string() + "\n") << "stdout holds more than the path";
    EXPECT_EQ(cluster.conf, cluster.dir / "slurm.conf");
    EXPECT_NE(slurp(cluster.conf).find("NodeName=" + name + " "), std::string::npos);
}

TEST(Slurm, SlurmOptionsWithoutSlurmAreRefused) {
    const fs::path file = work_dir() / "slurm_opts.json";
    std::ofstream(file) << R"({"workload": {"rays": "primary", "res": "8x8"},
                               "vary": {"l1.ways": [1, 2]}})";
    expect_one_line_error(run_rtsim(fmt::format("sweep '{}' --max-parallel 2", file.string())),
                          "need --slurm");
    expect_one_line_error(run_rtsim(fmt::format("sweep '{}' --collect", file.string())),
                          "--collect: needs --out");
}

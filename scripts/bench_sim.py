#!/usr/bin/env python3
"""Simulator speed vs. accuracy benchmark (not a test: machines are noisy, so it prints ratios
within one run rather than asserting times).

For each ray kind on a scene it runs `rtsim run` and prints simulated rays per host second and the
shares of host time (waiting for rays, models, SystemC kernel). (The fast model's error against
the time-ordered reference is what scripts/bench_fidelity.py measures.)

With --replay N it then records each kind's rays to a trace once and replays it N times per
variant (the default config; the same pinned to one host core with taskset, so trace decoding
shares that core with the simulation instead of using a second one; ideal memory; one simulated
core): simulated rays per host second without any functional work, best and median, and the
best one-host-core default replay against the target of 1 M simulated rays per host
second on one host core. With --engines, the fast and the accurate engine run one frame each
side by side (bunny at --engines-res, primary + shadow + 4 AO rays, the default chip and 64 cores
of 32 slots): simulated rays per host second and accurate over fast. With --profile as well, one more default replay runs under
`perf record -e cpu-clock` (a software clock: no hardware counters needed) and the functions
taking the most of the simulation thread's samples are listed; skipped with a note where perf
is missing or not permitted.

    scripts/bench_sim.py [--rtsim build/rtsim] [--scene FILE] [--res 256x256]
                         [--kinds primary,ao,diffuse] [--set bvh.width=8 ...] [--replay N] [--profile]
                         [--engines [--engines-res 1920x1080]]
"""
import argparse
import collections
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import run_stats  # noqa: E402


def run(rtsim, args, out, prefix=()):
    return run_stats(rtsim, args, out, "bench_sim", prefix)


TARGET_RAYS_PER_HOST_S = 1e6  # BVH8 diffuse, one host core, default mode
ONE_HOST_CORE = ("taskset", "-c", "0")  # the simulation and the trace decoding share one core
# (name, config overrides, command prefix)
REPLAY_VARIANTS = [("default", [], ()),
                   ("default, one host core", [], ONE_HOST_CORE),
                   ("sim.ideal_memory=true", ["--set", "sim.ideal_memory=true"], ()),
                   ("core.count=1", ["--set", "core.count=1"], ())]


def replay_section(a, tmp, extra):
    print(f"\nReplays of a recorded trace (no functional work), {a.replay} runs per variant:")
    print(f"{'rays':8} {'variant':24} {'rays':>9} {'Mcycles':>9} {'best M/host s':>14} "
          f"{'median':>7} {'vs default':>10}")
    for kind in a.kinds.split(","):
        trace = os.path.join(tmp, f"{kind}.rtt")
        cmd = [a.rtsim, "trace", "-q", "--scene", a.scene, "--rays", kind, "--res", a.res,
               "--config", a.config, "-o", trace] + extra
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"bench_sim: {' '.join(cmd)} failed: {r.stderr.strip()}")
        best_default = best_one_core = None
        for name, sets, prefix in REPLAY_VARIANTS:
            if prefix and not shutil.which(prefix[0]):
                print(f"{kind:8} {name:24} skipped: {prefix[0]} is not installed")
                continue
            speeds = []
            for i in range(a.replay):
                s = run(a.rtsim, ["--config", a.config, "--trace", trace] + extra + sets,
                        os.path.join(tmp, f"replay-{kind}-{i}"), prefix)
                speeds.append(s["host"]["simulated_rays_per_host_second"] / 1e6)
            best = max(speeds)
            best_default = best_default or best
            if prefix == ONE_HOST_CORE:
                best_one_core = best
            print(f"{kind:8} {name:24} {s['rays']['total']:9d} {s['total_cycles'] / 1e6:9.3f} "
                  f"{best:14.3f} {statistics.median(speeds):7.3f} {best / best_default:9.2f}x")
        print(f"{kind:8} best default replay against the 1 M rays/host s target: "
              f"{best_default * 1e6 / TARGET_RAYS_PER_HOST_S:.2f}x (trace decoding on a second core)")
        if best_one_core:
            print(f"{kind:8} best default replay on one host core against the target: "
                  f"{best_one_core * 1e6 / TARGET_RAYS_PER_HOST_S:.2f}x")
        if a.profile:
            profile_section(a, tmp, kind, trace, extra)


def profile_section(a, tmp, kind, trace, extra, top=16):
    """Where the simulation thread's host time goes, from perf's software-clock samples."""
    if not shutil.which("perf"):
        print(f"{kind:8} profile skipped: perf is not installed")
        return
    data = os.path.join(tmp, f"{kind}.perf")
    record = ["perf", "record", "-q", "-e", "cpu-clock", "-F", "5000", "-o", data, a.rtsim, "run", "-q",
              "--config", a.config, "--trace", trace, "--out", os.path.join(tmp, f"profile-{kind}")] + extra
    r = subprocess.run(record, capture_output=True, text=True)
    if r.returncode != 0:
        print(f"{kind:8} profile skipped: perf record failed: {r.stderr.strip().splitlines()[-1:]}")
        return
    rep = subprocess.run(["perf", "report", "-i", data, "--stdio", "--no-children", "--sort", "pid,symbol"],
                         capture_output=True, text=True)
    samples = collections.Counter()  # (thread, symbol) -> share of all samples
    for line in rep.stdout.splitlines():
        m = re.match(r"\s*([\d.]+)%\s+(\d+):\S+\s+\[[.k]\]\s+(.*?)(\s+-\s+-)?\s*$", line)
        if m:
            samples[(m.group(2), m.group(3))] += float(m.group(1))
    by_thread = collections.Counter()
    for (tid, _), share in samples.items():
        by_thread[tid] += share
    if not by_thread:
        print(f"{kind:8} profile skipped: perf report gave no samples")
        return
    main_tid, main_share = by_thread.most_common(1)[0]
    print(f"\nWhere the simulation thread's time goes ({kind}, one default replay under perf, cpu-clock "
          f"samples; that thread took {main_share:.0f}% of all samples, trace reading on the helper "
          f"thread {100 - main_share:.0f}%):")
    rows = sorted(((share, sym) for (tid, sym), share in samples.items() if tid == main_tid), reverse=True)
    for share, sym in rows[:top]:
        name = sym.replace("non-virtual thunk to ", "").replace("(anonymous namespace)::", "")
        name = re.sub(r"\(.*", "", name)
        print(f"  {share / main_share * 100:5.1f}%  {name}")


# The frame both engines run side by side (--engines): primary, shadow and 4 AO rays per pixel,
# on the default chip and on 64 cores of 32 slots.
ENGINE_FRAME = ["--rays", "primary,shadow,ao", "--ao-samples", "4"]
ENGINE_CHIPS = [("default", []), ("64x32", ["--set", "core.count=64", "--set", "core.ray_slots=32"])]


def engines_section(a, tmp, extra):
    print(f"\nBoth engines on one frame ({a.scene}, {a.engines_res}, primary + shadow + 4 AO), "
          f"one run each, in this run:")
    print(f"{'chip':8} {'engine':9} {'rays':>9} {'Mcycles':>9} {'host s':>7} "
          f"{'sim Mrays/host s':>17} {'vs fast':>8}")
    for chip, sets in ENGINE_CHIPS:
        fast_rate = None
        for engine in ("fast", "accurate"):
            s = run(a.rtsim, ["--config", a.config, "--scene", a.scene, "--res", a.engines_res] +
                    ENGINE_FRAME + extra + sets + ["--set", f"sim.fidelity={engine}"],
                    os.path.join(tmp, f"engines-{chip}-{engine}"))
            h = s["host"]
            rate = h["simulated_rays_per_host_second"] / 1e6
            fast_rate = fast_rate or rate
            print(f"{chip:8} {engine:9} {s['rays']['total']:9d} {s['total_cycles'] / 1e6:9.3f} "
                  f"{h['simulation_s']:7.2f} {rate:17.3f} {rate / fast_rate:7.2f}x")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--rtsim", default="build/rtsim")
    p.add_argument("--scene", default="/usr/share/glmark2/models/bunny.obj")
    p.add_argument("--config", default="configs/baseline.json")
    p.add_argument("--res", default="256x256")
    p.add_argument("--kinds", default="primary,ao,diffuse")
    p.add_argument("--set", action="append", default=[], help="config override, KEY=VALUE (repeatable)")
    p.add_argument("--replay", type=int, default=0, help="replays per variant of a recorded trace")
    p.add_argument("--engines", action="store_true",
                   help="also run the fast and the accurate engine side by side on one frame "
                        "(--engines-res, primary + shadow + 4 AO) on the default chip and 64 x 32")
    p.add_argument("--engines-res", default="1920x1080")
    p.add_argument("--profile", action="store_true",
                   help="with --replay: profile one default replay with perf (cpu-clock samples)")
    a = p.parse_args()
    print(f"scene {a.scene}, config {a.config}, {a.res}, overrides {a.set or 'none'}")
    print("Shares of simulation host time: waiting for rays (generation and functional tracing on a")
    print("helper thread), models (the core scheduler's process running the cores), kernel (the rest).")
    print(f"{'rays':8} {'rays':>9} {'Mcycles':>9} {'DRAM MB':>8} {'host s':>7} {'sim Mrays/host s':>17} "
          f"{'rays wait':>9} {'models':>7} {'kernel':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in a.kinds.split(","):
            extra = [x for kv in a.set for x in ("--set", kv)]
            s = run(a.rtsim, ["--config", a.config, "--scene", a.scene, "--rays", kind, "--res", a.res]
                    + extra, os.path.join(tmp, kind))
            h = s["host"]
            sim_s = h["simulation_s"]
            print(f"{kind:8} {s['rays']['total']:9d} {s['total_cycles'] / 1e6:9.3f} "
                  f"{s['bandwidth']['dram']['bytes'] / 1e6:8.2f} {sim_s:7.3f} "
                  f"{h['simulated_rays_per_host_second'] / 1e6:17.3f} "
                  f"{h['functional_s'] / sim_s * 100:8.0f}% "
                  f"{h['models_s'] / sim_s * 100:6.0f}% {h['kernel_s'] / sim_s * 100:6.0f}%")
        if a.replay > 0:
            replay_section(a, tmp, [x for kv in a.set for x in ("--set", kv)])
        if a.engines:
            engines_section(a, tmp, [x for kv in a.set for x in ("--set", kv)])


if __name__ == "__main__":
    main()

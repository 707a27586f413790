#!/usr/bin/env python3
"""Simulator speed vs. accuracy benchmark (not a test: machines are noisy, so it prints ratios
within one run rather than asserting times).

For each ray kind on a scene it runs `rtsim run` at several temporal-decoupling quanta and prints
simulated rays per host second, the shares of host time (waiting for rays, models, SystemC
kernel), and the error
of total cycles and DRAM bytes against quantum 0 (the exact reference).

With --replay N it then records each kind's rays to a trace once and replays it N times per
variant (the default config, ideal memory, one core): simulated rays per host second without
any functional work, best and median, and the best default replay against issue 5's target of
1 M simulated rays per host second.

    scripts/bench_sim.py [--rtsim build/rtsim] [--scene FILE] [--res 256x256] [--quanta 0,10,100,1000]
                         [--kinds primary,ao,diffuse] [--set bvh.width=8 ...] [--replay N]
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import run_stats  # noqa: E402


def run(rtsim, args, out):
    return run_stats(rtsim, args, out, "bench_sim")


TARGET_RAYS_PER_HOST_S = 1e6  # issue 5, BVH8 diffuse, one host core, default mode
REPLAY_VARIANTS = [("default", []), ("sim.ideal_memory=true", ["--set", "sim.ideal_memory=true"]),
                   ("core.count=1", ["--set", "core.count=1"])]


def replay_section(a, tmp, extra):
    print(f"\nReplays of a recorded trace (no functional work), quantum 0, {a.replay} runs per variant:")
    print(f"{'rays':8} {'variant':24} {'rays':>9} {'Mcycles':>9} {'best M/host s':>14} "
          f"{'median':>7} {'vs default':>10}")
    for kind in a.kinds.split(","):
        trace = os.path.join(tmp, f"{kind}.rtt")
        cmd = [a.rtsim, "trace", "-q", "--scene", a.scene, "--rays", kind, "--res", a.res,
               "--config", a.config, "-o", trace] + extra
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"bench_sim: {' '.join(cmd)} failed: {r.stderr.strip()}")
        best_default = None
        for name, sets in REPLAY_VARIANTS:
            speeds = []
            for i in range(a.replay):
                s = run(a.rtsim, ["--config", a.config, "--trace", trace] + extra + sets,
                        os.path.join(tmp, f"replay-{kind}-{i}"))
                speeds.append(s["host"]["simulated_rays_per_host_second"] / 1e6)
            best = max(speeds)
            best_default = best_default or best
            print(f"{kind:8} {name:24} {s['rays']['total']:9d} {s['total_cycles'] / 1e6:9.3f} "
                  f"{best:14.3f} {statistics.median(speeds):7.3f} {best / best_default:9.2f}x")
        print(f"{kind:8} best default replay against the 1 M rays/host s target: "
              f"{best_default * 1e6 / TARGET_RAYS_PER_HOST_S:.2f}x")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--rtsim", default="build/rtsim")
    p.add_argument("--scene", default="/usr/share/glmark2/models/bunny.obj")
    p.add_argument("--config", default="configs/baseline.json")
    p.add_argument("--res", default="256x256")
    p.add_argument("--kinds", default="primary,ao,diffuse")
    p.add_argument("--set", action="append", default=[], help="config override, KEY=VALUE (repeatable)")
    p.add_argument("--quanta", default="0,10,100,1000")
    p.add_argument("--replay", type=int, default=0, help="replays per variant of a recorded trace")
    a = p.parse_args()
    quanta = [int(q) for q in a.quanta.split(",")]
    print(f"scene {a.scene}, config {a.config}, {a.res}, overrides {a.set or 'none'}")
    print("Shares of simulation host time: waiting for rays (generation and functional tracing on a")
    print("helper thread), models (the core scheduler's process running the cores), kernel (the rest).")
    print(f"{'rays':8} {'quantum':>8} {'rays':>9} {'Mcycles':>9} {'cyc err':>8} {'DRAM err':>9} "
          f"{'host s':>7} {'sim Mrays/host s':>17} {'speedup':>8} {'rays wait':>9} {'models':>7} {'kernel':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in a.kinds.split(","):
            ref = None
            for q in quanta:
                extra = [x for kv in a.set for x in ("--set", kv)]
                s = run(a.rtsim, ["--config", a.config, "--scene", a.scene, "--rays", kind, "--res", a.res,
                                  "--set", f"sim.quantum_cycles={q}"] + extra, os.path.join(tmp, f"{kind}{q}"))
                h = s["host"]
                row = (s["total_cycles"], s["bandwidth"]["dram"]["bytes"], h["simulation_s"])
                ref = ref or row
                cyc_err = (row[0] - ref[0]) / ref[0] * 100
                dram_err = (row[1] - ref[1]) / max(ref[1], 1) * 100
                print(f"{kind:8} {q:8d} {s['rays']['total']:9d} {row[0] / 1e6:9.3f} {cyc_err:+7.2f}% "
                      f"{dram_err:+8.2f}% {row[2]:7.3f} {h['simulated_rays_per_host_second'] / 1e6:17.3f} "
                      f"{ref[2] / row[2]:7.2f}x {h['functional_s'] / row[2] * 100:8.0f}% "
                      f"{h['models_s'] / row[2] * 100:6.0f}% {h['kernel_s'] / row[2] * 100:6.0f}%")
        if a.replay > 0:
            replay_section(a, tmp, [x for kv in a.set for x in ("--set", kv)])


if __name__ == "__main__":
    main()

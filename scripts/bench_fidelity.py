#!/usr/bin/env python3
"""The fast model's error against the time-ordered reference (sim.fidelity = accurate).

Runs a matrix of scenes x ray kinds x configs that stress ordering and sharing, once with the
reference and once with the fast model, and reports per cell the
fast model's error in total cycles and DRAM bytes (percent of the reference), the difference in
L1 and L2 hit rates and in every stall share (percentage points), and the host seconds each
fidelity spent simulating (host.simulation_s: the timing models, not scene loading or tracing).

Writes out/bench/fidelity.json (every cell, untracked) and bench/results/fidelity.md (the summary: per
config the largest errors, every cell over the 1% target with its figures, and the host-time
ratio), and prints the summary. (Until the temporal-decoupling quantum was removed it also ran
the quanta: bench/results/fidelity_quanta.md is that record.)

    scripts/bench_fidelity.py [--rtsim build/rtsim] [--res 64x64]
                              [--scenes a,b] [--kinds primary,ao,diffuse] [--configs a,b] [-j 2]
                              [--out bench/results]

The sampled mode's run time against its error is the other half of this benchmark:
    scripts/bench_fidelity.py --sampled [ARGS...]
runs scripts/bench_sampled.py with ARGS (its own options: 6 scenes x primary, AO, diffuse and a
2-bounce path at 1920x1080, several sampling periods and --target-error against the full run of
each frame, 100 sample seeds per cell for the intervals' coverage, a Pareto plot of host seconds
against error; --skip for the skip design, --reference-set for matched pairs).
"""
import argparse
import concurrent.futures
import json
import os
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import SCENES, run_stats, write_results  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_SCENES = "cornell,sphere,bunny,armadillo"


def cfg(name):
    return ["--config", os.path.join(ROOT, "configs", name)]


# name -> (config arguments, resolution scale): configs that stress ordering and sharing.
CONFIGS = {
    "l1_mshr1": (["--set", "l1.mshrs=1"], 1),
    "l1_mshr2": (["--set", "l1.mshrs=2"], 1),
    "l2_mshr4": (["--set", "l2.mshrs=4"], 1),
    "dram_1ch": (["--set", "dram.channels=1"], 1),
    "l2_1bank": (["--set", "l2.banks=1"], 1),
    "units_by4": (["--set", "box_unit.shared_by=4", "--set", "triangle_unit.shared_by=4"], 1),
    "treelet": (cfg("treelet.json"), 1),
    "treelet_load": (cfg("treelet.json") + ["--set", "traversal.treelet_prefetch=true"], 1),
    "packet": (["--set", "traversal.mode=packet", "--set", "bvh.width=4"], 1),
    "small_caches": (cfg("small_caches.json"), 1),
    # A GPU-scale chip: 64 cores x 32 ray slots need more rays to fill them.
    "gpu_64x32": (["--set", "core.count=64", "--set", "core.ray_slots=32"], 2),
}

TARGET_PERCENT = 1.0


def scaled(res, scale):
    w, h = (int(x) for x in res.split("x"))
    return f"{w * scale}x{h * scale}"


def figures(s):
    """What is compared: cycles, DRAM bytes, hit rates and stall shares."""
    out = {"cycles": s["total_cycles"], "dram_bytes": s["bandwidth"]["dram"]["bytes"],
           "l1_hit_rate": s["caches"]["l1_total"]["hit_rate"],
           "l2_hit_rate": s["caches"]["l2"]["hit_rate"],
           "host_s": s["host"]["simulation_s"]}
    for cause, share in s["stalls"]["total"]["share"].items():
        out["stall_" + cause] = share
    return out


def run_one(job):
    rtsim, args, out = job
    return figures(run_stats(rtsim, args, out, "bench_fidelity"))


def pct(x, ref):
    return 100.0 * (x - ref) / ref if ref else (0.0 if x == ref else float("inf"))


def compare(fast, ref):
    e = {"cycles_pct": pct(fast["cycles"], ref["cycles"]),
         "dram_bytes_pct": pct(fast["dram_bytes"], ref["dram_bytes"]),
         "host_ratio": ref["host_s"] / fast["host_s"] if fast["host_s"] > 0 else float("inf")}
    for k in fast:
        if k.endswith("hit_rate") or k.startswith("stall_"):
            e[k + "_pp"] = 100.0 * (fast[k] - ref.get(k, 0.0))
    return e


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--sampled":
        # Its matrix (1080p frames, sample seeds, periods) shares nothing with the one below.
        script = os.path.join(ROOT, "scripts", "bench_sampled.py")
        os.execv(sys.executable, [sys.executable, script] + sys.argv[2:])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--res", default="64x64")
    ap.add_argument("--scenes", default=DEFAULT_SCENES)
    ap.add_argument("--kinds", default="primary,ao,diffuse")
    ap.add_argument("--configs", default=",".join(CONFIGS))
    ap.add_argument("-j", type=int, default=2, help="runs at once")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    a = ap.parse_args()
    scenes = a.scenes.split(",")
    for n in scenes:
        if n not in SCENES:
            sys.exit(f"bench_fidelity: --scenes: unknown scene {n} (known: {', '.join(SCENES)})")
        if not SCENES[n].startswith("builtin:") and not os.path.exists(SCENES[n]):
            sys.exit(f"bench_fidelity: {SCENES[n]}: scene file not found (scripts/setup.sh fetches it)")
    configs = a.configs.split(",")
    for c in configs:
        if c not in CONFIGS:
            sys.exit(f"bench_fidelity: --configs: unknown config {c} (known: {', '.join(CONFIGS)})")
    kinds = a.kinds.split(",")

    tmp = tempfile.mkdtemp(prefix="bench_fidelity_")
    jobs = {}
    for scene in scenes:
        for kind in kinds:
            for c in configs:
                extra, scale = CONFIGS[c]
                base = ["--scene", SCENES[scene], "--rays", kind, "--res", scaled(a.res, scale)]
                base += extra
                cell = (scene, kind, c)
                jobs[cell + ("accurate",)] = base + ["--set", "sim.fidelity=accurate"]
                jobs[cell + ("fast",)] = base
    print(f"bench_fidelity: {len(scenes)} scenes x {len(kinds)} kinds x {len(configs)} configs, "
          f"fast and accurate: {len(jobs)} runs at {a.res}", file=sys.stderr)
    results = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.j) as pool:
        futures = {pool.submit(run_one, (a.rtsim, args, os.path.join(tmp, "_".join(map(str, key))))): key
                   for key, args in jobs.items()}
        for done, f in enumerate(concurrent.futures.as_completed(futures), 1):
            results[futures[f]] = f.result()
            if done % 50 == 0:
                print(f"bench_fidelity: {done}/{len(jobs)} runs", file=sys.stderr)

    cells = []
    for scene in scenes:
        for kind in kinds:
            for c in configs:
                ref = results[(scene, kind, c, "accurate")]
                fast = results[(scene, kind, c, "fast")]
                cells.append({"scene": scene, "kind": kind, "config": c, "accurate": ref,
                              "fast": fast, "error": compare(fast, ref)})

    lines = [f"# Fast model against the time-ordered reference (sim.fidelity = accurate)", "",
             f"`scripts/bench_fidelity.py --res {a.res}` (gpu_64x32 at twice the resolution); "
             f"scenes {', '.join(scenes)}; ray kinds {', '.join(kinds)}; "
             f"{len(cells)} cells. Errors are the fast model's: cycles and DRAM bytes in percent of "
             f"the reference, hit rates and stall shares in percentage points (largest absolute "
             f"value over the cells). Host time: the reference's simulation seconds over the fast "
             f"model's (median).", ""]
    header = ("| config | max cycles % | mean cycles % | max DRAM % | max L1 hit pp | "
              "max L2 hit pp | max stall pp | cells > 1% | host ratio |")
    lines += [header, "|" + "---|" * 9]
    for c in configs:
        sel = [x for x in cells if x["config"] == c]
        err = [x["error"] for x in sel]
        worst = lambda k: max(err, key=lambda e: abs(e[k]))[k]
        stall_pp = max(abs(v) for e in err for k, v in e.items() if k.startswith("stall_"))
        over = sum(1 for e in err if abs(e["cycles_pct"]) > TARGET_PERCENT
                   or abs(e["dram_bytes_pct"]) > TARGET_PERCENT)
        lines.append(
            f"| {c} | {worst('cycles_pct'):+.2f} | "
            f"{statistics.mean(e['cycles_pct'] for e in err):+.2f} | "
            f"{worst('dram_bytes_pct'):+.2f} | {worst('l1_hit_rate_pp'):+.2f} | "
            f"{worst('l2_hit_rate_pp'):+.2f} | {stall_pp:.2f} | {over}/{len(sel)} | "
            f"{statistics.median(e['host_ratio'] for e in err):.1f}x |")
    misses = [x for x in cells if (
        abs(x["error"]["cycles_pct"]) > TARGET_PERCENT or abs(x["error"]["dram_bytes_pct"]) > TARGET_PERCENT)]
    lines += ["", f"## Cells over the {TARGET_PERCENT:g}% target ({len(misses)} of "
              f"{len(cells)})", ""]
    if misses:
        lines += ["| scene | kind | config | cycles % | DRAM % | fast cycles | reference cycles |",
                  "|" + "---|" * 7]
        for x in sorted(misses, key=lambda x: -abs(x["error"]["cycles_pct"])):
            lines.append(f"| {x['scene']} | {x['kind']} | {x['config']} | "
                         f"{x['error']['cycles_pct']:+.2f} | {x['error']['dram_bytes_pct']:+.2f} | "
                         f"{x['fast']['cycles']} | {x['accurate']['cycles']} |")
    fast_s = sum(x["fast"]["host_s"] for x in cells)
    ref_s = sum(x["accurate"]["host_s"] for x in cells)
    lines += ["", f"Host simulation seconds over all cells: fast {fast_s:.2f} s, "
              f"accurate {ref_s:.2f} s ({ref_s / fast_s:.1f}x)."]
    text = "\n".join(lines) + "\n"
    print(text)
    write_results(a.out, "fidelity", text, {"res": a.res, "cells": cells})


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Sampled simulation on frames it was never tuned on: error and interval coverage per design.

The sampling method's settings were chosen on bench_sampled.py's 24 frames (bunny, armadillo,
Cornell, camel, elephant, homer). This script draws its frames from other meshes of the same
Debian archive, and its sample seeds from a seed it prints (--seed, default: drawn from the
clock), so that no figure it prints was tuned on. For each frame it runs the full fast run
(the truth) once and then the sampled skip design at each period, for each sample design, over
--runs sample seeds, and reports per frame, design and period:

  * the cycles' and DRAM bytes' mean and 95th-percentile absolute error against the full run;
  * the share of runs whose 95% interval holds the full run's figure (coverage, over the runs
    that gave an interval), with its 95% Wilson interval, how many gave a zero-width interval on
    an inexact figure, and how many gave none (an estimate the data could not bound);
  * host seconds: the full run's and the sampled runs' median `host.run_time_s`; x+p adds the
    host time a first sampled run spent building the frame's profile (and its functional L2
    count) into a cache folder of this evaluation's own, so that no earlier run's cache entry
    makes it look free.

    scripts/eval_sampled.py [--rtsim build/rtsim] [--seed S] [--runs 30] [--periods 10,50]
        [--designs stratified,work] [--frames fandisk_large:diffuse:1024x768,...] [-j 2]
        [--spp N] [--set KEY=VALUE ...] [--target-error P] [--out bench/results]

--set gives every run (full and sampled) a config field, for example a large chip:
--set core.count=64 --set core.ray_slots=32. --target-error P sizes each sampled run with a pilot
(the periods are then the pilots' own); its host time counts the pilot.

Writes bench/results/sampled_heldout.md (and every run's figures to out/bench/).
"""
import argparse
import concurrent.futures
import math
import os
import random
import statistics
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import CGAL, ROOT, run_stats, write_results  # noqa: E402

# Meshes the sampling method was never tuned on (bench_sampled.py uses bunny, armadillo, camel,
# elephant, homer and the Cornell box; lion, cow, dino and diplodocus have since served to
# diagnose and set the window drain and warm-up, so they are tuning meshes too).
HELD_OUT = ["fandisk_large", "mannequin-devil", "man", "ChineseDragon-10kv", "bull", "elk",
            "hand", "bear", "anchor_dense", "bear_bis"]
KINDS = {"primary": ["--rays", "primary"],
         "ao": ["--rays", "ao"],
         "diffuse": ["--rays", "diffuse", "--diffuse-depth", "1"],
         "path2": ["--rays", "diffuse", "--diffuse-depth", "2"]}


def wilson(k, n, z=1.96):
    """The 95% Wilson interval of a proportion k / n."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (max(0.0, c - h), min(1.0, c + h))


def parse_frames(text, rng):
    """FRAME,... as MESH:KIND:WxH; 'random:N' draws N frames from the held-out meshes."""
    if text.startswith("random:"):
        n = int(text.split(":")[1])
        meshes = [m for m in HELD_OUT if os.path.exists(os.path.join(CGAL, m + ".off"))]
        # Distinct meshes while there are enough, then distinct (mesh, kind) pairs.
        pool = [(m, k) for m in meshes for k in KINDS]
        rng.shuffle(pool)
        out, seen = [], set()
        for m, k in pool:
            if len(out) == n:
                break
            if m in seen and len(seen) < len(meshes):
                continue
            seen.add(m)
            out.append((m, k, rng.choice(["512x512", "1024x768"])))
        return out
    frames = []
    for f in text.split(","):
        mesh, kind, res = f.split(":")
        if kind not in KINDS:
            sys.exit(f"eval_sampled: unknown kind {kind} (known: {', '.join(KINDS)})")
        frames.append((mesh, kind, res))
    return frames


def figure(stats, name):
    """The run's estimate of a figure; None where it gave none (a sample with no unit of work)."""
    s = stats["sampling"]
    if s.get("in_full"):
        # The plan could not beat the full run, which ran instead: exact.
        v = float(stats["total_cycles"] if name == "cycles"
                  else stats["bandwidth"]["dram"]["bytes"])
        return {"value": v, "lo": v, "hi": v, "caveat": ""}
    if "total_cycles" not in s:
        return {"value": float("nan"), "lo": None, "hi": None, "caveat": s.get("note", "")}
    return s["total_cycles"] if name == "cycles" else s["counters"].get("dram.bytes")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--periods", default="10,50")
    ap.add_argument("--designs", default="stratified,work")
    ap.add_argument("--frames", default="random:6")
    ap.add_argument("-j", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    ap.add_argument("--name", default="sampled_heldout")
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--target-error", type=float, default=None)
    a = ap.parse_args(argv)
    seed = a.seed if a.seed is not None else int(time.time()) % 1000000
    rng = random.Random(seed)
    frames = parse_frames(a.frames, rng)
    periods = [int(p) for p in a.periods.split(",")]
    designs = a.designs.split(",")
    # Sample seeds far from the 1-100 the method was tuned with.
    sample_seeds = [rng.randrange(1000, 10**9) for _ in range(a.runs)]
    print(f"eval_sampled: seed {seed}; frames {frames}", file=sys.stderr)
    rows, cells = [], []
    with tempfile.TemporaryDirectory() as tmp:
        cache = os.path.join(tmp, "cache")
        for fi, (mesh, kind, res) in enumerate(frames):
            scene = os.path.join(CGAL, mesh + ".off")
            frame = ["--scene", scene, "--spp", str(a.spp), "--bvh-cache", cache] + KINDS[kind]
            for kv in a.set:
                frame += ["--set", kv]
            base = frame + ["--res", res]
            # The mesh and BVH into the cache first (a frame of one tile: they do not depend on
            # the resolution), so that neither the full run nor the sampled ones time a build.
            run_stats(a.rtsim, frame + ["--res", "8x8"], os.path.join(tmp, f"f{fi}_bvh"),
                      "eval_sampled")
            full = run_stats(a.rtsim, base, os.path.join(tmp, f"f{fi}_full"), "eval_sampled")
            truth = {"cycles": float(full["total_cycles"]),
                     "dram": float(full["bandwidth"]["dram"]["bytes"])}
            sampled = base + ["--set", "sim.sampled=true",
                              "--set", "sim.sample_fast_forward=skip"]
            # The profile, once per frame, built by a first run into the empty cache (and then
            # read by the runs below): what building it cost is that run's own account.
            first = run_stats(a.rtsim, sampled + ["--set", "sim.sample_period_units=10"],
                              os.path.join(tmp, f"f{fi}_profile"), "eval_sampled")
            profile_s = profile_build_seconds(first, f"{mesh} {kind} {res}")
            jobs = []
            with concurrent.futures.ThreadPoolExecutor(a.j) as pool:
                for d in designs:
                    for p in periods:
                        for k, s in enumerate(sample_seeds):
                            args = sampled + ["--set", f"sim.sample_design={d}",
                                              "--set", f"sim.sample_period_units={p}",
                                              "--set", f"sim.sample_seed={s}"]
                            if a.target_error is not None:
                                args += ["--target-error", str(a.target_error)]
                            out = os.path.join(tmp, f"f{fi}_{d}_{p}_{k}")
                            jobs.append(((d, p), pool.submit(run_stats, a.rtsim, args, out,
                                                             "eval_sampled")))
            by_cell = {}
            for key, job in jobs:
                by_cell.setdefault(key, []).append(job.result())
            for (d, p), runs in by_cell.items():
                cell = {"mesh": mesh, "kind": kind, "res": res, "design": d, "period": p,
                        "full_cycles": truth["cycles"], "full_dram": truth["dram"],
                        "full_host_s": full["host"]["run_time_s"], "profile_s": profile_s,
                        "runs": []}
                for st in runs:
                    r = {"host_s": st["host"]["run_time_s"]}
                    for name, key in (("cycles", "cycles"), ("dram", "dram")):
                        e = figure(st, name)
                        if e is None:
                            continue
                        r[name] = {"value": e["value"], "lo": e["lo"], "hi": e["hi"],
                                   "caveat": e.get("caveat", "")}
                    cell["runs"].append(r)
                cells.append(cell)
                rows.append(summarise(cell))
                print(format_row(rows[-1]), file=sys.stderr)
    text = report(seed, a, frames, rows)
    write_results(a.out, a.name, text, {"seed": seed, "cells": cells})
    print(text)


def profile_build_seconds(stats, frame):
    """The host seconds a sampled run spent building its frame's profile and functional L2
    count (not reading them from the cache)."""
    prof = stats["sampling"]["profile"]
    if prof["cache"] == "hit":
        sys.exit(f"eval_sampled: {frame}: the first sampled run found its profile cached")
    host = stats["host"]
    l2 = host.get("functional_l2_s", 0.0) if host.get("functional_l2_cache") != "hit" else 0.0
    return prof["seconds"] + l2


def summarise(cell):
    out = {k: cell[k] for k in ("mesh", "kind", "res", "design", "period")}
    for name, truth in (("cycles", cell["full_cycles"]), ("dram", cell["full_dram"])):
        errs, covered, zero, unbounded, n = [], 0, 0, 0, 0
        for r in cell["runs"]:
            e = r.get(name)
            if e is None:
                continue
            n += 1
            if math.isnan(e["value"]):
                unbounded += 1  # no estimate at all
                continue
            errs.append(abs(e["value"] / truth - 1) * 100 if truth else 0.0)
            if e["lo"] is None:
                unbounded += 1  # no interval given: not counted in the coverage
                continue
            if e["lo"] == e["hi"] and e["value"] != truth:
                zero += 1
            covered += e["lo"] <= truth <= e["hi"]
        errs.sort()
        out[name] = {"n": n, "mean": statistics.mean(errs) if errs else float("nan"),
                     "p95": errs[min(len(errs) - 1, int(math.ceil(0.95 * len(errs))) - 1)]
                     if errs else float("nan"),
                     "covered": covered, "zero": zero, "unbounded": unbounded,
                     "wilson": wilson(covered, n - unbounded)}
    hs = [r["host_s"] for r in cell["runs"]]
    out["x"] = cell["full_host_s"] / statistics.median(hs) if hs else float("nan")
    out["x_with_profile"] = cell["full_host_s"] / (statistics.median(hs) + cell["profile_s"])
    return out


def format_row(r):
    c, d = r["cycles"], r["dram"]
    return (f"| {r['mesh']} | {r['kind']} | {r['res']} | {r['design']} | 1/{r['period']} | "
            f"{c['mean']:.2f}% | {c['p95']:.2f}% | "
            f"{100 * c['covered'] / max(1, c['n'] - c['unbounded']):.0f}% "
            f"({100 * c['wilson'][0]:.0f}-{100 * c['wilson'][1]:.0f}) | {c['zero']} | "
            f"{c['unbounded']} | {d['mean']:.2f}% | {d['p95']:.2f}% | "
            f"{100 * d['covered'] / max(1, d['n'] - d['unbounded']):.0f}% | {r['x']:.1f} | "
            f"{r['x_with_profile']:.2f} |")


def report(seed, a, frames, rows):
    lines = ["# Sampled simulation on held-out frames (scripts/eval_sampled.py)", "",
             f"Seed {seed} (frames and sample seeds drawn from it); {a.runs} runs per cell; "
             f"{a.spp} spp; settings: {' '.join(a.set) or 'defaults'}"
             f"{f'; --target-error {a.target_error}' if a.target_error is not None else ''}; "
             f"frames {', '.join(f'{m} {k} {r}' for m, k, r in frames)}. Meshes and seeds never "
             "used to tune the method. Each cell's truth is the full fast run of the frame. "
             "'no int.': runs whose estimate carried no interval (the data could not bound it); "
             "coverage is over the others. 'zero': zero-width intervals on an inexact figure. "
             "x: the full run's host.run_time_s over the sampled run's median; x+p adds the host "
             "time of building the frame's profile (and functional L2 count), once per frame.",
             "",
             "| mesh | kind | res | design | rate | cycles mean abs err | p95 | coverage (Wilson) "
             "| zero | no int. | DRAM mean abs err | p95 | DRAM cov | x | x+p |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    lines += [format_row(r) for r in rows]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()

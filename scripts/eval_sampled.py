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

-j runs that many sampled runs at a time: the x columns are then measured under that load
against a full run timed alone (on 2 cores, -j 2 made heavy frames' sampled runs up to twice as
slow); time with -j 1.

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
# diagnose and set the window drain and warm-up, hand the start-up units, bull the quick
# pilot's rule on rays in detail, blade the window hold and fandisk_large the warm-up's length
# on 64 x 32 cores, so they are tuning meshes too).
HELD_OUT = ["mech-holes-shark", "mannequin-devil", "man", "ChineseDragon-10kv", "elk", "bear",
            "anchor_dense", "bear_bis", "triceratops", "femur", "knot1", "b9_mesh"]
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


# Chips a frame can name: the default config's 8 cores, or a large one.
CHIPS = {"default": [], "64x32": ["--set", "core.count=64", "--set", "core.ray_slots=32"]}


def draw_frames(n, rng, spp, heavy, used):
    """N frames on held-out meshes, distinct meshes while there are enough (none of `used`, the
    meshes drawn already), then distinct (mesh, kind) pairs. Cheap: 512x512 or 1024x768 at `spp`
    on the default chip. Heavy: 1920x1080, 8 spp, a diffuse path on 64 x 32 cores (full fast
    runs of 10 s or more here), where sampling has most to save."""
    meshes = [m for m in HELD_OUT if os.path.exists(os.path.join(CGAL, m + ".off"))]
    kinds = ["diffuse", "path2"] if heavy else list(KINDS)
    pool = [(m, k) for m in meshes for k in kinds]
    rng.shuffle(pool)
    pool.sort(key=lambda mk: mk[0] in used)  # meshes not drawn yet first
    out, seen = [], set()
    for m, k in pool:
        if len(out) == n:
            break
        if m in seen and len(seen) < len(meshes):
            continue
        seen.add(m)
        if heavy:
            out.append((m, k, "1920x1080", 8, "64x32"))
        else:
            out.append((m, k, rng.choice(["512x512", "1024x768"]), spp, "default"))
    used.update(seen)
    return out


def parse_frames(text, rng, spp=1):
    """FRAME,... as MESH:KIND:WxH[:SPP[:CHIP]]; 'random:N' draws N cheap frames from the held-out
    meshes and 'heavy:N' N heavy ones (draw_frames)."""
    frames, used = [], set()
    for f in text.split(","):
        if f.startswith(("random:", "heavy:")):
            frames += draw_frames(int(f.split(":")[1]), rng, spp, f.startswith("heavy:"), used)
            continue
        parts = f.split(":")
        if len(parts) < 3 or len(parts) > 5:
            sys.exit(f"eval_sampled: frame {f}: MESH:KIND:WxH[:SPP[:CHIP]]")
        mesh, kind, res = parts[:3]
        if kind not in KINDS:
            sys.exit(f"eval_sampled: unknown kind {kind} (known: {', '.join(KINDS)})")
        chip = parts[4] if len(parts) > 4 else "default"
        if chip not in CHIPS:
            sys.exit(f"eval_sampled: unknown chip {chip} (known: {', '.join(CHIPS)})")
        frames.append((mesh, kind, res, int(parts[3]) if len(parts) > 3 else spp, chip))
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
    frames = parse_frames(a.frames, rng, a.spp)
    periods = [int(p) for p in a.periods.split(",")]
    designs = a.designs.split(",")
    # Sample seeds far from the 1-100 the method was tuned with.
    sample_seeds = [rng.randrange(1000, 10**9) for _ in range(a.runs)]
    print(f"eval_sampled: seed {seed}; frames {frames}", file=sys.stderr)
    rows, cells = [], []
    with tempfile.TemporaryDirectory() as tmp:
        cache = os.path.join(tmp, "cache")
        for fi, (mesh, kind, res, spp, chip) in enumerate(frames):
            scene = os.path.join(CGAL, mesh + ".off")
            frame = (["--scene", scene, "--spp", str(spp), "--bvh-cache", cache] + KINDS[kind] +
                     CHIPS[chip])
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
                cell = {"mesh": mesh, "kind": kind, "res": res, "spp": spp, "chip": chip,
                        "design": d, "period": p,
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


def p95(errs):
    """The 95th percentile of sorted errors (the nearest rank)."""
    return errs[min(len(errs) - 1, int(math.ceil(0.95 * len(errs))) - 1)]


def coverage_pct(c):
    """A figure's coverage over the runs that gave an interval, in percent."""
    return 100 * c["covered"] / max(1, c["n"] - c["unbounded"])


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
    out = {k: cell[k] for k in ("mesh", "kind", "res", "spp", "chip", "design", "period")}
    out["full_host_s"] = cell["full_host_s"]
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
        out[name] = {"n": n, "errs": errs,
                     "mean": statistics.mean(errs) if errs else float("nan"),
                     "p95": p95(errs) if errs else float("nan"),
                     "covered": covered, "zero": zero, "unbounded": unbounded,
                     "wilson": wilson(covered, n - unbounded)}
    hs = [r["host_s"] for r in cell["runs"]]
    out["x"] = cell["full_host_s"] / statistics.median(hs) if hs else float("nan")
    out["x_with_profile"] = cell["full_host_s"] / (statistics.median(hs) + cell["profile_s"])
    return out


def format_row(r):
    c, d = r["cycles"], r["dram"]
    return (f"| {r['mesh']} | {r['kind']} | {r['res']} | {r['spp']} | {r['chip']} | "
            f"{r['full_host_s']:.2f} | {r['design']} | 1/{r['period']} | "
            f"{c['mean']:.2f}% | {c['p95']:.2f}% | "
            f"{coverage_pct(c):.0f}% "
            f"({100 * c['wilson'][0]:.0f}-{100 * c['wilson'][1]:.0f}) | {c['zero']} | "
            f"{c['unbounded']} | {d['mean']:.2f}% | {d['p95']:.2f}% | "
            f"{coverage_pct(d):.0f}% | {r['x']:.1f} | "
            f"{r['x_with_profile']:.2f} |")


def report(seed, a, frames, rows):
    lines = ["# Sampled simulation on held-out frames (scripts/eval_sampled.py)", "",
             f"Seed {seed} (frames and sample seeds drawn from it); {a.runs} runs per cell; "
             f"settings: {' '.join(a.set) or 'defaults'}"
             f"{f'; --target-error {a.target_error}' if a.target_error is not None else ''}; "
             f"frames {', '.join(f'{m} {k} {r} {n} spp {c}' for m, k, r, n, c in frames)}. "
             "Meshes and seeds never "
             "used to tune the method. Each cell's truth is the full fast run of the frame. "
             "'no int.': runs whose estimate carried no interval (the data could not bound it); "
             "coverage is over the others. 'zero': zero-width intervals on an inexact figure. "
             "x: the full run's host.run_time_s over the sampled run's median; x+p adds the host "
             "time of building the frame's profile (and functional L2 count), once per frame.",
             "",
             "| mesh | kind | res | spp | chip | full s | design | rate | cycles mean abs err "
             "| p95 | coverage (Wilson) | zero | no int. | DRAM mean abs err | p95 | DRAM cov "
             "| x | x+p |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    lines += [format_row(r) for r in rows]
    lines += targets(rows)
    return "\n".join(lines) + "\n"


def targets(rows):
    """The rows pooled per design and rate, against the targets sampled runs are held to: mean
    |error| <= 1% and 95th percentile <= 3% (cycles, DRAM bytes), coverage >= 93% in every frame
    (Wilson lower bound >= 90%), no zero-width interval on an inexact figure, x >= 5 on frames
    whose full run takes 10 s or more, never below 1 / 1.1 on the others."""
    out = ["", "## Against the targets, per design and rate (all frames pooled)", "",
           "| design | rate | cycles mean / p95 | DRAM mean / p95 | worst frame's coverage "
           "(Wilson low) | zero | x+p on frames of 10 s or more (min) | x+p on the others (min) |",
           "|---|---|---|---|---|---|---|---|"]
    for key in sorted({(r["design"], r["period"]) for r in rows}):
        rs = [r for r in rows if (r["design"], r["period"]) == key]
        cells = []
        for name in ("cycles", "dram"):
            errs = sorted(e for r in rs for e in r[name]["errs"])
            if not errs:
                cells.append("n/a")
                continue
            cells.append(f"{statistics.mean(errs):.2f}% / {p95(errs):.2f}%")
        worst = min(rs, key=lambda r: r["cycles"]["wilson"][0])
        c = worst["cycles"]
        cov = f"{coverage_pct(c):.0f}% ({100 * c['wilson'][0]:.0f}%)"
        zero = sum(r["cycles"]["zero"] + r["dram"]["zero"] for r in rs)
        heavy = [r["x_with_profile"] for r in rs if r["full_host_s"] >= 10]
        cheap = [r["x_with_profile"] for r in rs if r["full_host_s"] < 10]
        xs = [f"{statistics.median(v):.2f} ({min(v):.2f})" if v else "none" for v in (heavy, cheap)]
        out.append(f"| {key[0]} | 1/{key[1]} | {cells[0]} | {cells[1]} | {cov} | {zero} | "
                   f"{xs[0]} | {xs[1]} |")
    return out


if __name__ == "__main__":
    main()

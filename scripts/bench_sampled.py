#!/usr/bin/env python3
"""Sampled simulation (sim.sampled = true) against the full run of the same frame.

For each scene x workload (primary, AO, one diffuse bounce, a 2-bounce diffuse path) the frame
runs once in full (the fast model, the truth here) and then sampled:
  * at each sampling period P in --periods, from every start unit the design can draw
    (sim.sample_first_unit = 0 .. P-1; at most --max-starts of them, evenly spread). A
    systematic sample of period P has exactly P equally likely outcomes, so over all starts the
    coverage of the 95% intervals (the share that holds the full run's figure) is the design's
    exact coverage, not an estimate from random seeds;
  * with --target-error T for each T in --target-errors (Stein's two-stage procedure: a pilot
    sizes the sample), from --adaptive-starts starts.
Per cell and mode it reports the error of the estimated total cycles, DRAM bytes and energy per
ray (stats.json's sampling.energy, from the counters' joint jackknife) against
the full run (mean and worst absolute percent, mean signed), the mean half-width of their
intervals and their coverage, the share of rays run in detail, and the host time: median
seconds of the sampled runs against the median of --full-repeats full runs (on this shared
machine, in this run).

Writes bench/results/sampled_warm.md and sampled_warm_pareto.svg: host seconds against the
cycles' mean absolute error, one point per mode and cell, the Pareto front marked; every run's
figures go to out/bench/NAME.json (untracked). Prints the summary. With --skip, the skip design
(sim.sample_fast_forward=skip: tiles far from a measured unit are never traced; each frame's
profile is computed once, untimed, before the timed runs) and bench/results/sampled_unpaired.*
instead.

With --design-set (repeatable) the design simulated, full and sampled, is the default config
with those fields changed. With --reference-set (repeatable; --skip only) each sampled run is
paired with a reference design, the default config with those fields changed (none: the default
itself): the reference measures every unit of each frame once, untimed (its cost listed), and
every sampled run passes --reference (sim/sampling/reference.h), which samples the reference design on
the same units (a child run, once per seed and period: in a sweep of designs with one seed it is
paid once, so its seconds are listed apart and left out of the run's host time). Writes
sampled.* (or --name).

    scripts/bench_sampled.py [--rtsim build/rtsim] [--res 1920x1080]
        [--scenes bunny,armadillo,cornell,camel,elephant,homer]
        [--workloads primary,ao,diffuse,path2] [--periods 10,20,100] [--max-starts 100]
        [--target-errors 5] [--adaptive-starts 5] [--full-repeats 3] [-j 2]
        [--set KEY=VALUE] [--skip] [--design-set KEY=VALUE] [--reference-set KEY=VALUE]
        [--name NAME] [--out bench/results]

Its scenes (--scenes, bunny, armadillo, Cornell, camel, elephant, homer) are the tuning set:
every sampling setting was chosen on them. --evaluate runs the evaluation set instead, through
scripts/eval_sampled.py: frames on meshes of the same Debian archive that no setting was chosen
on, drawn at report time from --seed (printed; drawn from the clock if not given), with sample
seeds drawn from it too. --eval-frames (default random:8,heavy:4) names them: cheap frames
(512x512 or 1024x768, the default chip, where fixed costs dominate) and heavy ones (1920x1080,
8 spp, a diffuse path on 64 x 32 cores, full runs of 10 s or more here, where sampling matters).
The skip design `work` at --periods (its first), --runs per frame (400 for a coverage claim
without its Wilson interval), or --target-errors (its first) to size each run with a pilot; the
x+p column counts the profile built cold; runs are timed one at a time. Writes
bench/results/sampled_evaluation.md, with --target-errors P sampled_evaluation_targetP.md (or
--name):

    scripts/bench_sampled.py --evaluate [--seed S] [--runs 20] [--target-errors 2]
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
from rtsim_run import ROOT, SCENES, run_stats, write_results  # noqa: E402
import eval_sampled  # noqa: E402  (the evaluation set: --evaluate)

WORKLOADS = {"primary": ["--rays", "primary"],
             "ao": ["--rays", "ao"],
             "diffuse": ["--rays", "diffuse", "--diffuse-depth", "1"],
             "path2": ["--rays", "diffuse", "--diffuse-depth", "2"]}
FIGURES = ("cycles", "dram_bytes", "energy")


def starts_for(period, most):
    """Start units to run for a period: all of them, or `most` evenly spread."""
    if period <= most:
        return list(range(period))
    return sorted({int(i * period / most) for i in range(most)})


def cpu_seconds(stats):
    """A run's CPU seconds over its run time (host.run_cpu_s); exits on an rtsim without it."""
    if "run_cpu_s" not in stats.get("host", {}):
        sys.exit("bench_sampled: stats.json has no host.run_cpu_s (an rtsim older than it)")
    return stats["host"]["run_cpu_s"]


def summarise(rows):
    out = {}
    for name in FIGURES:
        errs = [r[name]["error_pct"] for r in rows]
        covered = sum(r[name]["covered"] for r in rows)
        out[name] = {"mean_abs_error_pct": statistics.mean(abs(e) for e in errs),
                     "max_abs_error_pct": max(abs(e) for e in errs),
                     "mean_error_pct": statistics.mean(errs),
                     "mean_half_width_pct": statistics.mean(r[name]["half_width_pct"]
                                                            for r in rows),
                     "covered": covered,
                     "coverage": covered / len(rows)}
    out["detailed_share"] = statistics.mean(r["detailed_share"] for r in rows)
    out["units_measured"] = statistics.mean(r["units_measured"] for r in rows)
    out["host_s"] = statistics.median(r["host_s"] for r in rows)
    out["wall_s"] = statistics.median(r["wall_s"] for r in rows)
    out["cpu_s"] = statistics.median(r["cpu_s"] for r in rows)
    out["matched_host_s"] = statistics.median(r.get("matched_host_s", 0.0) for r in rows)
    out["runs"] = len(rows)
    return out


# The speed target: sampled runs this many times faster than the full run.
TARGET_SPEEDUP = 20.0
# The speed-ups: (key in a mode's summary, the seconds it divides, its label in the tables).
SPEEDUPS = (("speedup", "host_s", "x"), ("wall_speedup", "wall_s", "x wall"),
            ("cpu_speedup", "cpu_s", "x cpu"))


def speedup_interval(full, sampled, draws=2000, seed=1):
    """The 95% percentile-bootstrap interval of median(full) / median(sampled): each side's runs
    resampled with replacement (a shared machine moves run times by 10% and more between runs,
    so a cell's x is an estimate too). Seeded: the same runs give the same interval."""
    rng = random.Random(seed)
    ratios = sorted(statistics.median(rng.choices(full, k=len(full))) /
                    statistics.median(rng.choices(sampled, k=len(sampled)))
                    for _ in range(draws))
    return ratios[int(0.025 * draws)], ratios[int(0.975 * draws) - 1]


def wilson(hits, n, z=1.96):
    """The 95% Wilson score interval of a binomial share: how sure a coverage over n seeds is."""
    if n == 0:
        return 0.0, 1.0
    p = hits / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def pareto(points):
    """Indices of the points no other point beats on both host seconds and error."""
    front = []
    for i, (x, y) in enumerate(points):
        if not any((x2 <= x and y2 <= y and (x2 < x or y2 < y)) for x2, y2 in points):
            front.append(i)
    return front


def svg_plot(cells, path):
    """Host seconds (log) against the cycles' mean absolute error (log), a point per mode and
    cell, coloured by mode; the Pareto front over all points drawn as a line."""
    pts = []
    for c in cells:
        for m in c["modes"]:
            if m["runs"] == 0:
                continue
            err = max(m["cycles"]["mean_abs_error_pct"], 0.01)
            pts.append((m["host_s"], err, m["mode"], f"{c['scene']}/{c['workload']}"))
    if not pts:
        return
    modes = sorted({p[2] for p in pts}, key=lambda m: (not m.startswith("1/"), m))
    palette = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2"]
    colour = {m: palette[i % len(palette)] for i, m in enumerate(modes)}
    W, H, L, R, T, B = 760, 500, 70, 190, 40, 60
    lx = [math.log10(p[0]) for p in pts]
    ly = [math.log10(p[1]) for p in pts]
    x0, x1 = math.floor(min(lx) * 2) / 2, math.ceil(max(lx) * 2) / 2 or 0.5
    y0, y1 = math.floor(min(ly)), math.ceil(max(ly))
    if x1 <= x0:
        x1 = x0 + 0.5
    if y1 <= y0:
        y1 = y0 + 1

    def X(v):
        return L + (math.log10(v) - x0) / (x1 - x0) * (W - L - R)

    def Y(v):
        return H - B - (math.log10(v) - y0) / (y1 - y0) * (H - T - B)

    s = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" '
         f'font-family="sans-serif" font-size="12">',
         f'<rect width="{W}" height="{H}" fill="white"/>',
         f'<text x="{L}" y="22" font-size="14">Sampled simulation: host time against error '
         f'(one point per mode and scene/workload)</text>']
    for e in range(int(y0), int(y1) + 1):
        y = Y(10 ** e)
        s.append(f'<line x1="{L}" x2="{W - R}" y1="{y:.1f}" y2="{y:.1f}" stroke="#ddd"/>')
        s.append(f'<text x="{L - 6}" y="{y + 4:.1f}" text-anchor="end">{10 ** e:g}%</text>')
    t = x0
    while t <= x1 + 1e-9:
        x = X(10 ** t)
        s.append(f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{T}" y2="{H - B}" stroke="#eee"/>')
        s.append(f'<text x="{x:.1f}" y="{H - B + 16}" text-anchor="middle">{10 ** t:.3g}</text>')
        t += 0.5
    s.append(f'<text x="{(L + W - R) / 2}" y="{H - 18}" text-anchor="middle">host seconds per '
             'run (median; log)</text>')
    s.append(f'<text transform="translate(16,{(T + H - B) / 2}) rotate(-90)" '
             'text-anchor="middle">cycles: mean absolute error against the full run (log)</text>')
    front = sorted((pts[i] for i in pareto([(p[0], p[1]) for p in pts])), key=lambda p: p[0])
    s.append('<polyline fill="none" stroke="black" stroke-width="1.5" stroke-dasharray="5,3" '
             'points="' + " ".join(f"{X(p[0]):.1f},{Y(p[1]):.1f}" for p in front) + '"/>')
    for p in pts:
        s.append(f'<circle cx="{X(p[0]):.1f}" cy="{Y(p[1]):.1f}" r="4" fill="{colour[p[2]]}" '
                 f'fill-opacity="0.8"><title>{p[3]} {p[2]}: {p[0]:.2f} s, {p[1]:.2f}%</title>'
                 '</circle>')
    for p in front:
        s.append(f'<circle cx="{X(p[0]):.1f}" cy="{Y(p[1]):.1f}" r="7" fill="none" '
                 'stroke="black"/>')
    ly_ = T + 10
    for m in modes:
        s.append(f'<circle cx="{W - R + 20}" cy="{ly_}" r="5" fill="{colour[m]}"/>')
        s.append(f'<text x="{W - R + 30}" y="{ly_ + 4}">{m}</text>')
        ly_ += 18
    s.append(f'<circle cx="{W - R + 20}" cy="{ly_}" r="7" fill="none" stroke="black"/>')
    s.append(f'<text x="{W - R + 30}" y="{ly_ + 4}">Pareto front</text>')
    s.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(s) + "\n")


def evaluate(args):
    """The evaluation set through eval_sampled.py (its own seed, meshes and report)."""
    # One run at a time: the full run is timed alone, and a sampled run timed beside another
    # (each traces on a helper thread) took up to twice as long on 2 cores.
    argv = ["--rtsim", args.rtsim, "--frames", args.eval_frames, "--designs", "work",
            "--periods", args.periods.split(",")[0], "--runs", str(args.runs), "-j", "1",
            "--out", args.out]
    # A run sized by a pilot reports beside the plain one, not over it.
    target = args.target_errors.split(",")[0] if args.target_errors else None
    default_name = "sampled_evaluation" + (f"_target{target.replace('.', '_')}" if target else "")
    argv += ["--name", args.name or default_name]
    if args.seed is not None:
        argv += ["--seed", str(args.seed)]
    if target:  # given: each run sized by a pilot
        argv += ["--target-error", target]
    for kv in args.set:
        argv += ["--set", kv]
    eval_sampled.main(argv)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--res", default="1920x1080")
    ap.add_argument("--scenes", default="bunny,armadillo,cornell,camel,elephant,homer")
    ap.add_argument("--workloads", default="primary,ao,diffuse,path2")
    ap.add_argument("--periods", default="10,20,100")
    ap.add_argument("--design", default="stratified", choices=["stratified", "systematic"])
    ap.add_argument("--max-starts", type=int, default=100,
                    help="systematic: at most this many start units per period (all if fewer); "
                         "stratified: this many sample seeds")
    ap.add_argument("--target-errors", default=None,
                    help="comma list of --target-error percentages (default 5; '' for none)")
    ap.add_argument("--adaptive-starts", type=int, default=5)
    ap.add_argument("--full-repeats", type=int, default=3)
    ap.add_argument("--unit-rays", type=int, default=1024)
    ap.add_argument("--skip", action="store_true",
                    help="the skip design (sim.sample_fast_forward=skip: units of tiles, tiles "
                         "far from a measured unit never traced); writes sampled_unpaired.*, "
                         "or sampled.* with --reference-set")
    ap.add_argument("--set", action="append", default=[],
                    help="KEY=VALUE config override for the sampled runs (repeatable)")
    ap.add_argument("--design-set", action="append", default=[],
                    help="KEY=VALUE: the design simulated, full and sampled (repeatable)")
    ap.add_argument("--reference-set", action="append", default=None,
                    help="KEY=VALUE: pair the sampled runs with this reference design, the "
                         "default config changed so (repeatable; '' for the default itself)")
    ap.add_argument("--name", default=None, help="results' file name (default by mode)")
    ap.add_argument("-j", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    ap.add_argument("--evaluate", action="store_true",
                    help="the evaluation set (held-out meshes, drawn from --seed) instead")
    ap.add_argument("--eval-frames", default="random:8,heavy:4")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--runs", type=int, default=20)
    args = ap.parse_args(argv)
    if args.evaluate:
        return evaluate(args)
    if args.target_errors is None:
        args.target_errors = "5"
    scenes = args.scenes.split(",")
    workloads = args.workloads.split(",")
    periods = [int(p) for p in args.periods.split(",") if p]
    targets = [float(t) for t in args.target_errors.split(",") if t]
    if args.full_repeats < 1:
        sys.exit("bench_sampled: --full-repeats must be 1 or more (each cell's full run is the "
                 "truth its errors are measured against)")
    if args.max_starts < 1:
        sys.exit("bench_sampled: --max-starts must be 1 or more")
    for s in scenes:
        if s not in SCENES:
            sys.exit(f"bench_sampled: unknown scene {s} (known: {', '.join(SCENES)})")
    for w in workloads:
        if w not in WORKLOADS:
            sys.exit(f"bench_sampled: unknown workload {w} (known: {', '.join(WORKLOADS)})")
    sets = [a for kv in args.set for a in ("--set", kv)]
    if args.skip:
        sets += ["--set", "sim.sample_fast_forward=skip"]
    design = [a for kv in args.design_set for a in ("--set", kv)]
    paired = args.reference_set is not None
    reference = [a for kv in (args.reference_set or []) if kv for a in ("--set", kv)]
    if paired and not args.skip:
        sys.exit("bench_sampled: --reference-set needs --skip (a reference's units are tiles)")
    out_name = args.name or ("sampled" if paired else
                             "sampled_unpaired" if args.skip else "sampled_warm")
    references = {}  # (scene, workload): the reference's folder and its full run's seconds

    profiles = {}
    with tempfile.TemporaryDirectory() as tmp:
        def frame(scene, wl, res=args.res):
            return ["--scene", SCENES[scene], "--res", res, "--bvh-cache",
                    os.path.join(tmp, "bvh")] + WORKLOADS[wl] + design

        def run(job):
            scene, wl, mode, k = job
            extra = []
            if mode != "full":
                extra = ["--set", "sim.sampled=true",
                         "--set", f"sim.sample_unit_rays={args.unit_rays}"] + sets
                extra += ["--set", f"sim.sample_design={args.design}"]
                # A systematic sample is fixed by its start; a stratified one by its seed.
                if mode.startswith("1/"):
                    extra += ["--set", f"sim.sample_period_units={mode[2:]}"]
                    extra += (["--set", f"sim.sample_first_unit={k}"]
                              if args.design == "systematic" else
                              ["--set", f"sim.sample_seed={k + 1}"])
                else:  # "target T%": the pilot's period is the first listed
                    extra += ["--set", f"sim.sample_period_units={periods[0]}",
                              "--target-error", mode.split()[1].rstrip("%")]
                    extra += (["--set", f"sim.sample_first_unit={k % periods[0]}"]
                              if args.design == "systematic" else
                              ["--set", f"sim.sample_seed={k + 1}"])
            if mode != "full" and paired:
                extra += ["--reference", references[(scene, wl)][0]]
            out = os.path.join(tmp, "-".join([scene, wl, mode.replace("/", "_").replace(" ", "_"),
                                              str(k)]))
            # The whole process's wall seconds too: a sampled run's start, estimates and outputs
            # are outside its host.run_time_s, and a larger share of it than of a full run's.
            start = time.monotonic()
            st = run_stats(args.rtsim, frame(scene, wl) + extra, out, "bench_sampled")
            st["bench_wall_s"] = time.monotonic() - start
            return st

        # The BVH cache is filled first, so no timed run builds a tree; in the skip design, each
        # frame's profile too (what it cost is listed).
        for scene in scenes:
            run_stats(args.rtsim, frame(scene, "primary", "8x8"),
                      os.path.join(tmp, "warm-" + scene), "bench_sampled")
        if args.skip:
            for scene in scenes:
                for wl in workloads:
                    st = run_stats(args.rtsim, frame(scene, wl) + ["--set", "sim.sampled=true"]
                                   + sets, os.path.join(tmp, f"profile-{scene}-{wl}"),
                                   "bench_sampled")
                    profiles[(scene, wl)] = st["sampling"]["profile"]["seconds"]
                    if paired:
                        # The reference design (its own fields, not the design's) measuring
                        # every unit.
                        ref_args = (["--scene", SCENES[scene], "--res", args.res,
                                     "--bvh-cache", os.path.join(tmp, "bvh")] + WORKLOADS[wl])
                        d = os.path.join(tmp, f"reference-{scene}-{wl}")
                        st = run_stats(args.rtsim, ref_args + reference + sets
                                       + ["--set", "sim.sampled=true",
                                          "--set", "sim.sample_period_units=1"], d,
                                       "bench_sampled")
                        references[(scene, wl)] = (d, st["host"]["run_time_s"])
                        # A paired run's units (sim.sample_paired_unit_tiles) may merge the
                        # reference's: the profile of that unit size is made here, untimed, by
                        # a paired run with a seed the timed runs do not use.
                        period = periods[0] if periods else 50
                        run_stats(args.rtsim, frame(scene, wl) + sets
                                  + ["--set", "sim.sampled=true",
                                     "--set", f"sim.sample_period_units={period}",
                                     "--set", "sim.sample_seed=1000000", "--reference", d],
                                  os.path.join(tmp, f"profile-paired-{scene}-{wl}"),
                                  "bench_sampled")
        jobs = []
        for scene in scenes:
            for wl in workloads:
                sampled = []
                for p in periods:
                    ks = (starts_for(p, args.max_starts) if args.design == "systematic"
                          else range(args.max_starts))
                    sampled += [(scene, wl, f"1/{p}", k) for k in ks]
                for t in targets:
                    sampled += [(scene, wl, f"target {t:g}%", k)
                                for k in range(args.adaptive_starts)]
                # The full runs spread evenly among the cell's sampled runs: x divides seconds
                # measured side by side, not minutes apart (a frame's full runs moved up to 1.9x
                # between benches on this shared machine).
                fulls = [(scene, wl, "full", k) for k in range(args.full_repeats)]
                at = [round((k + 0.5) * len(sampled) / len(fulls)) for k in range(len(fulls))]
                for i in range(len(sampled) + 1):
                    jobs += [f for f, a in zip(fulls, at) if a == i]
                    if i < len(sampled):
                        jobs.append(sampled[i])
        with concurrent.futures.ThreadPoolExecutor(args.j) as pool:
            results = dict(zip(jobs, pool.map(run, jobs)))

    cells = []
    for scene in scenes:
        for wl in workloads:
            fulls = [results[(scene, wl, "full", k)] for k in range(args.full_repeats)]
            truth = fulls[0]
            for f in fulls[1:]:
                if f["total_cycles"] != truth["total_cycles"]:
                    sys.exit(f"bench_sampled: {scene}/{wl}: full runs differ")
            # Each full run's seconds (for the speed-ups' intervals) and their medians.
            full_runs = {"host_s": [f["host"]["run_time_s"] for f in fulls],
                         "wall_s": [f["bench_wall_s"] for f in fulls],
                         "cpu_s": [cpu_seconds(f) for f in fulls]}
            full = {"total_cycles": truth["total_cycles"],
                    "dram_bytes": truth["counters"]["dram.bytes"],
                    "energy": truth["energy"]["per_ray_nj"]}
            for measure, runs in full_runs.items():
                full[measure] = statistics.median(runs)
                full["runs_" + measure] = runs
            cell = {"scene": scene, "workload": wl, "rays": truth["rays"]["total"],
                    "full": full, "modes": []}
            for mode in [f"1/{p}" for p in periods] + [f"target {t:g}%" for t in targets]:
                rows = []
                no_estimate = 0
                for (sc, w, m, k), st in results.items():
                    if (sc, w, m) != (scene, wl, mode):
                        continue
                    sm = st["sampling"]
                    if "total_cycles" not in sm:
                        # Too few units at this period for an estimate (a short frame): counted,
                        # not averaged in.
                        no_estimate += 1
                        continue
                    # A paired run's matched reference sample is paid once per seed in a
                    # sweep: listed apart.
                    matched_s = sm.get("reference", {}).get("matched_host_s", 0.0)
                    row = {"start": k, "detailed_share": sm["detailed_share"],
                           "units_measured": sm["units_measured"],
                           "host_s": st["host"]["run_time_s"] - matched_s,
                           # The matched sample's seconds are its whole child process's.
                           "wall_s": st["bench_wall_s"] - matched_s,
                           # The process's own CPU seconds: the matched sample's child is
                           # another process.
                           "cpu_s": cpu_seconds(st),
                           "matched_host_s": matched_s}
                    if "energy" not in sm:
                        sys.exit(f"bench_sampled: {scene}/{wl}: a sampled run without "
                                 "sampling.energy (an rtsim older than its energy intervals)")
                    for name, t, est in (("cycles", truth["total_cycles"], sm["total_cycles"]),
                                         ("dram_bytes", truth["counters"]["dram.bytes"],
                                          # absent: no measured unit moved a DRAM byte
                                          sm["counters"].get("dram.bytes", {
                                              "value": 0.0, "lo": 0.0, "hi": 0.0,
                                              "half_width_pct": 0.0})),
                                         ("energy", truth["energy"]["per_ray_nj"],
                                          sm["energy"]["per_ray_nj"])):
                        # An unbounded interval is written as null: it holds anything, but
                        # says nothing, so it counts as a miss with an infinite width.
                        if est["lo"] is None or est["hi"] is None:
                            est = dict(est, lo=math.inf, hi=-math.inf, half_width_pct=math.inf)
                        row[name] = {"value": est["value"],
                                     "error_pct": 100.0 * (est["value"] - t) / t,
                                     "half_width_pct": est["half_width_pct"],
                                     # Every unit measured (period 1) gives a zero-width
                                     # interval: its sum of per-unit doubles is the run's
                                     # count up to rounding, which must not count as a miss.
                                     "covered": (est["lo"] - 1e-9 * abs(t) <= t
                                                 <= est["hi"] + 1e-9 * abs(t))}
                    if "target" in sm:
                        row["target_met"] = sm["target"]["met"]
                    rows.append(row)
                if not rows:
                    cell["modes"].append({"mode": mode, "runs": 0, "no_estimate": no_estimate})
                    continue
                summary = summarise(rows)
                summary["no_estimate"] = no_estimate
                summary["mode"] = mode
                for key, measure, _ in SPEEDUPS:
                    summary[key] = full[measure] / summary[measure]
                    summary[key + "_interval"] = speedup_interval(
                        full["runs_" + measure], [r[measure] for r in rows])
                summary["rows"] = rows
                cell["modes"].append(summary)
            cells.append(cell)

    lines = ["# Sampled simulation against the full run (scripts/bench_sampled.py)", "",
             (f"{args.res}, sim.sample_fast_forward=skip (units of tiles, tiles far from a "
              "measured unit never traced; each frame's profile computed by its first sampled "
              "run and cached for the others, its cost listed below the tables)"
              if args.skip else f"{args.res}, units of {args.unit_rays} rays")
             + f", {args.design} design; workloads: "
             "primary; ao (2 AO rays per primary hit, primaries not simulated); diffuse (1 "
             "bounce); path2 (2-bounce diffuse path). Each cell's frame runs in full (the "
             f"fast model) {args.full_repeats} times, spread evenly among its sampled runs, "
             "and sampled at 1 unit in P "
             + (f"from every start unit (at most {args.max_starts}, evenly spread: the "
                "systematic design's outcomes, so coverage is exact over them)"
                if args.design == "systematic" else
                f"with {args.max_starts} sample seeds (sim.sample_seed; the frame is the same)")
             + ", and with --target-error from a few seeds."
             + (f" Design: the default config with {', '.join(args.design_set)}."
                if args.design_set else "")
             + (" Paired (--reference) with the reference design "
                + (f"(the default config with {', '.join(k for k in args.reference_set if k)})"
                   if any(args.reference_set) else "(the default config)")
                + ", which measured every unit of each frame once, untimed (seconds below); "
                "host s leaves out each run's matched reference sample (a child run, paid once "
                "per seed in a sweep; its median seconds below)." if paired else "")
             + " Errors and half-widths in percent of the full "
             "run; cov: the share of runs whose 95% interval holds the full run's figure; "
             "host: median seconds per run (host.run_time_s), x: full / sampled host seconds, "
             "x wall: the same of the whole processes' wall seconds (start, estimates and "
             "outputs included), x cpu: the same of the CPU seconds the run took over its "
             "host.run_time_s, every thread's (host.run_cpu_s: what a busy machine pays, "
             "whatever else runs beside it; a --target-error run's pilot, a child process, is "
             "not in it), on this shared 2-core machine, "
             f"{args.j} run{'s' if args.j > 1 else ''} at a time.", "",
             "| scene | workload | rays | mode | runs | detailed | units | cycles mean abs err "
             "| max | mean | half-width | cov | DRAM mean abs err | max | half-width | cov "
             "| energy/ray mean abs err | max | half-width | cov | host s | x | x wall | x cpu |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
             "---|---|---|---|"]
    for c in cells:
        lines.append(f"| {c['scene']} | {c['workload']} | {c['rays']} | full | "
                     f"{args.full_repeats} | 100% | | | | | | | | | | | | | | | "
                     f"{c['full']['host_s']:.2f} | 1 | 1 | 1 |")
        for m in c["modes"]:
            if m["runs"] == 0:
                lines.append(f"| | | | {m['mode']} | 0 ({m['no_estimate']} without an estimate: "
                             "too few units) | | | | | | | | | | | | | | | | | | | |")
                continue
            cy, dr, en = m["cycles"], m["dram_bytes"], m["energy"]
            lines.append(
                f"| | | | {m['mode']} | {m['runs']}"
                f"{' (+' + str(m['no_estimate']) + ' without)' if m['no_estimate'] else ''} | "
                f"{100 * m['detailed_share']:.1f}% | "
                f"{m['units_measured']:.0f} | {cy['mean_abs_error_pct']:.2f}% | "
                f"{cy['max_abs_error_pct']:.2f}% | {cy['mean_error_pct']:+.2f}% | "
                f"{cy['mean_half_width_pct']:.2f}% | {100 * cy['coverage']:.0f}% | "
                f"{dr['mean_abs_error_pct']:.2f}% | {dr['max_abs_error_pct']:.2f}% | "
                f"{dr['mean_half_width_pct']:.2f}% | {100 * dr['coverage']:.0f}% | "
                f"{en['mean_abs_error_pct']:.2f}% | {en['max_abs_error_pct']:.2f}% | "
                f"{en['mean_half_width_pct']:.2f}% | {100 * en['coverage']:.0f}% | "
                f"{m['host_s']:.2f} | "
                + "".join(f"{m[key]:.2f} | " for key, _, _ in SPEEDUPS).rstrip())
    # Per mode over every cell: the figures the targets are stated in.
    lines += ["", "Per mode, over every cell:", "",
              "| mode | cells | cycles mean abs err (worst cell) | cycles coverage (worst cell) "
              "| DRAM mean abs err (worst cell) | DRAM coverage (worst cell) "
              "| energy/ray mean abs err (worst cell) | energy/ray coverage (worst cell) "
              "| x median (worst cell) | x wall median (worst cell) "
              "| x cpu median (worst cell) |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    mode_names = [m["mode"] for m in cells[0]["modes"]] if cells else []
    for mode in mode_names:
        ms = [m for c in cells for m in c["modes"] if m["mode"] == mode and m["runs"] > 0]
        if not ms:
            continue
        cy = [m["cycles"] for m in ms]
        dr = [m["dram_bytes"] for m in ms]
        en = [m["energy"] for m in ms]
        lines.append(
            f"| {mode} | {len(ms)} | "
            f"{statistics.mean(x['mean_abs_error_pct'] for x in cy):.2f}% "
            f"({max(x['mean_abs_error_pct'] for x in cy):.2f}%) | "
            f"{100 * statistics.mean(x['coverage'] for x in cy):.0f}% "
            f"({100 * min(x['coverage'] for x in cy):.0f}%) | "
            f"{statistics.mean(x['mean_abs_error_pct'] for x in dr):.2f}% "
            f"({max(x['mean_abs_error_pct'] for x in dr):.2f}%) | "
            f"{100 * statistics.mean(x['coverage'] for x in dr):.0f}% "
            f"({100 * min(x['coverage'] for x in dr):.0f}%) | "
            f"{statistics.mean(x['mean_abs_error_pct'] for x in en):.2f}% "
            f"({max(x['mean_abs_error_pct'] for x in en):.2f}%) | "
            f"{100 * statistics.mean(x['coverage'] for x in en):.0f}% "
            f"({100 * min(x['coverage'] for x in en):.0f}%) | "
            + "".join(f"{statistics.median(m[key] for m in ms):.2f} "
                      f"({min(m[key] for m in ms):.2f}) | " for key, _, _ in SPEEDUPS).rstrip())
    # A cell's coverage over 100 seeds is itself a sample: a cell whose intervals truly cover
    # 95% shows less than 93% (92 of 100 or fewer) about one time in eight, so a few of 24 cells
    # fall below 93% by chance alone. Listed: the cells below the target, with the 95% interval
    # of their coverage; a cell whose interval lies wholly below it falls short beyond chance.
    target = 0.93
    lines += ["", f"Cells whose coverage is below {100 * target:.0f}% (the 95% Wilson interval "
              "of the coverage over the cell's seeds; 'short' when it lies wholly below), and "
              "every cell's seeds pooled:", "",
              "| mode | figure | cells below | short beyond chance | pooled coverage (95% interval) |",
              "|---|---|---|---|---|"]
    for mode in mode_names:
        ms = [(c, m) for c in cells for m in c["modes"] if m["mode"] == mode and m["runs"] > 0]
        for fig, label in (("cycles", "cycles"), ("dram_bytes", "DRAM bytes")):
            below, short, hits, n = [], [], 0, 0
            for c, m in ms:
                k = m[fig]["covered"]
                hits += k
                n += m["runs"]
                lo, hi = wilson(k, m["runs"])
                if m[fig]["coverage"] < target:
                    below.append(f"{c['scene']} {c['workload']} {100 * m[fig]['coverage']:.0f}% "
                                 f"({100 * lo:.0f}-{100 * hi:.0f}%)")
                    if hi < target:
                        short.append(f"{c['scene']} {c['workload']}")
            lo, hi = wilson(hits, n)
            lines.append(f"| {mode} | {label} | {'; '.join(below) or 'none'} | "
                         f"{', '.join(short) or 'none'} | {100 * hits / max(n, 1):.1f}% "
                         f"({100 * lo:.1f}-{100 * hi:.1f}%) |")
    # Speed: a cell's x is a ratio of medians over its runs on a shared machine, so it carries
    # an interval too; a cell whose interval lies wholly below the target falls short beyond
    # the machine's noise.
    lines += ["", f"Cells below {TARGET_SPEEDUP:g}x (each x with the 95% bootstrap interval of "
              "its ratio of medians over the cell's full and sampled runs; 'short' when the "
              "interval lies wholly below):", "",
              "| mode | measure | cells below | short beyond noise |", "|---|---|---|---|"]
    for mode in mode_names:
        ms = [(c, m) for c in cells for m in c["modes"] if m["mode"] == mode and m["runs"] > 0]
        for key, _, label in SPEEDUPS:
            below, short = [], []
            for c, m in ms:
                lo, hi = m[key + "_interval"]
                if m[key] < TARGET_SPEEDUP:
                    below.append(f"{c['scene']} {c['workload']} {m[key]:.1f} ({lo:.1f}-{hi:.1f})")
                    if hi < TARGET_SPEEDUP:
                        short.append(f"{c['scene']} {c['workload']}")
            lines.append(f"| {mode} | {label} | {'; '.join(below) or 'none'} | "
                         f"{', '.join(short) or 'none'} |")
    if profiles:
        lines += ["", "Frame profiles (the skip design's; computed once per frame by an untimed "
                  "sampled run before the timed ones, which all loaded it from the cache; on all "
                  "host cores):", "",
                  "| scene | workload | profile s | full run host s |", "|---|---|---|---|"]
        for c in cells:
            lines.append(f"| {c['scene']} | {c['workload']} | "
                         f"{profiles[(c['scene'], c['workload'])]:.2f} | "
                         f"{c['full']['host_s']:.2f} |")
            c["profile_s"] = profiles[(c["scene"], c["workload"])]
    if paired:
        lines += ["", "Reference design (paid once per frame by a sweep: it measures every unit; "
                  "and once per seed and period: its matched sample):", "",
                  "| scene | workload | reference full s | matched sample s, median per mode "
                  "| full run host s |", "|---|---|---|---|---|"]
        for c in cells:
            ref_s = references[(c["scene"], c["workload"])][1]
            c["reference_s"] = ref_s
            matched = ", ".join(f"{m['mode']} {m['matched_host_s']:.2f}" for m in c["modes"]
                                if m["runs"] > 0)
            lines.append(f"| {c['scene']} | {c['workload']} | {ref_s:.2f} | {matched} | "
                         f"{c['full']['host_s']:.2f} |")
    lines += ["", f"Plot: {out_name}_pareto.svg (host seconds against the cycles' mean absolute "
              "error; the dashed line is the Pareto front)."]
    text = "\n".join(lines) + "\n"
    write_results(args.out, out_name, text,
                  {"res": args.res, "unit_rays": args.unit_rays, "periods": periods,
                   "design": args.design,
                   "target_errors": targets, "cells": cells})
    svg_plot(cells, os.path.join(args.out, out_name + "_pareto.svg"))
    print(text)


if __name__ == "__main__":
    main()

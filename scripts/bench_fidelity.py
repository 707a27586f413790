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
    scripts/bench_fidelity.py --random N [--seed S] [-j 2] [--out bench/results]

--random N draws N cells at random, each a config drawn from the schema's ranges (MSHRs 1-32,
banks, channels, cores x slots up to 64 x 32, cache sizes and replacement policies, crossbar
widths, unit sharing, treelets with and without loads, packets, write traffic, command DRAM,
L1 and L2 prefetchers, stream buffers and cache levels below the L1s or the L2, drawn from
streams of their own so that the rest of each config is what the seed drew before they existed)
on a mesh (TUNED_SCENES, which the fixed matrix uses, and HELD_OUT_SCENES, which it never used)
with a ray kind, from a seed it prints (drawn at run time unless --seed). It reports the cells
within 1%, the worst, the distribution, and how the fast run judged itself (stats.json
fidelity_check): every cell should be within 1% or flagged. Writes
bench/results/fidelity_random.md.

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
import math
import os
import statistics
import subprocess
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

# The seed sim/fidelity_check.h's regimes and bounds were set on: report on others.
TUNING_SEED = 1001
# --random: meshes the fixed matrix uses, and meshes it never used.
TUNED_SCENES = ["cornell", "sphere", "bunny", "armadillo"]
HELD_OUT_SCENES = ["turbine", "camel", "fandisk_large", "cow", "dino", "elk"]
RANDOM_KINDS = {"primary": ["--rays", "primary"], "ao": ["--rays", "ao"],
                "shadow": ["--rays", "primary,shadow"],
                "diffuse": ["--rays", "diffuse", "--diffuse-depth", "1"]}


def draw_config(rng, path_rng=None, cache_rng=None):
    """One config drawn from the schema's ranges: its fields, --set arguments and a label."""
    c = {}
    cores = rng.choice([1, 2, 4, 8, 16, 32, 64])
    slots = rng.choice([1, 2, 4, 8, 16, 32])
    c["core.count"] = cores
    c["core.ray_slots"] = slots
    c["l1.mshrs"] = rng.choice([1, 2, 4, 8, 16, 32])
    c["l2.mshrs"] = rng.choice([1, 2, 4, 8, 16, 32, 64])
    c["l1.banks"] = rng.choice([1, 1, 2, 4])
    c["l2.banks"] = rng.choice([1, 2, 4, 8, 16])
    c["l1.size_kib"] = rng.choice([4, 8, 16, 32, 64])
    c["l1.ways"] = rng.choice([1, 2, 4, 8])
    c["l2.size_kib"] = rng.choice([64, 128, 256, 512, 1024, 4096])
    c["l2.ways"] = rng.choice([4, 8, 16])
    c["l1.replacement"] = rng.choice(["lru", "lru", "fifo", "random", "tree_plru", "srrip"])
    c["l2.replacement"] = rng.choice(["lru", "lru", "fifo", "random", "tree_plru", "srrip"])
    c["crossbar.bytes_per_cycle"] = rng.choice([0, 16, 32, 64, 128])
    c["dram.channels"] = rng.choice([1, 2, 4, 8])
    c["box_unit.shared_by"] = rng.choice([1, 1, 2, 4])
    c["triangle_unit.shared_by"] = rng.choice([1, 1, 2, 4])
    if rng.random() < 0.3:
        c["dram.model"] = "command"
    if rng.random() < 0.25:  # write traffic: a short stack that spills, hit records
        c["core.short_stack_entries"] = rng.choice([4, 8])
        c["core.hit_record_bytes"] = 16
        c["l2.write_policy"] = rng.choice(["write_back", "write_through"])
    if rng.random() < 0.3:  # hardware prefetchers
        c["l1.prefetcher"] = rng.choice(["next_line", "next_line", "stride", "none"])
        c["l2.prefetcher"] = rng.choice(["next_line", "stride", "none"])
        c["l1.prefetch_degree"] = rng.choice([1, 2, 4])
        c["l2.prefetch_degree"] = rng.choice([1, 2, 4])
    mode = rng.choices(["independent", "treelet", "packet"], weights=[6, 2, 2])[0]
    if mode == "treelet":
        c["traversal.mode"] = "treelet"
        c["bvh.width"] = 4
        c["bvh.treelet_bytes"] = 8192
        c["traversal.treelet_prefetch"] = rng.choice([True, False])
        c.pop("core.short_stack_entries", None)
    elif mode == "packet":
        c["traversal.mode"] = "packet"
        c["bvh.width"] = 4
        c["traversal.packet_size"] = rng.choice([4, 8, 16])
    else:
        c["bvh.width"] = rng.choice([2, 4, 8])
    if path_rng is not None:  # blocks in the memory path, drawn apart (the rest stays as seeded)
        for position in ("below_l1", "below_l2"):
            if path_rng.random() < 0.2:
                c[f"memory_path.{position}"] = "stream_buffer"
                c["memory_path.stream_buffer.entries"] = path_rng.choice([4, 8, 16])
                c["memory_path.stream_buffer.depth"] = path_rng.choice([1, 2, 4])
    if cache_rng is not None:  # a cache level of its own where no stream buffer is (a stream apart)
        for position in ("below_l1", "below_l2"):
            if cache_rng.random() < 0.15 and f"memory_path.{position}" not in c:
                c[f"memory_path.{position}"] = "cache"
                c["memory_path.cache.size_kib"] = cache_rng.choice([16, 64, 256, 1024])
                c["memory_path.cache.ways"] = cache_rng.choice([4, 8, 16])
                c["memory_path.cache.mshrs"] = cache_rng.choice([4, 16, 64])
    sets = []
    for k, v in c.items():
        sets += ["--set", f"{k}={json.dumps(v) if isinstance(v, bool) else v}"]
    label = (f"{cores}x{slots} l1m{c['l1.mshrs']} l2m{c['l2.mshrs']} "
             f"xb{c['crossbar.bytes_per_cycle']} w{c['bvh.width']} {mode}"
             f"{'+load' if c.get('traversal.treelet_prefetch') else ''}"
             f"{' cmd' if 'dram.model' in c else ''}{' wr' if 'core.hit_record_bytes' in c else ''}"
             f"{' pf' if 'l1.prefetcher' in c else ''}"
             f"{path_label(c)}")
    return sets, label, c


def path_label(c):
    """The memory-path blocks of a config, for its label: sb1/sb2 (a stream buffer below the
    L1s/the L2), l15/l3 (a cache level)."""
    names = {("below_l1", "stream_buffer"): " sb1", ("below_l2", "stream_buffer"): " sb2",
             ("below_l1", "cache"): " l15", ("below_l2", "cache"): " l3"}
    return "".join(names[(p, c[f"memory_path.{p}"])] for p in ("below_l1", "below_l2")
                   if f"memory_path.{p}" in c)


def config_loads(rtsim, sets):
    return subprocess.run([rtsim, "config"] + sets, capture_output=True, text=True).returncode == 0


def fast_check(stats):
    """The fast run's judgement of itself (stats.json fidelity_check), if it made one."""
    fc = stats.get("fidelity_check")
    if not fc:
        return {"flagged": False, "expected_error_pct": None}
    return {"flagged": bool(fc.get("flagged")), "expected_error_pct": fc.get("expected_error_pct"),
            "regimes": [r["name"] for r in fc.get("regimes", [])]}


def predictors(s):
    """What the fast run sees of itself: shares of requests served out of time order, queueing
    and stall shares (kept with every cell, for studying what predicts the error)."""
    c = s["counters"]
    ooo = s.get("out_of_order", {})

    def ratio(a, b):
        return a / b if b else 0.0
    p = {"l2_lookup_ooo": ratio(ooo.get("l2_lookups", 0), c.get("l2.accesses", 0)),
         "l2_mshr_ooo": ratio(ooo.get("l2_mshr_requests", 0), c.get("l2.misses", 0)),
         "dram_ooo": ratio(ooo.get("dram_requests", 0),
                           c.get("dram.reads", 0) + c.get("dram.writes", 0)),
         "crossbar_busy": ratio(c.get("crossbar.busy_cycles", 0), s["total_cycles"]),
         "l1_mshr_wait_per_miss": ratio(sum(v for k, v in c.items() if k.startswith("l1[")
                                            and k.endswith(".mshr_wait_cycles")),
                                        sum(v for k, v in c.items() if k.startswith("l1[")
                                            and k.endswith(".misses"))),
         "l2_mshr_wait_per_miss": ratio(c.get("l2.mshr_wait_cycles", 0), c.get("l2.misses", 0))}
    for cause, share in s["stalls"]["total"]["share"].items():
        p["stall_" + cause] = share
    return p


def random_main(a):
    import random
    seed = a.seed if a.seed is not None else random.SystemRandom().randrange(1, 10**6)
    if seed == TUNING_SEED:
        print(f"bench_fidelity: seed {seed} is the tuning seed: its figures are not an "
              f"evaluation", file=sys.stderr)
    rng = random.Random(seed)
    path_rng = random.Random(seed * 1000003 + 7)
    cache_rng = random.Random(seed * 1000003 + 11)
    print(f"bench_fidelity: --random {a.random} --seed {seed}", file=sys.stderr)
    scenes = TUNED_SCENES + HELD_OUT_SCENES
    for n in scenes:
        if not SCENES[n].startswith("builtin:") and not os.path.exists(SCENES[n]):
            sys.exit(f"bench_fidelity: {SCENES[n]}: scene file not found (scripts/setup.sh fetches it)")
    tmp = tempfile.mkdtemp(prefix="bench_fidelity_random_")
    cells = []
    while len(cells) < a.random:
        sets, label, c = draw_config(rng, path_rng, cache_rng)
        scene = rng.choice(scenes)
        kind = rng.choice(list(RANDOM_KINDS))
        if not config_loads(a.rtsim, sets):
            continue
        # Enough rays to fill the chip's slots many times: about 24 per slot, 48 to 256 a side.
        side = max(48, min(a.max_side, int(math.sqrt(a.pixels_per_slot * c["core.count"] *
                                                       c["core.ray_slots"]))))
        side = (side + 7) // 8 * 8
        base = ["--scene", SCENES[scene], "--res", f"{side}x{side}"] + RANDOM_KINDS[kind] + sets
        cells.append({"scene": scene, "held_out": scene in HELD_OUT_SCENES, "kind": kind,
                      "label": label, "config": c, "res": side, "args": base})
    jobs = {}
    for i, cell in enumerate(cells):
        jobs[(i, "accurate")] = cell["args"] + ["--set", "sim.fidelity=accurate"]
        jobs[(i, "fast")] = cell["args"]
    results = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.j) as pool:
        futures = {pool.submit(run_stats, a.rtsim, args, os.path.join(tmp, f"{i}_{f}"),
                               "bench_fidelity"): (i, f) for (i, f), args in jobs.items()}
        for done, fut in enumerate(concurrent.futures.as_completed(futures), 1):
            results[futures[fut]] = fut.result()
            if done % 100 == 0:
                print(f"bench_fidelity: {done}/{len(jobs)} runs", file=sys.stderr)
    for i, cell in enumerate(cells):
        ref, fast = results[(i, "accurate")], results[(i, "fast")]
        cell["accurate"] = figures(ref)
        cell["fast"] = figures(fast)
        cell["error"] = compare(cell["fast"], cell["accurate"])
        cell["predictors"] = predictors(fast)
        cell["check"] = fast_check(fast)
        del cell["args"]
    text = random_report(seed, cells)
    print(text)
    write_results(a.out, "fidelity_random", text, {"seed": seed, "cells": cells})


def within_target(x):
    return (abs(x["error"]["cycles_pct"]) <= TARGET_PERCENT
            and abs(x["error"]["dram_bytes_pct"]) <= TARGET_PERCENT)


def random_report(seed, cells):
    errs = [abs(x["error"]["cycles_pct"]) for x in cells]

    def q(v, p):
        v = sorted(v)
        return v[min(len(v) - 1, int(p * len(v)))]
    n = len(cells)
    ok = sum(1 for x in cells if within_target(x))
    flagged = sum(1 for x in cells if x["check"]["flagged"])
    missed = sum(1 for x in cells if not within_target(x) and not x["check"]["flagged"])
    flagged_ok = sum(1 for x in cells if within_target(x) and x["check"]["flagged"])

    def err(x):
        return max(abs(x["error"]["cycles_pct"]), abs(x["error"]["dram_bytes_pct"]))
    bounded = [x for x in cells if x["check"]["expected_error_pct"] is not None]
    in_bound = sum(1 for x in bounded if err(x) <= x["check"]["expected_error_pct"])
    lines = ["# Fast engine against the accurate one on random configs", "",
             f"`scripts/bench_fidelity.py --random {n} --seed {seed}`: each cell a config drawn "
             f"from the schema's ranges, a mesh ({', '.join(TUNED_SCENES)}; never used by the "
             f"fixed matrix: {', '.join(HELD_OUT_SCENES)}) and a ray kind; square frames of about "
             f"24 rays per ray slot (48 to 256 pixels a side). Error: the fast engine's cycles "
             f"and DRAM bytes against the accurate engine's on the same config and rays. The "
             f"regimes a fast run flags itself in (sim/fidelity_check.h) and their bounds were "
             f"set on the tuning seed {TUNING_SEED}; report on another seed.", "",
             "| cells | within 1% (cycles and DRAM) | flagged by the run | over 1%, not flagged "
             "| flagged, within 1% | mean abs cycles % | median | 90th pct | worst |",
             "|" + "---|" * 9,
             f"| {n} | {ok} ({100 * ok / n:.0f}%) | {flagged} ({100 * flagged / n:.0f}%) | "
             f"{missed} | {flagged_ok} | {statistics.mean(errs):.2f} | {q(errs, 0.5):.2f} | "
             f"{q(errs, 0.9):.2f} | {max(errs):.2f} |", "",
             f"Within the error the run stated for itself (stats.json "
             f"fidelity_check.expected_error_pct, the larger of cycles and DRAM bytes): "
             f"{in_bound} of {len(bounded)} cells.", ""]
    for name, sel in (("tuned meshes", [x for x in cells if not x["held_out"]]),
                      ("held-out meshes", [x for x in cells if x["held_out"]])):
        if sel:
            e = [abs(x["error"]["cycles_pct"]) for x in sel]
            lines.append(f"- {name}: {len(sel)} cells, {sum(1 for x in sel if within_target(x))} "
                         f"within 1%, mean abs cycles error {statistics.mean(e):.2f}%, worst "
                         f"{max(e):.2f}%")
    lines += ["", "| abs cycles error | cells |", "|---|---|"]
    edges = [0, 0.25, 0.5, 1, 2, 5, 10, float("inf")]
    for lo, hi in zip(edges, edges[1:]):
        lines.append(f"| {lo:g}-{hi:g}% | {sum(1 for v in errs if lo <= v < hi)} |")
    lines += ["", "Mean abs cycles error by one field of the config (cells; mean; worst):", ""]
    for key in ("core.count", "l1.mshrs", "bvh.width", "dram.model", "traversal.mode"):
        groups = {}
        for x in cells:
            groups.setdefault(str(x["config"].get(key, "default")), []).append(
                abs(x["error"]["cycles_pct"]))
        parts = [f"{k}: {len(v)}; {statistics.mean(v):.1f}%; {max(v):.1f}%"
                 for k, v in sorted(groups.items())]
        lines.append(f"- `{key}`: " + " | ".join(parts))
    lines += ["", f"## Cells over 1% ({n - ok})", "",
              "| scene | kind | config | cycles % | DRAM % | flagged | expected % |",
              "|" + "---|" * 7]
    for x in sorted([x for x in cells if not within_target(x)],
                    key=lambda x: -abs(x["error"]["cycles_pct"])):
        ex = x["check"]["expected_error_pct"]
        lines.append(f"| {x['scene']} | {x['kind']} | {x['label']} | "
                     f"{x['error']['cycles_pct']:+.2f} | {x['error']['dram_bytes_pct']:+.2f} | "
                     f"{'yes' if x['check']['flagged'] else 'no'} | "
                     f"{'' if ex is None else f'{ex:.1f}'} |")
    return "\n".join(lines) + "\n"


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
    ap.add_argument("--random", type=int, default=0, help="N cells drawn at random (see above)")
    ap.add_argument("--seed", type=int, default=None, help="--random's seed (default: drawn)")
    ap.add_argument("--pixels-per-slot", type=int, default=24,
                    help="--random: pixels per ray slot of each cell's square frame")
    ap.add_argument("--max-side", type=int, default=256,
                    help="--random: the largest frame side in pixels")
    a = ap.parse_args()
    if a.random:
        return random_main(a)
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

#!/usr/bin/env python3
"""Reduced-precision box units against fp32: the extra work they cost and its timing effect.

For each scene x ray kind x node format (full, compressed) x box datapath width
(box_unit.mantissa_bits: 23 is fp32; 16; 10, fp16's mantissa; 7, bfloat16's; 5) x origin
translation (box_unit.translate_origin: distances from the node's entry point, or from the
ray's origin), runs

  * `rtsim trace` for the functional work: nodes, box tests (child boxes) and triangle tests
    per ray, and the hits (--hits-bin), which are compared ray by ray with the fp32 run of the
    same format: conservative rounding may add work but must never change a hit (a differing
    hit is counted as a mismatch; the target is 0);
  * `rtsim run` for the timing: total cycles, and the bytes the traversal fetches per ray (L1
    requested bytes) and moves from DRAM.

Every figure is reported against the fp32 run of the same scene, kind and node format (Koskela
et al. 2015 report +2.5% box tests and +15% triangle tests for half-precision nodes). Writes
bench/results/reduced_precision.{md,json} and prints the summary.

    scripts/bench_precision.py [--rtsim build/rtsim] [--res 128x128] [--width 4]
                               [--scenes a,b] [--kinds primary,ao,diffuse] [--bits 23,16,10,7,5]
                               [-j 2] [--out bench/results]
"""
import argparse
import concurrent.futures
import itertools
import os
import re
import statistics
import struct
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import SCENES, run_stats, write_results  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PRECISION_SCENES = "cornell,bunny,armadillo,elephant,homer,turbine"
WORK = re.compile(r"work\s+([\d.]+) nodes, ([\d.]+) box tests, ([\d.]+) triangle tests per ray")


def datapath(fmt, bits, translate, width):
    return ["--set", f"bvh.width={width}", "--set", f"bvh.node_format={fmt}", "--set",
            f"box_unit.mantissa_bits={bits}", "--set",
            f"box_unit.translate_origin={'true' if translate else 'false'}"]


def trace(rtsim, scene, kind, sets, res, hits):
    cmd = [rtsim, "trace", "--scene", scene, "--rays", kind, "--res", res] + sets + [
        "--hits-bin", hits, "-j", "1"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"bench_precision: {' '.join(cmd)} failed: {r.stderr.strip()}")
    m = WORK.search(r.stdout)
    if not m:
        sys.exit(f"bench_precision: no work line in the output of {' '.join(cmd)}")
    return {"nodes": float(m.group(1)), "box_tests": float(m.group(2)),
            "tri_tests": float(m.group(3))}


def cell(args, tmp, scene_name, kind, fmt, bits, translate):
    scene = SCENES[scene_name]
    tag = f"{scene_name}-{kind}-{fmt}-{bits}-{int(translate)}"
    hits = os.path.join(tmp, tag + ".hits")
    sets = datapath(fmt, bits, translate, args.width)
    out = trace(args.rtsim, scene, kind, sets, args.res, hits)
    s = run_stats(args.rtsim, ["--scene", scene, "--rays", kind, "--res", args.res] + sets,
                  os.path.join(tmp, tag), "bench_precision")
    rays = s["rays"]["total"]
    out.update({"scene": scene_name, "kind": kind, "format": fmt, "bits": bits,
                "translate": translate, "rays": rays,
                "hits_file": hits, "cycles": s["total_cycles"],
                "l1_bytes_per_ray": s["bandwidth"]["l1"]["bytes"] / rays,
                "dram_bytes_per_ray": s["bandwidth"]["dram"]["bytes"] / rays,
                "hits": sum(s["rays"]["hits_by_kind"].values())})
    return out


# Occlusion queries stop at the first hit found: a different traversal order may find a
# different occluder, which is as right as the first. Their answer is hit or miss.
ANY_HIT_KINDS = ("ao", "shadow")


def compare_hits(path, ref_path, any_hit):
    """Rays whose answer differs from the reference run's (records of uint32 ray, float t,
    int32 prim, float u, float v): for closest-hit rays the hit itself (t, primitive, u, v), for
    any-hit rays whether they hit. Also returns how many any-hit rays found another occluder."""
    rec = struct.Struct("<Ififf")
    with open(path, "rb") as f, open(ref_path, "rb") as g:
        a, b = f.read(), g.read()
    if len(a) != len(b):
        return -1, 0
    mismatches = other = 0
    for x, y in zip(rec.iter_unpack(a), rec.iter_unpack(b)):
        if x == y:
            continue
        if any_hit and (x[2] >= 0) == (y[2] >= 0):
            other += 1
        else:
            mismatches += 1
    return mismatches, other


def pct(a, b):
    return 100.0 * (a - b) / b if b else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--res", default="128x128")
    ap.add_argument("--width", type=int, default=4)
    ap.add_argument("--scenes", default=PRECISION_SCENES)
    ap.add_argument("--kinds", default="primary,ao,diffuse")
    ap.add_argument("--bits", default="23,16,10,7,5")
    ap.add_argument("-j", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    args = ap.parse_args()
    scenes, kinds = args.scenes.split(","), args.kinds.split(",")
    bits_list = [int(b) for b in args.bits.split(",")]
    if 23 not in bits_list:
        sys.exit("bench_precision: --bits must include 23, the fp32 reference")
    for s in scenes:
        if s not in SCENES:
            sys.exit(f"bench_precision: unknown scene {s} (known: {', '.join(SCENES)})")
    with tempfile.TemporaryDirectory() as tmp:
        # fp32 once (translation applies only to reduced datapaths), the others both ways.
        jobs = [(sc, k, f, b, t) for sc in scenes for k in kinds for f in ("full", "compressed")
                for b in bits_list for t in ((True,) if b == 23 else (True, False))]
        with concurrent.futures.ThreadPoolExecutor(args.j) as pool:
            cells = list(pool.map(lambda j: cell(args, tmp, *j), jobs))
        by_key = {(c["scene"], c["kind"], c["format"], c["bits"]): c for c in cells
                  if c["bits"] == 23}
        for c in cells:
            ref = by_key[(c["scene"], c["kind"], c["format"], 23)]
            c["hit_mismatches"], c["other_occluder"] = compare_hits(
                c["hits_file"], ref["hits_file"], any_hit=c["kind"] in ANY_HIT_KINDS)
            for k in ("nodes", "box_tests", "tri_tests", "l1_bytes_per_ray",
                      "dram_bytes_per_ray", "cycles"):
                c[k + "_pct"] = pct(c[k], ref[k])
        for c in cells:
            del c["hits_file"]

    lines = [f"# Reduced-precision box units against fp32 (scripts/bench_precision.py)", "",
             f"BVH{args.width}, SAH, {args.res} rays per kind, config baseline (8 cores, one "
             "box and one triangle unit each). Per cell the change against the fp32 "
             "(mantissa_bits = 23) run of the same scene, kind and node format. 'mismatch': "
             "rays whose hit (t, primitive, u, v) differs from fp32; conservative rounding must "
             "keep it at 0 (for AO rays, occlusion queries, the answer is hit or miss: another "
             "occluder found first is not a mismatch). 'origin': distances from the node's entry point (node, "
             "box_unit.translate_origin = true) or from the ray's origin (ray).", ""]
    lines += ["## Mean over scenes", "",
              "| format | bits | origin | kind | nodes | box tests | tri tests | L1 bytes | "
              "DRAM bytes | cycles | mismatches |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for f, b, t, k in itertools.product(("full", "compressed"), bits_list, (True, False), kinds):
        if b == 23:
            continue
        cs = [c for c in cells
              if (c["format"], c["bits"], c["translate"], c["kind"]) == (f, b, t, k)]
        mean = {x: statistics.mean(c[x + "_pct"] for c in cs)
                for x in ("nodes", "box_tests", "tri_tests", "l1_bytes_per_ray",
                          "dram_bytes_per_ray", "cycles")}
        lines.append(
            f"| {f} | {b} | {'node' if t else 'ray'} | {k} | {mean['nodes']:+.2f}% | "
            f"{mean['box_tests']:+.2f}% | {mean['tri_tests']:+.2f}% | "
            f"{mean['l1_bytes_per_ray']:+.2f}% | {mean['dram_bytes_per_ray']:+.2f}% | "
            f"{mean['cycles']:+.2f}% | {sum(c['hit_mismatches'] for c in cs)} |")
    lines += ["", "## Every cell", "",
              "| scene | kind | format | bits | origin | box tests/ray | tri tests/ray | "
              "L1 B/ray | DRAM B/ray | cycles | mismatches |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in cells:
        lines.append(
            f"| {c['scene']} | {c['kind']} | {c['format']} | {c['bits']} | "
            f"{'node' if c['translate'] else 'ray'} | "
            f"{c['box_tests']:.2f} ({c['box_tests_pct']:+.1f}%) | "
            f"{c['tri_tests']:.2f} ({c['tri_tests_pct']:+.1f}%) | "
            f"{c['l1_bytes_per_ray']:.0f} ({c['l1_bytes_per_ray_pct']:+.1f}%) | "
            f"{c['dram_bytes_per_ray']:.1f} ({c['dram_bytes_per_ray_pct']:+.1f}%) | "
            f"{c['cycles']} ({c['cycles_pct']:+.1f}%) | {c['hit_mismatches']} |")
    text = "\n".join(lines) + "\n"
    write_results(args.out, "reduced_precision", text,
                  {"res": args.res, "width": args.width, "cells": cells})
    print("\n".join(lines[:lines.index("## Every cell")]))
    if any(c["hit_mismatches"] != 0 for c in cells):
        sys.exit("bench_precision: some reduced-precision run changed a hit")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Sampled simulation (sim.fidelity = sampled) against the full run of the same frame.

For each scene x sampling period, and each of --seeds workload seeds (each seed is another frame:
other AO and diffuse directions, and another first measured unit), runs the frame in full (the
fast model) and sampled, and reports per cell:
  * the error of the estimated total cycles and DRAM bytes against the full run (mean and worst
    absolute percent);
  * the mean half-width of their 95% intervals, and their coverage: the share of seeds whose
    interval holds the full run's figure (nominal 95%);
  * the share of rays run in detail and the host-time ratio full / sampled (host.run_time_s and
    host.simulation_s, on this machine, in this run).
Writes bench/results/sampled.{md,json} and prints the summary.

    scripts/bench_sampled.py [--rtsim build/rtsim] [--res 256x256] [--rays primary,ao,diffuse]
                             [--scenes bunny,armadillo,cornell] [--periods 5,10,20]
                             [--seeds 30] [-j 2] [--out bench/results]
"""
import argparse
import concurrent.futures
import os
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import ROOT, SCENES, run_stats, write_results  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--res", default="256x256")
    ap.add_argument("--rays", default="primary,ao,diffuse")
    ap.add_argument("--scenes", default="bunny,armadillo,cornell")
    ap.add_argument("--periods", default="5,10,20")
    ap.add_argument("--unit-rays", type=int, default=1024)
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--set", action="append", default=[],
                    help="KEY=VALUE config override for the sampled runs (repeatable)")
    ap.add_argument("-j", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    args = ap.parse_args()
    scenes = args.scenes.split(",")
    periods = [int(p) for p in args.periods.split(",")]
    for s in scenes:
        if s not in SCENES:
            sys.exit(f"bench_sampled: unknown scene {s} (known: {', '.join(SCENES)})")

    def frame(scene, seed):
        return ["--scene", SCENES[scene], "--rays", args.rays, "--res", args.res, "--seed",
                str(seed), "--bvh-cache", os.path.join(tmp, "bvh")]

    def full(job):
        scene, seed = job
        return run_stats(args.rtsim, frame(scene, seed),
                         os.path.join(tmp, f"full-{scene}-{seed}"), "bench_sampled")

    def sampled(job):
        scene, period, seed = job
        return run_stats(args.rtsim, frame(scene, seed) + [
            "--set", "sim.fidelity=sampled", "--set", f"sim.sample_period_units={period}",
            "--set", f"sim.sample_unit_rays={args.unit_rays}"] +
            [a for kv in args.set for a in ("--set", kv)],
            os.path.join(tmp, f"s-{scene}-{period}-{seed}"), "bench_sampled")

    seeds = range(1, args.seeds + 1)
    with tempfile.TemporaryDirectory() as tmp:
        with concurrent.futures.ThreadPoolExecutor(args.j) as pool:
            full_jobs = [(sc, s) for sc in scenes for s in seeds]
            fulls = dict(zip(full_jobs, pool.map(full, full_jobs)))
            s_jobs = [(sc, p, s) for sc in scenes for p in periods for s in seeds]
            samples = dict(zip(s_jobs, pool.map(sampled, s_jobs)))

    cells = []
    for sc in scenes:
        for p in periods:
            rows = []
            for s in seeds:
                f, sm = fulls[(sc, s)], samples[(sc, p, s)]["sampling"]
                h_f, h_s = fulls[(sc, s)]["host"], samples[(sc, p, s)]["host"]
                if "total_cycles" not in sm:
                    sys.exit(f"bench_sampled: {sc} period {p} seed {s}: {sm.get('note')}")
                row = {"seed": s, "detailed_share": sm["detailed_share"],
                       "units_measured": sm["units_measured"],
                       "run_ratio": h_f["run_time_s"] / h_s["run_time_s"],
                       "sim_ratio": h_f["simulation_s"] / h_s["simulation_s"]}
                for name, truth, est in (
                        ("cycles", f["total_cycles"], sm["total_cycles"]),
                        ("dram_bytes", f["counters"]["dram.bytes"],
                         sm["counters"].get("dram.bytes"))):
                    row[name] = {"truth": truth, "value": est["value"],
                                 "error_pct": 100.0 * (est["value"] - truth) / truth,
                                 "half_width_pct": est["half_width_pct"],
                                 "covered": est["lo"] <= truth <= est["hi"]}
                rows.append(row)
            cell = {"scene": sc, "period": p, "rows": rows}
            for name in ("cycles", "dram_bytes"):
                errs = [abs(r[name]["error_pct"]) for r in rows]
                cell[name] = {
                    "mean_abs_error_pct": statistics.mean(errs),
                    "max_abs_error_pct": max(errs),
                    "mean_error_pct": statistics.mean(r[name]["error_pct"] for r in rows),
                    "mean_half_width_pct": statistics.mean(r[name]["half_width_pct"]
                                                           for r in rows),
                    "coverage": sum(r[name]["covered"] for r in rows) / len(rows)}
            cell["detailed_share"] = statistics.mean(r["detailed_share"] for r in rows)
            cell["run_ratio"] = statistics.mean(r["run_ratio"] for r in rows)
            cell["sim_ratio"] = statistics.mean(r["sim_ratio"] for r in rows)
            cells.append(cell)

    lines = ["# Sampled simulation against the full run (scripts/bench_sampled.py)", "",
             f"{args.res}, rays {args.rays}, units of {args.unit_rays} rays, "
             f"{args.seeds} seeds per cell (each seed another frame, compared with its own full "
             "run). Errors and half-widths in percent of the full run; coverage: the share of "
             "seeds whose 95% interval holds the full run's figure. Host ratios: full / sampled "
             "host seconds (whole run; simulation only), on this shared machine.", "",
             "| scene | period | detailed | cycles mean abs err | max | mean err | half-width "
             "| coverage | DRAM mean abs err | max | half-width | coverage | run x | sim x |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in cells:
        cy, dr = c["cycles"], c["dram_bytes"]
        lines.append(
            f"| {c['scene']} | {c['period']} | {100 * c['detailed_share']:.1f}% | "
            f"{cy['mean_abs_error_pct']:.2f}% | {cy['max_abs_error_pct']:.2f}% | "
            f"{cy['mean_error_pct']:+.2f}% | {cy['mean_half_width_pct']:.2f}% | "
            f"{100 * cy['coverage']:.0f}% | {dr['mean_abs_error_pct']:.2f}% | "
            f"{dr['max_abs_error_pct']:.2f}% | {dr['mean_half_width_pct']:.2f}% | "
            f"{100 * dr['coverage']:.0f}% | {c['run_ratio']:.2f} | {c['sim_ratio']:.2f} |")
    text = "\n".join(lines) + "\n"
    write_results(args.out, "sampled", text, {"res": args.res, "rays": args.rays,
                                              "unit_rays": args.unit_rays, "cells": cells})
    print(text)


if __name__ == "__main__":
    main()

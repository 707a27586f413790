#!/usr/bin/env python3
"""The command-level DRAM model (rtsim dram) against DRAMsim3 on the same memory traces.

DRAMsim3 is not part of RTSim: build it from its public repository (umd-memsys/DRAMsim3) and
pass its binary and a device config. Both simulators read the same .ini (rtsim through its
importer) and the same traces in DRAMsim3's format:
  * stream: sequential 64-byte reads, one every 2 cycles (saturating);
  * random: uniform random addresses, 30% writes, one every 4 cycles;
  * rtsim-<scene>: the requests an RTSim run sent to DRAM (rtsim run --mem-trace), on the
    DDR4-3200 preset's clock; rtsim-<scene>-writes: the same with the traversal's own writes
    (configs/write_traffic.json, a 128 KiB L2), so READ and WRITE lines mix.
Reported per trace: cycles until the last request completed (DRAMsim3's found by bisection on
its -c), read latency, row hits, ACT and REF commands, energy. Writes
bench/results/dram_vs_dramsim3.{md,json}.

    scripts/compare_dramsim3.py --dramsim3 /path/to/dramsim3main --ini /path/to/DDR4_8Gb_x8_3200.ini
        [--rtsim build/rtsim] [--requests 50000] [--out bench/results]
"""
import argparse
import json
import os
import random
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import ROOT, SCENES, write_results  # noqa: E402


def dramsim3(binary, ini, trace, cycles, out):
    os.makedirs(out, exist_ok=True)
    subprocess.run([binary, ini, "-c", str(cycles), "-t", trace, "-o", out], check=True,
                   capture_output=True)
    with open(os.path.join(out, "dramsim3.json")) as f:
        stats = json.load(f)
    # One entry per channel; sum the counts, average the latency weighted by reads.
    chans = list(stats.values())
    total = {}
    for k in ("num_reads_done", "num_writes_done", "num_act_cmds", "num_ref_cmds",
              "num_read_row_hits", "num_write_row_hits", "num_read_cmds", "num_write_cmds",
              "total_energy", "act_energy", "read_energy", "write_energy", "ref_energy"):
        total[k] = sum(float(c.get(k, 0)) for c in chans)
    reads = total["num_reads_done"]
    total["average_read_latency"] = (sum(float(c["average_read_latency"]) * float(
        c["num_reads_done"]) for c in chans) / reads) if reads else 0.0
    return total


def finish_cycles(binary, ini, trace, n, tmp):
    """The fewest cycles after which DRAMsim3 has completed all n requests (bisection)."""
    lo, hi = 1, 1024
    while True:
        s = dramsim3(binary, ini, trace, hi, os.path.join(tmp, "d3"))
        if s["num_reads_done"] + s["num_writes_done"] >= n:
            break
        lo, hi = hi, hi * 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        s = dramsim3(binary, ini, trace, mid, os.path.join(tmp, "d3"))
        if s["num_reads_done"] + s["num_writes_done"] >= n:
            hi = mid
        else:
            lo = mid
    return hi, dramsim3(binary, ini, trace, hi, os.path.join(tmp, "d3"))


def compare_trace(rtsim, binary, ini, trace, tmp):
    """One trace through `rtsim dram` and DRAMsim3 with the same device file: each one's cycles
    until the last request completed, read latency, row hit rate, ACT and REF counts, energy."""
    with open(trace) as f:
        n = sum(1 for line in f if line.strip())
    out = os.path.join(tmp, "rt-" + os.path.basename(trace))
    subprocess.run([rtsim, "dram", "-q", trace, "--device", ini, "-o", out], check=True)
    with open(os.path.join(out, "stats.json")) as f:
        r = json.load(f)
    cycles, d = finish_cycles(binary, ini, trace, n, tmp)
    d_hits = d["num_read_row_hits"] + d["num_write_row_hits"]
    d_cols = d["num_read_cmds"] + d["num_write_cmds"]
    return {
        "requests": n,
        "rtsim": {"cycles": r["cycles"], "read_latency": r["read_latency_cycles"]["mean"],
                  "row_hit_rate": r["row_hit_rate"], "act": r["commands"]["act"],
                  "ref": r["commands"]["ref"], "energy_nj": r["energy_pj"]["total"] / 1e3},
        # DRAMsim3 sums VDD x IDD x cycles and calls it pJ (its comment: "if we convert cycles
        # to ns then it's exactly pJ"), never multiplying by tCK: in pJ its figures are tCK
        # times what it prints.
        "dramsim3": {"cycles": cycles, "read_latency": d["average_read_latency"],
                     "row_hit_rate": d_hits / d_cols if d_cols else 0.0,
                     "act": d["num_act_cmds"], "ref": d["num_ref_cmds"],
                     "energy_printed": d["total_energy"] / 1e3,
                     "energy_nj": d["total_energy"] * r["device"]["tck_ns"] / 1e3}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dramsim3", required=True, help="DRAMsim3's dramsim3main binary")
    ap.add_argument("--ini", required=True, help="a DRAMsim3 device config, e.g. DDR4_8Gb_x8_3200.ini")
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--requests", type=int, default=50000)
    ap.add_argument("--scenes", default="cornell,bunny")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        traces = {}
        rng = random.Random(1)
        p = os.path.join(tmp, "stream.trace")
        with open(p, "w") as f:
            for i in range(args.requests):
                f.write(f"0x{i * 64:x} READ {2 * i}\n")
        traces["stream"] = p
        p = os.path.join(tmp, "random.trace")
        with open(p, "w") as f:
            for i in range(args.requests):
                op = "WRITE" if rng.random() < 0.3 else "READ"
                f.write(f"0x{rng.randrange(1 << 32) & ~63:x} {op} {4 * i}\n")
        traces["random"] = p
        for scene in args.scenes.split(","):
            # Reads only (BVH data), and with the traversal's writes (configs/write_traffic.json:
            # spilled stacks and hit records; a 128 KiB L2 writes dirty lines back in the frame).
            for tag, extra in (("", []),
                               ("-writes", ["--config", os.path.join(ROOT, "configs",
                                                                     "write_traffic.json"),
                                            "--set", "l2.size_kib=128"])):
                p = os.path.join(tmp, f"{scene}{tag}.trace")
                subprocess.run([args.rtsim, "run", "-q", "--scene", SCENES[scene], "--res",
                                "256x256", "--rays", "primary,ao", "--set", "dram.model=command",
                                "--mem-trace", p, "-o", os.path.join(tmp, "run-" + scene + tag)]
                               + extra, check=True)
                traces["rtsim-" + scene + tag] = p
        for name, trace in traces.items():
            rows.append(dict(trace=name, **compare_trace(args.rtsim, args.dramsim3, args.ini,
                                                         trace, tmp)))

    def pct(a, b):
        return f"{100.0 * (a - b) / b:+.1f}%" if b else "n/a"

    lines = ["# Command-level DRAM model against DRAMsim3 (scripts/compare_dramsim3.py)", "",
             f"Device: {os.path.basename(args.ini)}, read by both (rtsim through its .ini "
             "importer). Cycles: until the last request completed (DRAMsim3's by bisection on "
             "its cycle count). Differences relative to DRAMsim3. DRAMsim3's energy is its "
             "printed total times tCK: it sums VDD x IDD x cycles without converting cycles to "
             "ns, so what it prints as pJ is 1/tCK times too large.", "",
             "| trace | requests | cycles rtsim | DRAMsim3 | diff | read latency rtsim | DRAMsim3 "
             "| row hits rtsim | DRAMsim3 | ACT rtsim | DRAMsim3 | REF rtsim | DRAMsim3 "
             "| energy nJ rtsim | DRAMsim3 | diff |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        a, b = row["rtsim"], row["dramsim3"]
        lines.append(
            f"| {row['trace']} | {row['requests']} | {a['cycles']} | {b['cycles']} | "
            f"{pct(a['cycles'], b['cycles'])} | {a['read_latency']:.1f} | "
            f"{b['read_latency']:.1f} | {100 * a['row_hit_rate']:.1f}% | "
            f"{100 * b['row_hit_rate']:.1f}% | {a['act']} | {b['act']:.0f} | {a['ref']} | "
            f"{b['ref']:.0f} | {a['energy_nj']:.0f} | {b['energy_nj']:.0f} | "
            f"{pct(a['energy_nj'], b['energy_nj'])} |")
    text = "\n".join(lines) + "\n"
    write_results(args.out, "dram_vs_dramsim3", text, {"ini": args.ini, "rows": rows})
    print(text)


if __name__ == "__main__":
    main()

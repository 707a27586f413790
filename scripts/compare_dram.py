#!/usr/bin/env python3
"""Every memory family against DRAMsim3: one device file per family, light, moderate and
saturating loads, one table.

DRAMsim3 is not part of RTSim: build it from its public repository (umd-memsys/DRAMsim3) and pass
its binary and its configs folder. For each family's device file both simulators read the same
.ini (rtsim through its importer) and run the same traces (DRAMsim3's format, device cycles):
  * random-light: uniform random 64-byte addresses, 25% writes, one request per 40 cycles;
  * random-moderate: the same, one per 10 cycles;
  * random-saturating: the same, one per cycle (the queues fill; completion time matters);
  * stream-light: sequential 64-byte reads, one per 40 cycles;
  * stream-saturating: the same, one per cycle.
The targets: read latency and ACT count within 5% at light load, completion time within 10% at
saturating load. Also counts how many of the folder's device files load at all. Writes
bench/results/dram_standards.md (every row: out/bench/dram_standards.json).

    scripts/compare_dram.py --dramsim3 /path/to/dramsim3main --configs /path/to/DRAMsim3/configs
        [--rtsim build/rtsim] [--requests 15000] [--families DDR3,GDDR6,...] [--out bench/results]
"""
import argparse
import os
import random
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_dramsim3 import compare_trace  # noqa: E402
from rtsim_run import ROOT, write_results  # noqa: E402

# One device file per family, from DRAMsim3's configs folder.
FAMILIES = {"DDR3": "DDR3_8Gb_x8_1600.ini", "DDR4": "DDR4_8Gb_x8_3200.ini",
            "LPDDR3": "LPDDR3_8Gb_x32_1600.ini", "LPDDR4": "LPDDR4_8Gb_x16_2400.ini",
            "GDDR5": "GDDR5_8Gb_x32.ini", "GDDR5X": "GDDR5X_8Gb_x32.ini",
            "GDDR6": "GDDR6_8Gb_x16.ini", "HBM": "HBM_4Gb_x128.ini", "HBM2": "HBM2_8Gb_x128.ini"}
LOADS = {"random-light": ("random", 40), "random-moderate": ("random", 10),
         "random-saturating": ("random", 1), "stream-light": ("stream", 40),
         "stream-saturating": ("stream", 1)}


def write_trace(path, kind, interval, n, seed):
    rng = random.Random(seed)
    with open(path, "w") as f:
        for i in range(n):
            if kind == "stream":
                f.write(f"0x{i * 64:x} READ {interval * i}\n")
            else:
                op = "WRITE" if rng.random() < 0.25 else "READ"
                f.write(f"0x{rng.randrange(1 << 30) & ~63:x} {op} {interval * i}\n")


def pct(a, b):
    return 100.0 * (a - b) / b if b else (0.0 if a == b else float("inf"))


def report(requests, rows, loaded, refused):
    """The summary table (Markdown) of compare_trace rows."""
    def ok_light(r):
        return (abs(pct(r["rtsim"]["read_latency"], r["dramsim3"]["read_latency"])) <= 5
                and abs(pct(r["rtsim"]["act"], r["dramsim3"]["act"])) <= 5)

    def ok_saturating(r):
        return abs(pct(r["rtsim"]["cycles"], r["dramsim3"]["cycles"])) <= 10
    lines = ["# Every memory family against DRAMsim3 (scripts/compare_dram.py)", "",
             f"One DRAMsim3 device file per family, read by both simulators (rtsim through its "
             f".ini importer); {requests} requests per trace, 64-byte, random ones 25% writes; "
             f"loads: one request per 40, 10 and 1 device cycles. Differences relative to "
             f"DRAMsim3. Targets: read latency and ACTs within 5% at light load, completion "
             f"within 10% at saturating load (**bold**: missed).", "",
             f"Device files in DRAMsim3's configs folder: {len(loaded)} of "
             f"{len(loaded) + len(refused)} simulate; refused: "
             + ("; ".join(f"{n} ({why})" for n, why in refused) or "none") + ".", "",
             "| family | device | load | completion | read latency rtsim | DRAMsim3 | diff "
             "| ACT rtsim | DRAMsim3 | diff | REF rtsim | DRAMsim3 | energy diff |",
             "|" + "---|" * 13]
    for r in rows:
        x, d = r["rtsim"], r["dramsim3"]
        light = r["load"].endswith("light")
        sat = r["load"].endswith("saturating")

        def mark(text, bad):
            return f"**{text}**" if bad else text
        lat = pct(x["read_latency"], d["read_latency"])
        act = pct(x["act"], d["act"])
        cyc = pct(x["cycles"], d["cycles"])
        lines.append(
            f"| {r['family']} | {r['device']} | {r['load']} | "
            f"{mark(f'{cyc:+.1f}%', sat and not ok_saturating(r))} | {x['read_latency']:.1f} | "
            f"{d['read_latency']:.1f} | {mark(f'{lat:+.1f}%', light and abs(lat) > 5)} | "
            f"{x['act']} | {d['act']:.0f} | {mark(f'{act:+.1f}%', light and abs(act) > 5)} | "
            f"{x['ref']} | {d['ref']:.0f} | {pct(x['energy_nj'], d['energy_nj']):+.1f}% |")
    light_rows = [r for r in rows if r["load"].endswith("light")]
    sat_rows = [r for r in rows if r["load"].endswith("saturating")]
    lines += ["", f"Light loads within target: {sum(map(ok_light, light_rows))} of "
              f"{len(light_rows)}; saturating loads within target: "
              f"{sum(map(ok_saturating, sat_rows))} of {len(sat_rows)}."]
    text = "\n".join(lines) + "\n"
    return text


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dramsim3", required=True, help="DRAMsim3's dramsim3main binary")
    ap.add_argument("--configs", required=True, help="DRAMsim3's configs folder")
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--requests", type=int, default=15000)
    ap.add_argument("--families", default=",".join(FAMILIES))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    a = ap.parse_args()
    for f in a.families.split(","):
        if f not in FAMILIES:
            sys.exit(f"compare_dram: --families: unknown family {f} (known: {', '.join(FAMILIES)})")
        if not os.path.exists(os.path.join(a.configs, FAMILIES[f])):
            sys.exit(f"compare_dram: {os.path.join(a.configs, FAMILIES[f])}: not found")
    # Which of the folder's device files load (simulate a few requests) or are refused, and why.
    loaded, refused = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tiny = os.path.join(tmp, "tiny.trace")
        write_trace(tiny, "random", 40, 8, 1)
        for name in sorted(os.listdir(a.configs)):
            if not name.endswith(".ini"):
                continue
            r = subprocess.run([a.rtsim, "dram", "-q", tiny, "--device",
                                os.path.join(a.configs, name)], capture_output=True, text=True)
            why = r.stderr.strip().removeprefix("rtsim: error: ")
            (loaded if r.returncode == 0 else refused).append((name, why.split(".ini: ", 1)[-1]))
        rows = []
        for family in a.families.split(","):
            ini = os.path.join(a.configs, FAMILIES[family])
            for load, (kind, interval) in LOADS.items():
                trace = os.path.join(tmp, f"{family}-{load}.trace")
                write_trace(trace, kind, interval, a.requests, 7)
                row = compare_trace(a.rtsim, a.dramsim3, ini, trace, tmp)
                row.update(family=family, device=FAMILIES[family], load=load)
                rows.append(row)
                print(f"compare_dram: {family} {load} done", file=sys.stderr)

    text = report(a.requests, rows, loaded, refused)
    write_results(a.out, "dram_standards", text, {"rows": rows, "loaded": loaded,
                                                  "refused": refused})
    print(text)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Every memory family against a reference simulator: DRAMsim3 for the families it models,
Ramulator 2 for DDR5 and LPDDR5; light, moderate and saturating loads, one table.

Neither reference is part of RTSim: build DRAMsim3 from its public repository (umd-memsys/DRAMsim3)
and pass its binary and its configs folder; build Ramulator 2 (CMU-SAFARI/ramulator2, the last
version with the `ramulator2` executable, whose main loop must accept `-d CYCLES` to keep ticking
the memory after the trace is sent so that every request completes) and pass its binary. For each
DRAMsim3 family's device file both simulators read the same .ini (rtsim through its importer); for
DDR5 and LPDDR5, rtsim's preset is written out as a Ramulator 2 config with the same organisation
and every timing in cycles (matched timings), its RoBaRaCoCh address mapping, open rows, FR-FCFS
and all-bank refresh. Both run the same traces (device cycles):
  * random-light: uniform random 64-byte addresses, 25% writes, one request per 40 cycles;
  * random-moderate: the same, one per 10 cycles;
  * random-saturating: the same, one per cycle (the queues fill; completion time matters);
  * stream-light: sequential 64-byte reads, one per 40 cycles;
  * stream-saturating: the same, one per cycle.
The targets: read latency and ACT count within 5% at light load, completion time within 10% at
saturating load. Also counts how many of the folder's device files load at all. The traces'
addresses come from --seed (drawn at run time when not given, and printed with the table). Writes
bench/results/dram_standards.md (every row: out/bench/dram_standards.json).

    scripts/compare_dram.py --dramsim3 /path/to/dramsim3main --configs /path/to/DRAMsim3/configs
        [--ramulator2 /path/to/ramulator2] [--rtsim build/rtsim] [--requests 15000]
        [--families DDR3,GDDR6,DDR5,...] [--seed S] [--out bench/results]
"""
import argparse
import os
import json
import random
import re
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
# rtsim's own presets checked against Ramulator 2: the preset of Ramulator 2's tables it was taken
# from, for the timings rtsim has no field for.
RAMULATOR2_FAMILIES = {"DDR5": ("DDR5_16Gb_x8_4800", "DDR5_4800AN"),
                       "LPDDR5": ("LPDDR5_8Gb_x16_6400", "LPDDR5_6400")}
# Ramulator 2's channel interleave on the line above the transaction, then RoBaRaCoCh (column,
# rank, bank group, bank, row upwards), in rtsim's most-significant-first notation.
RAMULATOR2_MAPPING = "robabgracoch"
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


def write_loadstore_trace(trace, path):
    """The same requests in Ramulator 2's LoadStoreTrace format (no times: the load comes from the
    clock ratio between its front end and its memory); returns their operations in order."""
    ops = []
    with open(trace) as f, open(path, "w") as out:
        for line in f:
            addr, op, _ = line.split()
            ops.append(op)
            out.write(f"{'ST' if op == 'WRITE' else 'LD'} {addr}\n")
    return ops


def ramulator2_timings(dev):
    """rtsim's device fields under Ramulator 2's timing names (cycles). rtsim has one tCCD per
    bank-group relation for reads and writes alike, so the write tCCDs are set to it; LPDDR5's
    per-bank and all-bank precharge both take rtsim's t_rp."""
    burst = dev["burst_cycles"]
    t = {"nCL": dev["cl"], "nCWL": dev["cwl"], "nRCD": dev["t_rcd"], "nRP": dev["t_rp"],
         "nRAS": dev["t_ras"], "nRC": dev["t_ras"] + dev["t_rp"], "nWR": dev["t_wr"],
         "nRTP": dev["t_rtp"], "nCCDS": dev["t_ccd_s"], "nCCDL": dev["t_ccd_l"],
         "nCCDS_WR": dev["t_ccd_s"], "nCCDL_WR": dev["t_ccd_l"], "nRRDS": dev["t_rrd_s"],
         "nRRDL": dev["t_rrd_l"], "nWTRS": dev["t_wtr_s"], "nWTRL": dev["t_wtr_l"],
         "nFAW": dev["t_faw"], "nRFC": dev["t_rfc"], "nREFI": dev["t_refi"]}
    if dev["protocol"] == "LPDDR5":
        t.update(nBL_min=burst, nRPab=dev["t_rp"])
    else:
        t.update(nBL=burst)
    return t


def ramulator2_org_preset(dev):
    density_gb = (dev["bankgroups"] * dev["banks_per_group"] * dev["rows"] * dev["columns"]
                  * dev["device_width_bits"]) >> 30
    return f"{dev['protocol']}_{density_gb}Gb_x{dev['device_width_bits']}"


def ramulator2_table_differences(ramulator, dev, timing_preset):
    """Where Ramulator 2's own timing table differs from rtsim's preset: {name: (its, rtsim's)}.
    The comparison runs both on rtsim's values; these are the differences it sets aside."""
    _, table = getattr(ramulator.dram, dev["protocol"])(
        org_preset=ramulator2_org_preset(dev), timing_preset=timing_preset).resolve()
    return {k: (table[k], v) for k, v in ramulator2_timings(dev).items()
            if k in table and table[k] != v}


def ramulator2_config(ramulator, dev, timing_preset, trace, interval, out):
    """A Ramulator 2 config (through its Python package) for rtsim's device `dev`: the same
    organisation, every timing rtsim has set to rtsim's value, one controller per channel,
    FR-FCFS, open rows, all-bank refresh, and a command trace. Its front end issues one request
    per front-end tick, so a front end `interval` times slower than the memory gives one request
    per `interval` memory cycles, waiting whenever the controller's queue is full."""
    std = dev["protocol"]
    controllers = []
    for ch in range(dev["channels"]):
        dram = getattr(ramulator.dram, std)(
            org_preset=ramulator2_org_preset(dev), timing_preset=timing_preset,
            rank=dev["ranks"], bankgroup=dev["bankgroups"], bank=dev["banks_per_group"],
            row=dev["rows"], column=dev["columns"], channel_width=dev["bus_width_bits"],
            **ramulator2_timings(dev))
        kind = ramulator.controller.LPDDR5 if std == "LPDDR5" else ramulator.controller.GenericDDR
        controllers.append(kind(
            dram=dram, scheduler=ramulator.scheduler.FRFCFS(),
            refresh_manager=ramulator.refresh_manager.AllBank(),
            row_policy=ramulator.row_policy.Open(), addr_mapper=ramulator.addr_mapper.RoBaRaCoCh(),
            controller_plugins=[ramulator.controller_plugin.CmdTraceRecorder(
                path=os.path.join(out, "cmd"))]))
    memory = ramulator.memory_system.GenericDRAM(
        clock_ratio=interval, channel_mapper=ramulator.channel_mapper.CacheLineInterleave(),
        controllers=controllers)
    frontend = ramulator.frontend.LoadStoreTrace(clock_ratio=1, path=trace)
    return {"frontend": frontend.to_config(), "memory_system": memory.to_config()}


def ramulator2(tools, dev, timing_preset, trace, interval, tmp):
    """Run one trace through Ramulator 2: completion (the last column command's data end), read
    latency, ACT and REF counts up to completion, from its statistics and command trace."""
    ramulator, driver = tools
    out = os.path.join(tmp, "r2-" + os.path.basename(trace))
    os.makedirs(out, exist_ok=True)
    ls = os.path.join(out, "trace.ls")
    ops = write_loadstore_trace(trace, ls)
    cfg = os.path.join(out, "config.json")
    with open(cfg, "w") as f:
        json.dump(ramulator2_config(ramulator, dev, timing_preset, ls, interval, out), f)
    # Ticks after the last request is sent: enough for two full queues and a refresh to drain.
    drain = 64 * 4 * (dev["t_ras"] + dev["t_rp"]) + dev["t_rfc"]
    r = subprocess.run([driver, cfg, str(drain)], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"ramulator2: {trace}: {r.stderr.strip() or r.stdout[-300:]}")
    stat = {}
    for key, value in re.findall(r"^\s*(read_latency|num_read_reqs_served|num_write_reqs_served)"
                                 r": ([-\d.e+]+)$", r.stdout, re.M):
        stat[key] = stat.get(key, 0.0) + float(value)
    if (stat.get("num_read_reqs_served", 0) != ops.count("READ")
            or stat.get("num_write_reqs_served", 0) != ops.count("WRITE")):
        raise RuntimeError(f"ramulator2: {trace}: not every request completed ({stat})")
    burst = dev["burst_cycles"]
    done, cmds = 0, []
    for ch in range(dev["channels"]):
        with open(os.path.join(out, f"cmd.ch{ch}")) as f:
            next(f)  # clock,command,...
            for line in f:
                clk, cmd = line.split(",")[:2]
                cmds.append((int(clk), cmd))
                if cmd in ("RD", "RDA"):
                    done = max(done, int(clk) + dev["cl"] + burst)
                elif cmd in ("WR", "WRA"):
                    done = max(done, int(clk) + dev["cwl"] + burst)
    act = "ACT1" if dev["protocol"] == "LPDDR5" else "ACT"
    return {"cycles": done, "read_latency": stat["read_latency"] / ops.count("READ"),
            "act": sum(1 for c, x in cmds if x == act and c <= done),
            "ref": sum(1 for c, x in cmds if x == "REFab" and c <= done)}


def ramulator2_tools(src, tmp):
    """Ramulator 2's Python package (configs) and this project's driver built against its
    library, from a Ramulator 2 source tree built with its own CMake (libramulator.so at its
    root)."""
    lib = os.path.join(src, "libramulator.so")
    if not os.path.exists(lib):
        sys.exit(f"compare_dram: --ramulator2 {src}: no libramulator.so (build Ramulator 2 first)")
    sys.path.insert(0, os.path.join(src, "python"))
    import ramulator  # noqa: E402  (Ramulator 2's own package, found only at run time)
    driver = os.path.join(tmp, "ramulator2_driver")
    subprocess.run(["g++", "-std=c++20", "-O2", "-I", os.path.join(src, "src"),
                    os.path.join(ROOT, "scripts", "ramulator2_driver.cpp"), "-L", src,
                    "-lramulator", "-lfmt", f"-Wl,-rpath,{os.path.abspath(src)}", "-o", driver],
                   check=True)
    return ramulator, driver


def compare_trace_ramulator2(rtsim, tools, preset, timing_preset, trace, interval, tmp):
    """One trace through `rtsim dram` (its preset, address mapping set to Ramulator 2's) and
    Ramulator 2 (the same device through its config)."""
    with open(os.path.join(ROOT, "configs", "dram", preset + ".json")) as f:
        dev = json.load(f)
    dev["address_mapping"] = RAMULATOR2_MAPPING
    out = os.path.join(tmp, "rt-" + os.path.basename(trace))
    subprocess.run([rtsim, "dram", "-q", trace, "--device", preset, "-o", out, "--set",
                    f"address_mapping={RAMULATOR2_MAPPING}"], check=True)
    with open(os.path.join(out, "stats.json")) as f:
        r = json.load(f)
    with open(trace) as f:
        n = sum(1 for _ in f)
    return {"requests": n,
            "table_differs": ramulator2_table_differences(tools[0], dev, timing_preset),
            "rtsim": {"cycles": r["cycles"], "read_latency": r["read_latency_cycles"]["mean"],
                      "act": r["commands"]["act"], "ref": r["commands"]["ref"],
                      "energy_nj": r["energy_pj"]["total"] / 1e3},
            "reference": ramulator2(tools, dev, timing_preset, trace, interval, tmp)}


def pct(a, b):
    return 100.0 * (a - b) / b if b else (0.0 if a == b else float("inf"))


def report(requests, seed, rows, loaded, refused):
    """The summary table (Markdown) of the comparison rows."""
    def ok_light(r):
        return (abs(pct(r["rtsim"]["read_latency"], r["reference"]["read_latency"])) <= 5
                and abs(pct(r["rtsim"]["act"], r["reference"]["act"])) <= 5)

    def ok_saturating(r):
        return abs(pct(r["rtsim"]["cycles"], r["reference"]["cycles"])) <= 10
    lines = ["# Every memory family against a reference simulator (scripts/compare_dram.py)", "",
             f"DRAMsim3's families: one DRAMsim3 device file per family, read by both simulators "
             f"(rtsim through its .ini importer). DDR5 and LPDDR5: rtsim's preset against "
             f"Ramulator 2 given the same organisation and rtsim's timings in cycles "
             f"(matched; where Ramulator 2's own table differs is listed below). {requests} "
             f"requests per trace, 64-byte, random ones 25% writes, addresses from seed {seed}; "
             f"loads: one request per 40, 10 and 1 "
             f"device cycles. Differences relative to the reference. Targets: read latency and "
             f"ACTs within 5% at light load, completion within 10% at saturating load "
             f"(**bold**: missed). Energy only where the reference computes it (DRAMsim3).", ""]
    if loaded or refused:
        lines += [f"Device files in DRAMsim3's configs folder: {len(loaded)} of "
                  f"{len(loaded) + len(refused)} simulate; refused: "
                  + ("; ".join(f"{n} ({why})" for n, why in refused) or "none") + ".", ""]
    differs = {r["device"]: r["table_differs"] for r in rows if "table_differs" in r}
    for device, diff in differs.items():
        lines.append(f"- {device}: Ramulator 2's table differs in "
                     + (", ".join(f"{k} {a} (rtsim {b})" for k, (a, b) in diff.items())
                        or "nothing") + ".")
    if differs:
        lines.append("")
    lines += ["| family | device | reference | load | completion | read latency rtsim | reference "
              "| diff | ACT rtsim | reference | diff | REF rtsim | reference | energy diff |",
              "|" + "---|" * 14]
    for r in rows:
        x, d = r["rtsim"], r["reference"]
        light = r["load"].endswith("light")
        sat = r["load"].endswith("saturating")

        def mark(text, bad):
            return f"**{text}**" if bad else text
        lat = pct(x["read_latency"], d["read_latency"])
        act = pct(x["act"], d["act"])
        cyc = pct(x["cycles"], d["cycles"])
        energy = (f"{pct(x['energy_nj'], d['energy_nj']):+.1f}%" if "energy_nj" in d
                  else "n/a")
        lines.append(
            f"| {r['family']} | {r['device']} | {r['ref_name']} | {r['load']} | "
            f"{mark(f'{cyc:+.1f}%', sat and not ok_saturating(r))} | {x['read_latency']:.1f} | "
            f"{d['read_latency']:.1f} | {mark(f'{lat:+.1f}%', light and abs(lat) > 5)} | "
            f"{x['act']} | {d['act']:.0f} | {mark(f'{act:+.1f}%', light and abs(act) > 5)} | "
            f"{x['ref']} | {d['ref']:.0f} | {energy} |")
    light_rows = [r for r in rows if r["load"].endswith("light")]
    sat_rows = [r for r in rows if r["load"].endswith("saturating")]
    lines += ["", f"Light loads within target: {sum(map(ok_light, light_rows))} of "
              f"{len(light_rows)}; saturating loads within target: "
              f"{sum(map(ok_saturating, sat_rows))} of {len(sat_rows)}."]
    text = "\n".join(lines) + "\n"
    return text


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dramsim3", help="DRAMsim3's dramsim3main binary")
    ap.add_argument("--configs", help="DRAMsim3's configs folder")
    ap.add_argument("--ramulator2", help="a built Ramulator 2 source tree (DDR5, LPDDR5)")
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--requests", type=int, default=15000)
    ap.add_argument("--families", help="default: every family whose reference is given")
    ap.add_argument("--seed", type=int, help="trace addresses (default: drawn now, printed)")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    a = ap.parse_args()
    if bool(a.dramsim3) != bool(a.configs):
        sys.exit("compare_dram: --dramsim3 and --configs go together")
    if not a.dramsim3 and not a.ramulator2:
        sys.exit("compare_dram: give --dramsim3 and --configs, or --ramulator2, or both")
    default = (list(FAMILIES) if a.dramsim3 else []) + (
        list(RAMULATOR2_FAMILIES) if a.ramulator2 else [])
    families = a.families.split(",") if a.families else default
    for f in families:
        if f in FAMILIES and a.dramsim3:
            if not os.path.exists(os.path.join(a.configs, FAMILIES[f])):
                sys.exit(f"compare_dram: {os.path.join(a.configs, FAMILIES[f])}: not found")
        elif f in RAMULATOR2_FAMILIES and a.ramulator2:
            pass
        elif f in FAMILIES or f in RAMULATOR2_FAMILIES:
            sys.exit(f"compare_dram: --families: {f} needs "
                     + ("--dramsim3 and --configs" if f in FAMILIES else "--ramulator2"))
        else:
            sys.exit(f"compare_dram: --families: unknown family {f} (known: "
                     f"{', '.join(list(FAMILIES) + list(RAMULATOR2_FAMILIES))})")
    seed = a.seed if a.seed is not None else random.SystemRandom().randrange(1, 1 << 20)
    print(f"compare_dram: trace seed {seed}", file=sys.stderr)
    # Which of the folder's device files load (simulate a few requests) or are refused, and why.
    loaded, refused = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tools = ramulator2_tools(a.ramulator2, tmp) if a.ramulator2 else None
        tiny = os.path.join(tmp, "tiny.trace")
        write_trace(tiny, "random", 40, 8, 1)
        for name in sorted(os.listdir(a.configs)) if a.configs else []:
            if not name.endswith(".ini"):
                continue
            r = subprocess.run([a.rtsim, "dram", "-q", tiny, "--device",
                                os.path.join(a.configs, name)], capture_output=True, text=True)
            why = r.stderr.strip().removeprefix("rtsim: error: ")
            (loaded if r.returncode == 0 else refused).append((name, why.split(".ini: ", 1)[-1]))
        rows = []
        for family in families:
            for load, (kind, interval) in LOADS.items():
                trace = os.path.join(tmp, f"{family}-{load}.trace")
                write_trace(trace, kind, interval, a.requests, seed)
                if family in FAMILIES:
                    row = compare_trace(a.rtsim, a.dramsim3,
                                        os.path.join(a.configs, FAMILIES[family]), trace, tmp)
                    row["reference"] = row.pop("dramsim3")
                    row.update(device=FAMILIES[family], ref_name="DRAMsim3")
                else:
                    preset, timing_preset = RAMULATOR2_FAMILIES[family]
                    row = compare_trace_ramulator2(a.rtsim, tools, preset, timing_preset,
                                                   trace, interval, tmp)
                    row.update(device=preset, ref_name="Ramulator 2")
                row.update(family=family, load=load)
                rows.append(row)
                print(f"compare_dram: {family} {load} done", file=sys.stderr)

    text = report(a.requests, seed, rows, loaded, refused)
    write_results(a.out, "dram_standards", text, {"seed": seed, "rows": rows, "loaded": loaded,
                                                  "refused": refused})
    print(text)


if __name__ == "__main__":
    main()

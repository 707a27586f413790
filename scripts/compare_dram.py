#!/usr/bin/env python3
"""Every memory family against a reference simulator: DRAMsim3 for the families it models,
Ramulator 2 for DDR5, LPDDR5 (per-bank and all-bank refresh) and HBM2 in pseudo-channel mode, and
DRAMPower for DDR5's and LPDDR5's energy; light, moderate and saturating loads, one table.

No reference is part of RTSim. Build DRAMsim3 from its public repository (umd-memsys/DRAMsim3) and
pass its binary and its configs folder. Build Ramulator 2 (CMU-SAFARI/ramulator2) with its own
CMake and pass the source tree: it has no executable, so this script compiles
scripts/ramulator2_driver.cpp against its library and writes rtsim's preset as a Ramulator 2
config through Ramulator 2's Python package, with the same organisation and every timing in
cycles (matched timings), its RoBaRaCoCh mapping, open rows and FR-FCFS; where a convention
differs (a REFpb's banks), the rtsim field that matches it is set and named in the table. Build
DRAMPower's CLI (tukl-msd/DRAMPower, DRAMPOWER_BUILD_CLI) and pass the source tree: rtsim's own
command trace (rtsim dram --commands) goes through it with rtsim's currents and timings in a
memspec made from DRAMPower's test memspec, and its core energy is the reference. For each
DRAMsim3 family's device file both simulators read the same .ini (rtsim through its importer).
Both run the same traces (device cycles):
  * random-light: uniform random 64-byte addresses, 25% writes, one request per 40 cycles;
  * random-moderate: the same, one per 10 cycles;
  * random-saturating: the same, one per cycle (the queues fill; completion time matters);
  * stream-light: sequential 64-byte reads, one per 40 cycles;
  * stream-saturating: the same, one per cycle.
The targets: read latency and ACT count within 5% at light load, completion time within 10% at
saturating load, energy within 10%. Also counts how many of the folder's device files load at
all. The traces' addresses come from --seed (drawn at run time when not given, and printed with
the table). Writes bench/results/dram_standards.md (every row: out/bench/dram_standards.json).

    scripts/compare_dram.py --dramsim3 /path/to/dramsim3main --configs /path/to/DRAMsim3/configs
        [--ramulator2 /path/to/ramulator2] [--drampower /path/to/DRAMPower] [--rtsim build/rtsim]
        [--requests 15000] [--families DDR3,GDDR6,DDR5,HBM2-pc,...] [--seed S] [--out DIR]
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
# rtsim's own presets checked against Ramulator 2: the preset, the timing preset of Ramulator 2's
# tables it was taken from (for the timings rtsim has no field for), device fields set on both
# sides, and where a convention differs, the rtsim field that matches Ramulator 2's and why.
RAMULATOR2_FAMILIES = {
    "DDR5": {"preset": "DDR5_16Gb_x8_4800", "timing": "DDR5_4800AN"},
    # Per-bank refresh (the preset's default): Ramulator 2's REFpb refreshes one bank where
    # JESD209-5's 16-bank modes (and DRAMPower's REFP2B) refresh a pair.
    "LPDDR5": {"preset": "LPDDR5_8Gb_x16_6400", "timing": "LPDDR5_6400",
               "set": {"refresh_pb_banks": 1},
               "convention": "REFpb refreshes one bank in Ramulator 2, a bank pair in rtsim's "
                             "preset (JESD209-5 16-bank modes): compared with refresh_pb_banks=1"},
    "LPDDR5-allbank": {"preset": "LPDDR5_8Gb_x16_6400", "timing": "LPDDR5_6400",
                       "set": {"refresh_mode": "all_bank"}},
    # Pseudo-channel mode: 8 channels of two 64-bit pseudo-channels, separate row and column
    # command buses.
    "HBM2-pc": {"preset": "HBM2_8Gb_x128_2000", "timing": "HBM2_2000Mbps",
                "convention": "an ACT holds Ramulator 2's row command bus 2 cycles, rtsim's 1"},
}
# Ramulator 2's channel interleave on the line above the transaction, then RoBaRaCoCh (column,
# then the levels under the channel upwards: rank or pseudo-channel, bank group, bank, row), in
# rtsim's most-significant-first notation.
RAMULATOR2_MAPPING = {"DDR5": "robabgracoch", "LPDDR5": "robabgracoch", "HBM2": "rorababgpccoch"}
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
    if dev["protocol"] == "HBM2":
        return {"nBL": burst, "nCL": dev["cl"], "nCWL": dev["cwl"], "nRCDRD": dev["t_rcd"],
                "nRCDWR": dev.get("t_rcd_wr") or dev["t_rcd"], "nRP": dev["t_rp"],
                "nRAS": dev["t_ras"], "nRC": dev["t_ras"] + dev["t_rp"], "nWR": dev["t_wr"],
                "nRTPL": dev["t_rtp"], "nCCDS": dev["t_ccd_s"], "nCCDL": dev["t_ccd_l"],
                "nRRDS": dev["t_rrd_s"], "nRRDL": dev["t_rrd_l"], "nWTRS": dev["t_wtr_s"],
                "nWTRL": dev["t_wtr_l"], "nFAW": dev["t_faw"], "nRFC": dev["t_rfc"],
                "nREFI": dev["t_refi"]}
    t = {"nCL": dev["cl"], "nCWL": dev["cwl"], "nRCD": dev["t_rcd"], "nRP": dev["t_rp"],
         "nRAS": dev["t_ras"], "nRC": dev["t_ras"] + dev["t_rp"], "nWR": dev["t_wr"],
         "nRTP": dev["t_rtp"], "nCCDS": dev["t_ccd_s"], "nCCDL": dev["t_ccd_l"],
         "nCCDS_WR": dev["t_ccd_s"], "nCCDL_WR": dev["t_ccd_l"], "nRRDS": dev["t_rrd_s"],
         "nRRDL": dev["t_rrd_l"], "nWTRS": dev["t_wtr_s"], "nWTRL": dev["t_wtr_l"],
         "nFAW": dev["t_faw"], "nRFC": dev["t_rfc"], "nREFI": dev["t_refi"]}
    if dev["protocol"] == "LPDDR5":
        t.update(nBL_min=burst, nRPab=dev["t_rp"])
        if dev.get("refresh_mode") == "per_bank":
            t.update(nRFCpb=dev["t_rfc_pb"], nREFIpb=dev["t_refi_pb"],
                     nPBR2PBR=dev["t_pbr2pbr"], nPBR2ACT=dev["t_pbr2act"])
    else:
        t.update(nBL=burst)
    return t


def ramulator2_org_preset(dev):
    if dev["protocol"] == "HBM2":
        return "HBM2_8Gb"  # the organisation is given level by level
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
    # Ranks, or HBM's pseudo-channels, as the level under the channel.
    upper = ({"pseudochannel": dev["pseudo_channels"]} if std == "HBM2"
             else {"rank": dev["ranks"]})
    kind = {"LPDDR5": ramulator.controller.LPDDR5,
            "HBM2": ramulator.controller.HBM12}.get(std, ramulator.controller.GenericDDR)
    refresh = (ramulator.refresh_manager.PerBank if dev.get("refresh_mode") == "per_bank"
               else ramulator.refresh_manager.AllBank)
    for ch in range(dev["channels"]):
        dram = getattr(ramulator.dram, std)(
            org_preset=ramulator2_org_preset(dev), timing_preset=timing_preset, **upper,
            bankgroup=dev["bankgroups"], bank=dev["banks_per_group"],
            row=dev["rows"], column=dev["columns"], channel_width=dev["bus_width_bits"],
            **ramulator2_timings(dev))
        controllers.append(kind(
            dram=dram, scheduler=ramulator.scheduler.FRFCFS(),
            refresh_manager=refresh(),
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
            "ref": sum(1 for c, x in cmds if x in ("REFab", "REFpb") and c <= done)}


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


def compare_trace_ramulator2(rtsim, tools, family, trace, interval, tmp, drampower=None):
    """One trace through `rtsim dram` (its preset, with the family's settings and Ramulator 2's
    address mapping) and Ramulator 2 (the same device through its config)."""
    fam = RAMULATOR2_FAMILIES[family]
    preset, timing_preset = fam["preset"], fam["timing"]
    with open(os.path.join(ROOT, "configs", "dram", preset + ".json")) as f:
        dev = json.load(f)
    sets = dict(fam.get("set", {}), address_mapping=RAMULATOR2_MAPPING[dev["protocol"]])
    energy_ref = drampower and dev["protocol"] in DRAMPOWER_TEMPLATES
    if energy_ref:
        # DRAMPower's bank-wise background (its memspec's factRho): matched on rtsim's side,
        # where it changes energy only.
        sets["bankwise_rho"] = drampower_memspec(drampower, dev)["memspec"]["bankwisespec"][
            "factRho"]
        # Its LPDDR5 model reads IDD3N as one bank open, its DDR5 model as all.
        if dev["protocol"] == "LPDDR5":
            sets["idd3n_open_banks"] = 1
    dev.update(sets)
    out = os.path.join(tmp, "rt-" + os.path.basename(trace))
    commands = os.path.join(out, "commands.csv")
    cmd = [rtsim, "dram", "-q", trace, "--device", preset, "-o", out, "--commands", commands]
    for k, v in sets.items():
        cmd += ["--set", f"{k}={v}"]
    subprocess.run(cmd, check=True)
    with open(os.path.join(out, "stats.json")) as f:
        r = json.load(f)
    with open(trace) as f:
        n = sum(1 for _ in f)
    reference = ramulator2(tools, dev, timing_preset, trace, interval, tmp)
    if energy_ref:
        reference["energy_nj"] = drampower_energy_nj(drampower, dev, commands, r["cycles"], out)
    return {"requests": n, "sets": sets,
            "table_differs": ramulator2_table_differences(tools[0], dev, timing_preset),
            "rtsim": {"cycles": r["cycles"], "read_latency": r["read_latency_cycles"]["mean"],
                      "act": r["commands"]["act"],
                      "ref": r["commands"]["ref"] + r["commands"]["ref_pb"],
                      "energy_nj": r["energy_pj"]["total"] / 1e3},
            "reference": reference}


# DRAMPower's own memspecs (its test resources) as templates: rtsim's organisation, currents and
# timings go in; DRAMPower's model parameters (bank-wise factRho, impedances) stay its own.
DRAMPOWER_TEMPLATES = {"DDR5": "ddr5.json", "LPDDR5": "lpddr5.json"}


def drampower_memspec(src, dev):
    """rtsim's device `dev` as a DRAMPower memspec of one channel (currents in A, tCK in s)."""
    with open(os.path.join(src, "tests", "tests_drampower", "resources",
                           DRAMPOWER_TEMPLATES[dev["protocol"]])) as f:
        spec = json.load(f)
    m = spec["memspec"]
    a, p, t = m["memarchitecturespec"], m["mempowerspec"], m["memtimingspec"]
    a.update(nbrOfColumns=dev["columns"], nbrOfRows=dev["rows"], width=dev["device_width_bits"],
             burstLength=dev["burst_length"], maxBurstLength=dev["burst_length"],
             nbrOfBankGroups=dev["bankgroups"],
             nbrOfBanks=dev["bankgroups"] * dev["banks_per_group"], nbrOfRanks=dev["ranks"],
             nbrOfDevices=dev["bus_width_bits"] // dev["device_width_bits"])
    t["tCK"] = dev["tck_ns"] * 1e-9
    amp = {k: dev[k] / 1000.0 for k in ("idd0", "idd2n", "idd3n", "idd4r", "idd4w", "idd5ab")}
    if dev["protocol"] == "DDR5":
        p.update(vdd=dev["vdd"], idd0=amp["idd0"], idd2n=amp["idd2n"], idd3n=amp["idd3n"],
                 idd4r=amp["idd4r"], idd4w=amp["idd4w"], idd5b=amp["idd5ab"],
                 idd5c=amp["idd5ab"], idd5f=amp["idd5ab"], iBeta_vdd=amp["idd0"])
        t.update(RAS=dev["t_ras"], RCD=dev["t_rcd"], RTP=dev["t_rtp"], WL=dev["cwl"],
                 RL=dev["cl"], WR=dev["t_wr"], RP=dev["t_rp"], RFC1=dev["t_rfc"],
                 RFC1_slr=dev["t_rfc"], REFI1=dev["t_refi"])
        return spec
    # LPDDR5: bursts of BL / (2 x WCK:CK) clock cycles, as rtsim's burst_cycles.
    banks = a["nbrOfBanks"]
    a.update(dataRate=2, per2BankOffset=banks // 2)
    t.update(WCK2CK=dev["burst_length"] // (2 * dev["burst_cycles"]), RAS=dev["t_ras"],
             RPab=dev["t_rp"], RPpb=dev["t_rp"], RCab=dev["t_ras"] + dev["t_rp"],
             RCpb=dev["t_ras"] + dev["t_rp"], RCD=dev["t_rcd"], RL=dev["cl"], WL=dev["cwl"],
             WR=dev["t_wr"], RBTP=dev["t_rtp"], REFI=dev["t_refi"], RFCab=dev["t_rfc"],
             RFCpb=dev.get("t_rfc_pb") or 1, REFIpb=dev.get("t_refi_pb", 0),
             pbR2act=dev.get("t_pbr2act", 0), pbR2pbR=dev.get("t_pbr2pbr", 0))
    # Per-bank refresh: DRAMPower reads IDD5PB as the average current with one refresh every
    # tREFI / 8, and charges it per bank refreshed. rtsim's preset has no IDD5PB (its refresh
    # costs the all-bank refresh's charge over the refreshes of a round), so that same charge
    # per bank goes in as the IDD5PB that yields it under DRAMPower's reading.
    per_bank_j = (dev["vdd"] * (amp["idd5ab"] - amp["idd3n"]) * dev["t_rfc"] / banks)
    idd5pb = amp["idd2n"] + per_bank_j / (dev["vdd"] * dev["t_refi"] / 8)
    p.update(vdd1=dev["vdd"], idd01=amp["idd0"], idd2n1=amp["idd2n"], idd3n1=amp["idd3n"],
             idd4r1=amp["idd4r"], idd4w1=amp["idd4w"], idd51=amp["idd5ab"], idd5pb1=idd5pb,
             iBeta_vdd1=amp["idd0"])
    return spec


def drampower_energy_nj(src, dev, commands_csv, end_cycle, tmp):
    """DRAMPower's core energy (nJ; its interface and I/O energy left out, as rtsim has none) of
    rtsim's own command trace, one DRAMPower run per channel."""
    cli = os.path.join(src, "build", "bin", "drampower_cli")
    spec_path = os.path.join(tmp, "memspec.json")
    with open(spec_path, "w") as f:
        json.dump(drampower_memspec(src, dev), f)
    config = os.path.join(tmp, "drampower_config.json")
    with open(config, "w") as f:
        json.dump({"useToggleRate": False}, f)
    burst_hex = "00" * (dev["bus_width_bits"] // 8 * dev["burst_length"])
    refpb = "REFP2B" if dev.get("refresh_pb_banks", 1) == 2 else "REFB"
    names = {"ACT": "ACT", "PRE": "PRE", "RD": "RD", "WR": "WR", "REF": "REFA", "REFpb": refpb}
    bpg = dev["banks_per_group"]
    per_channel = {}
    with open(commands_csv) as f:
        next(f)  # cycle,command,channel,rank,bankgroup,bank,row
        for line in f:
            cyc, cmd, ch, rank, bg, ba, row = line.strip().split(",")
            bank = int(bg) * bpg + int(ba) if int(bg) >= 0 else 0
            text = f"{cyc},{names[cmd]},{rank},{max(0, int(bg))},{bank},{row},0"
            if cmd in ("RD", "WR"):
                text += "," + burst_hex
            per_channel.setdefault(int(ch), []).append(text)
    total_j = 0.0
    for ch in range(dev["channels"] * dev.get("pseudo_channels", 1)):
        trace = os.path.join(tmp, f"drampower-ch{ch}.csv")
        with open(trace, "w") as f:
            f.write("\n".join(per_channel.get(ch, []) + [f"{end_cycle},END,0,0,0,0,0"]) + "\n")
        out = os.path.join(tmp, f"drampower-ch{ch}.json")
        open(out, "w").close()  # its CLI writes only to an existing file
        r = subprocess.run([cli, "-c", config, "-m", spec_path, "-t", trace, "-j", out],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"drampower: {trace}: {(r.stdout + r.stderr).strip()[-300:]}")
        with open(out) as f:
            core = json.load(f)["CoreEnergy"]
        for key, value in core.items():
            if isinstance(value, list):
                total_j += sum(v for b in value for k, v in b.items()
                               if k not in ("Bank", "Device", "Rank"))
            else:
                total_j += value
    return total_j * 1e9


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
             f"(**bold**: missed). Energy: DRAMsim3's own on its families; for the Ramulator 2 "
             f"families (Ramulator 2 has no energy model), DRAMPower's core energy (interface "
             f"and I/O left out, as rtsim models none) of rtsim's own command trace, with "
             f"rtsim's currents and timings in DRAMPower's memspec; target within 10%.", ""]
    if loaded or refused:
        lines += [f"Device files in DRAMsim3's configs folder: {len(loaded)} of "
                  f"{len(loaded) + len(refused)} simulate; refused: "
                  + ("; ".join(f"{n} ({why})" for n, why in refused) or "none") + ".", ""]
    differs = {r["family"]: r for r in rows if "table_differs" in r}
    for family, r in differs.items():
        fam = RAMULATOR2_FAMILIES[family]
        sets = ", ".join(f"{k}={v}" for k, v in r["sets"].items())
        lines.append(f"- {family} ({r['device']}, rtsim --set {sets}): Ramulator 2's table "
                     "differs in " + (", ".join(f"{k} {a} (rtsim {b})"
                                                for k, (a, b) in r["table_differs"].items())
                                      or "nothing")
                     + (f"; convention: {fam['convention']}" if "convention" in fam else "")
                     + ".")
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
    ap.add_argument("--drampower", help="a DRAMPower source tree with its CLI built "
                    "(build/bin/drampower_cli): energy reference for DDR5 and LPDDR5")
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
                    row = compare_trace_ramulator2(a.rtsim, tools, family, trace, interval, tmp,
                                                   a.drampower)
                    row.update(device=RAMULATOR2_FAMILIES[family]["preset"],
                               ref_name="Ramulator 2")
                row.update(family=family, load=load)
                rows.append(row)
                print(f"compare_dram: {family} {load} done", file=sys.stderr)

    text = report(a.requests, seed, rows, loaded, refused)
    write_results(a.out, "dram_standards", text, {"seed": seed, "rows": rows, "loaded": loaded,
                                                  "refused": refused})
    print(text)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Checks that a change keeps simulated statistics identical: runs two rtsim binaries on a matrix
of configs and workloads and compares every field of stats.json except `host` and
`sampling.profile`'s seconds and cache (the host's), and `config_files` (paths). Prints one line
per case and exits 1 on the first difference.

    scripts/same_stats.py OLD_RTSIM NEW_RTSIM [--only NAME,...] [--keep DIR] [--set K=V ...]

`--set sim.fidelity=accurate` runs the same matrix on the time-ordered engine.

The matrix covers every shipped config, every traversal mode, every replacement policy the old
binary knows, split L1, shared units, banks, MSHR limits, ideal modes and time series.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

BUNNY = "/usr/share/glmark2/models/bunny.obj"
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def cfg(name):
    return os.path.join(ROOT, "configs", name)


# name: arguments after `rtsim run`
CASES = {
    "default": [],
    "baseline_bunny_ao": ["--config", cfg("baseline.json"), "--scene", BUNNY, "--rays",
                          "primary,ao", "--res", "96x96"],
    "small_caches_diffuse_bvh8": ["--config", cfg("small_caches.json"), "--scene", BUNNY,
                                  "--rays", "diffuse", "--res", "96x96", "--set", "bvh.width=8"],
    "fifo_banks": ["--scene", BUNNY, "--rays", "ao", "--res", "64x64", "--set",
                   "l1.replacement=fifo", "--set", "l1.banks=2", "--set", "l2.replacement=fifo"],
    "random_split_mshr": ["--config", cfg("small_caches.json"), "--scene", BUNNY, "--rays",
                          "primary,ao", "--res", "64x64", "--set", "l1.split=true", "--set",
                          "l2.replacement=random", "--set", "l1.replacement=random", "--set",
                          "l1.mshrs=4", "--set", "l2.mshrs=8"],
    "treelet": ["--config", cfg("treelet.json"), "--scene", BUNNY, "--rays", "diffuse", "--res",
                "64x64"],
    "treelet_rr_cache": ["--config", cfg("treelet.json"), "--scene", BUNNY, "--rays",
                         "primary,diffuse", "--res", "64x64", "--set",
                         "traversal.treelet_scheduler=round_robin", "--set",
                         "traversal.treelet_prefetch=true", "--set",
                         "traversal.treelet_cache_kib=16", "--set", "ray_buffer.capacity_rays=512"],
    "packet": ["--scene", BUNNY, "--rays", "primary,shadow", "--res", "64x64", "--set",
               "traversal.mode=packet", "--set", "bvh.width=4"],
    "shared_units_issue2": ["--scene", BUNNY, "--rays", "primary,ao", "--res", "64x64", "--set",
                            "box_unit.shared_by=4", "--set", "triangle_unit.shared_by=2", "--set",
                            "core.issue_width=2", "--set", "l2.banks=4", "--set",
                            "sim.window_cycles=5000"],
    "ideal_compressed_lbvh": ["--rays", "primary,diffuse", "--res", "64x64", "--set",
                              "sim.ideal_memory=true", "--set", "bvh.builder=lbvh", "--set",
                              "bvh.node_format=compressed", "--set", "bvh.width=4"],
    # {trace}: a trace the old binary records first (bunny, BVH4 with treelets, primary+diffuse)
    "replay": ["--trace", "{trace}", "--set", "bvh.width=4", "--set", "bvh.treelet_bytes=8192",
               "--set", "l1.size_kib=8"],
    "replay_treelet": ["--trace", "{trace}", "--config", cfg("treelet.json")],
    # The traversal's own traffic: stack spills and refills, hit records, a small write buffer.
    "stack_hits_writes": ["--scene", BUNNY, "--rays", "primary,diffuse", "--res", "64x64",
                          "--set", "core.short_stack_entries=2", "--set",
                          "core.hit_record_bytes=16", "--set", "core.write_buffer_entries=2",
                          "--set", "dram.model=command", "--set", "l1.mshrs=2"],
    "treelet_records_in_memory": ["--config", cfg("treelet.json"), "--scene", BUNNY, "--rays",
                                  "diffuse", "--res", "64x64", "--set",
                                  "ray_buffer.storage=memory", "--set",
                                  "core.hit_record_bytes=16"],
    "ideal_units_4ch": ["--scene", BUNNY, "--rays", "ao", "--res", "64x64", "--set",
                        "sim.ideal_units=true", "--set",
                        "dram.channels=4", "--set", "crossbar.bytes_per_cycle=0"],
}


def run(rtsim, args, out):
    r = subprocess.run([rtsim, "run", "-q", "--out", out] + args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{rtsim} run {' '.join(args)} failed: {r.stderr.strip()}")
    with open(os.path.join(out, "stats.json")) as f:
        s = json.load(f)
    s.pop("host", None)
    s.pop("config_files", None)
    # The frame profile's build time, and whether it was built or found in the cache (skip
    # sampling), are the host's too.
    for key in ("seconds", "cache"):
        s.get("sampling", {}).get("profile", {}).pop(key, None)
    return s


def diff(a, b, path=""):
    """The first differing field as 'path: a != b', or None."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{path}.{k}: only in {'new' if k in b else 'old'}"
            d = diff(a[k], b[k], f"{path}.{k}")
            if d:
                return d
        return None
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{path}: {len(a)} entries != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            d = diff(x, y, f"{path}[{i}]")
            if d:
                return d
        return None
    return None if a == b else f"{path}: {a!r} != {b!r}"


def drop_added(old, new, path, added):
    """Removes from `new` the keys of config sections that `old` lacks (fields a change added;
    their defaults must not change what is simulated), listing them in `added`."""
    for k in list(new):
        if k not in old:
            added.append(f"{path}.{k}")
            del new[k]
        elif isinstance(old[k], dict) and isinstance(new[k], dict):
            drop_added(old[k], new[k], f"{path}.{k}", added)


def count_fields(v):
    if isinstance(v, dict):
        return sum(count_fields(x) for x in v.values())
    if isinstance(v, list):
        return sum(count_fields(x) for x in v)
    return 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--only", default="", help="comma list of case names")
    ap.add_argument("--keep", default="", help="keep the runs' folders here")
    ap.add_argument("--set", action="append", default=[], metavar="K=V",
                    help="a setting added to every case (e.g. sim.fidelity=accurate); repeatable")
    ap.add_argument("--allow-added", action="store_true",
                    help="fields only the new binary reports (new counters or sections) are listed, "
                         "not differences; every field both report must still be equal")
    ap.add_argument("--ignore", action="append", default=[],
                    help="a top-level section a change deliberately moved (e.g. energy), left "
                         "out of the comparison and named in the output; repeatable")
    a = ap.parse_args()
    names = [n for n in a.only.split(",") if n] or list(CASES)
    for n in names:
        if n not in CASES:
            sys.exit(f"--only: unknown case {n} (known: {', '.join(CASES)})")
    work = a.keep or tempfile.mkdtemp(prefix="same_stats_")
    trace = os.path.join(work, "bunny.rtt")
    if any("{trace}" in CASES[n] for n in names):
        r = subprocess.run([a.old, "trace", "-q", "--scene", BUNNY, "--rays", "primary,diffuse",
                            "--res", "64x64", "--set", "bvh.width=4", "--set",
                            "bvh.treelet_bytes=8192", "-o", trace], capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"recording the replay trace failed: {r.stderr.strip()}")
    for n in names:
        args = [x.replace("{trace}", trace) for x in CASES[n]]
        for kv in a.set:
            args += ["--set", kv]
        old = run(a.old, args, os.path.join(work, n, "old"))
        new = run(a.new, args, os.path.join(work, n, "new"))
        added, removed = [], []
        drop_added(old.get("config", {}), new.get("config", {}), "config", added)
        # Config fields a change removed (their old value was what the new binary always does).
        drop_added(new.get("config", {}), old.get("config", {}), "config", removed)
        if a.allow_added:
            drop_added(old, new, "", added)
        if added or removed:  # the hash covers those fields; the rest of the config is compared
            old.pop("config_hash", None)
            new.pop("config_hash", None)
        for section in a.ignore:
            old.pop(section, None)
            new.pop(section, None)
        d = diff(old, new)
        if d:
            print(f"{n}: DIFFERENT at {d}")
            sys.exit(1)
        shown = ", ".join(added[:6]) + (f", ... ({len(added)} in all)" if len(added) > 6 else "")
        extra = f"; fields only the new binary reports: {shown}" if added else ""
        if removed:
            extra += f"; config fields only the old binary had: {', '.join(removed)}"
        print(f"{n}: identical ({count_fields(new)} fields, {new['total_cycles']} cycles{extra})")
    ignored = f" (not compared: {', '.join(a.ignore)})" if a.ignore else ""
    print(f"all {len(names)} cases identical{ignored}")


if __name__ == "__main__":
    main()

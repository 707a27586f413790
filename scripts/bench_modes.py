#!/usr/bin/env python3
"""Traversal modes compared: baseline (rays traverse independently), treelet queues through the
ray buffer (with lines fetched on demand, and with whole treelets loaded per batch) and packets.

For each scene and ray kind it runs `rtsim run` in every mode on the same rays and prints DRAM
bytes, bytes per ray at DRAM and at the L2 (L1 fills: the traffic Aila & Karras 2010 count for
a per-core cache), ray-buffer bytes per ray, simulated rays per second, and each mode's DRAM and
L2 traffic relative to the baseline. Not a test: a table to read.

    scripts/bench_modes.py [--rtsim build/rtsim] [--res 512x512] [--kinds primary,ao,diffuse]
                           [--scenes a.obj,b.off] [--set key=value ...]
"""
import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import run_stats  # noqa: E402

MODES = [
    ("baseline", []),
    ("treelet", ["traversal.mode=treelet", "traversal.treelet_prefetch=false"]),
    ("treelet+load", ["traversal.mode=treelet", "traversal.treelet_prefetch=true"]),
    ("packet", ["traversal.mode=packet"]),
]


def default_scenes(root):
    scenes = ["builtin:cornell", "/usr/share/glmark2/models/bunny.obj"]
    elephant = os.path.join(root, ".cache/meshes/cgal/refined_elephant.off")
    if os.path.exists(elephant):
        scenes.append(elephant)
    return scenes


def run(rtsim, args, out):
    return run_stats(rtsim, args, out, "bench_modes")


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--rtsim", default=os.path.join(root, "build/rtsim"))
    p.add_argument("--res", default="512x512")
    p.add_argument("--kinds", default="primary,ao,diffuse")
    p.add_argument("--scenes", default=None, help="comma list (default: cornell, bunny, elephant)")
    p.add_argument("--set", action="append", default=[], help="config override for every mode")
    a = p.parse_args()
    scenes = a.scenes.split(",") if a.scenes else default_scenes(root)
    # Treelets sized to a quarter of the 32 KiB L1, BVH4; every mode gets the same BVH layout
    # (the treelet layout only renumbers records), so the rays and their steps are the same.
    common = ["bvh.width=4", "bvh.treelet_bytes=8192"] + a.set
    print(f"resolution {a.res}, overrides {common}, config configs/baseline.json otherwise")
    print("DRAM and L2 columns: bytes per ray; 'vs base': that traffic relative to the baseline.")
    hdr = (f"{'scene':16} {'rays':8} {'mode':13} {'rays':>8} {'Mcycles':>8} {'DRAM MB':>8} "
           f"{'DRAM/ray':>9} {'vs base':>8} {'L2/ray':>8} {'vs base':>8} {'RB/ray':>7} "
           f"{'Mrays/s':>8} {'lanes':>6} {'rays/batch':>10}")
    print(hdr)
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes:
            name = os.path.basename(scene).replace("builtin:", "")[:16]
            for kind in a.kinds.split(","):
                base = None
                for mode, sets in MODES:
                    args = ["--scene", scene, "--rays", kind, "--res", a.res]
                    for kv in common + sets:
                        args += ["--set", kv]
                    s = run(a.rtsim, args, os.path.join(tmp, f"{name}-{kind}-{mode}"))
                    rays = s["rays"]["total"]
                    dram = s["bandwidth"]["dram"]["bytes"]
                    l2 = s["bandwidth"]["l2"]["bytes"]
                    rb = s.get("ray_buffer", {})
                    if base is None:
                        base = (dram, l2)
                    lanes = s.get("packets", {}).get("lane_utilization")
                    lanes_text = f"{lanes:.0%}" if lanes is not None else "-"
                    batch_text = f"{rb['rays_per_batch']:.1f}" if rb else "-"
                    print(f"{name:16} {kind:8} {mode:13} {rays:8d} {s['total_cycles'] / 1e6:8.3f} "
                          f"{dram / 1e6:8.2f} {dram / rays:9.1f} {dram / base[0]:7.0%} "
                          f"{l2 / rays:8.1f} {l2 / base[1]:7.0%} {rb.get('bytes', 0) / rays:7.1f} "
                          f"{s['rays_per_second'] / 1e6:8.1f} "
                          f"{lanes_text:>6} {batch_text:>10}")
                sys.stdout.flush()


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Trace-file benchmark (figures, not a test): size per ray and per step, write and read speed,
the cost of recording against the untraced functional run, and a full-HD frame recorded and
replayed with its peak memory.

    scripts/bench_trace.py [--rtsim build/rtsim] [--scene FILE] [--res 512x512] [--skip-hd]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time


def run(cmd):
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"bench_trace: {' '.join(cmd)} failed: {r.stderr.strip()}")
    return r.stdout, dt


def best_of(n, cmd):
    return min(run(cmd)[1] for _ in range(n))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--rtsim", default="build/rtsim")
    p.add_argument("--scene", default="/usr/share/glmark2/models/bunny.obj")
    p.add_argument("--res", default="512x512")
    p.add_argument("--skip-hd", action="store_true", help="skip the 1920x1080 frame")
    a = p.parse_args()
    rt = a.rtsim
    with tempfile.TemporaryDirectory() as tmp:
        print(f"scene {a.scene}, {a.res}, 1 host thread")
        print(f"{'rays':9} {'count':>9} {'steps':>10} {'bytes/ray':>10} {'bytes/step':>11} {'write MB/s':>11} "
              f"{'read MB/s':>10} {'record/untraced':>16}")
        for kind in ["primary", "ao", "diffuse"]:
            rtt = os.path.join(tmp, f"{kind}.rtt")
            base = [rt, "trace", "-j", "1", "--scene", a.scene, "--rays", kind, "--res", a.res]
            untraced = best_of(3, base + ["-q"])
            recorded = best_of(3, base + ["-q", "-o", rtt])
            info_out, _ = run([rt, "trace-info", "--json", rtt])
            info = json.loads(info_out)
            read_t = best_of(3, [rt, "trace-info", rtt])
            mb = info["bytes"] / 1e6
            write_mb_s = mb / max(recorded - untraced, 1e-9)
            print(f"{kind:9} {info['rays']:9d} {info['steps']:10d} {info['bytes_per_ray']:10.2f} "
                  f"{info['bytes_per_step']:11.3f} {write_mb_s:11.1f} {mb / read_t:10.1f} {recorded / untraced:15.2f}x")
        if a.skip_hd:
            return
        # A full-HD frame: 1 primary, 1 shadow and 4 AO rays per pixel, on the built-in room (every
        # pixel hits), recorded and then replayed through the timing model.
        rtt = os.path.join(tmp, "hd.rtt")
        out, t_rec = run([rt, "trace", "--scene", "builtin:cornell", "--rays", "primary,shadow,ao", "--ao-samples", "4",
                          "--res", "1920x1080", "-o", rtt])
        rec_rss = float(re.search(r"peak RSS (\d+) MiB", out).group(1))
        info = json.loads(run([rt, "trace-info", "--json", rtt])[0])
        _, t_rep = run([rt, "run", "-q", "--trace", rtt, "--out", os.path.join(tmp, "hd")])
        with open(os.path.join(tmp, "hd", "stats.json")) as f:
            stats = json.load(f)
        print(f"\n1920x1080 frame, primary + shadow + 4 AO per pixel: {info['rays']} rays, {info['steps']} steps, "
              f"{info['bytes'] / 1e6:.1f} MB ({info['bytes_per_step']:.3f} bytes/step)")
        print(f"  record: {t_rec:.1f} s, peak RSS {rec_rss:.0f} MiB")
        print(f"  replay: {t_rep:.1f} s, peak RSS {stats['host']['peak_rss_mib']:.0f} MiB, "
              f"{stats['host']['simulated_rays_per_host_second'] / 1e6:.2f} M simulated rays per host second")


if __name__ == "__main__":
    main()

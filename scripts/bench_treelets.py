#!/usr/bin/env python3
"""Where treelet queues cut DRAM traffic and energy, and where they do not.

Aila & Karras (HPG 2010) queue rays by treelet so that a treelet's data is fetched once for many
rays, and report up to 90% less memory traffic in difficult scenes. This runs RTSim's treelet
mode (configs/treelet.json) against independent traversal of the same frame and config over
the regimes that decide it, one factor at a time around a centre point:

  * scene size against L2 size: libcgal-demo's refined_elephant (89k triangles, a 7.6 MB BVH4)
    and a 3x3 grid of it (800k triangles, 68 MB; scripts/make_grid_scene.py), L2 of 128 KiB,
    1 MiB and 4 MiB;
  * rays in flight (ray_buffer.capacity_rays) against the number of treelets;
  * treelet size (bvh.treelet_bytes) against the 32 KiB L1;
  * rays per batch (traversal.treelet_batch_rays) and the treelet scheduler;
  * queues in SRAM against queues in memory (ray_buffer.storage), where every crossing writes
    the ray's record to memory and reads it back.

Every point reports DRAM bytes per ray (and how much of it is BVH data and how much ray records:
bandwidth.dram.by_region), L2-to-L1 bytes per ray, energy per ray, cycles, and rays per batch,
each against the independent-traversal run with the same scene, frame and L2. The compulsory
traffic (the BVH's bytes over the frame's rays: every byte fetched once) bounds what any order
can save. Writes bench/results/treelets.{md,json}.

    scripts/bench_treelets.py [--rtsim build/rtsim] [--res 1024x1024] [-j 2]
                              [--out bench/results]
"""
import argparse
import concurrent.futures
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import CGAL, ROOT, run_stats, write_results  # noqa: E402

ELEPHANT = os.path.join(CGAL, "refined_elephant.off")
GRID = os.path.join(ROOT, ".cache", "meshes", "grid", "refined_elephant_3x3.off")
SCENES = {"elephant": ELEPHANT, "elephant3x3": GRID}

# The centre point: the regime where treelets pay (found by this benchmark; configs/
# treelet_best.json holds it), each factor varied from it in turn.
CENTRE = {"scene": "elephant", "spp": 4, "l2_kib": 128, "treelet_bytes": 16384,
          "capacity": 65536, "batch": 4096, "storage": "sram", "scheduler": "most_rays",
          "prefetch": False, "banks": 1}


def points():
    """(group, label, settings) for every treelet point; baselines are derived from them."""
    out = []

    def add(group, label, **change):
        p = dict(CENTRE)
        p.update(change)
        out.append((group, label, p))

    for scene in ("elephant", "elephant3x3"):
        for l2 in (128, 1024, 4096):
            add("scene size against L2", f"{scene}, L2 {l2} KiB", scene=scene, l2_kib=l2)
    for spp in (1, 4, 16):
        add("rays per frame", f"{spp} samples per pixel", spp=spp)
    for cap in (1024, 4096, 16384, 65536, 262144):
        add("rays in flight", f"{cap} rays in flight", capacity=cap)
    for cap in (65536, 262144, 1048576):
        add("rays in flight", f"{cap} rays in flight, 16 spp", capacity=cap, spp=16)
    for tb in (4096, 8192, 16384, 32768, 65536, 131072):
        add("treelet size against the 32 KiB L1", f"treelets of {tb // 1024} KiB",
            treelet_bytes=tb)
    for b in (64, 256, 1024, 4096, 16384):
        add("rays per batch", f"batches of up to {b} rays", batch=b)
    for s in ("most_rays", "round_robin", "age_ordered"):
        add("scheduler", f"scheduler {s}", scheduler=s)
    add("prefetch", "whole treelet loaded per batch", prefetch=True)
    for banks in (1, 4, 16, 64):
        add("ray-buffer SRAM banks (energy)", f"{banks} banks of {65536 * 64 // banks // 1024} KiB",
            banks=banks)
    for scene in ("elephant", "elephant3x3"):
        add("ray-buffer SRAM banks (energy)", f"{scene}, 16 banks, treelets of 64 KiB",
            scene=scene, banks=16, treelet_bytes=65536)
    # configs/treelet_best.json as it is (its settings are the best regime's).
    add("best regime: configs/treelet_best.json", "configs/treelet_best.json, 16 spp", spp=16,
        config="treelet_best.json")
    for storage in ("sram", "memory"):
        for cap in (16384, 65536):
            for l2 in (128, 4096):
                add("queues in SRAM against memory",
                    f"{storage}, {cap} rays, L2 {l2} KiB", storage=storage, capacity=cap,
                    l2_kib=l2)
    return out


def frame_args(a, p):
    return ["--scene", SCENES[p["scene"]], "--rays", "diffuse", "--res", a.res, "--spp",
            str(p["spp"]), "--set", "bvh.width=4", "--set", f"l2.size_kib={p['l2_kib']}"]


def treelet_args(p):
    if "config" in p:
        return ["--config", os.path.join(ROOT, "configs", p["config"])]
    return ["--config", os.path.join(ROOT, "configs", "treelet.json"),
            "--set", f"bvh.treelet_bytes={p['treelet_bytes']}",
            "--set", f"ray_buffer.capacity_rays={p['capacity']}",
            "--set", f"traversal.treelet_batch_rays={p['batch']}",
            "--set", f"ray_buffer.storage={p['storage']}",
            "--set", f"traversal.treelet_scheduler={p['scheduler']}",
            "--set", f"traversal.treelet_prefetch={'true' if p['prefetch'] else 'false'}",
            "--set", f"ray_buffer.banks={p['banks']}"]


def figures(s):
    """Per-ray figures of one run."""
    rays = s["rays"]["total"]
    c = s["counters"]
    by = s["bandwidth"]["dram"]["by_region"]
    l1_fill = sum(v for k, v in c.items()
                  if (k.startswith("l1[") or k.startswith("treelet_cache[")) and
                  k.endswith(".fill_bytes"))
    rb = s.get("ray_buffer", {})
    return {
        "rays": rays,
        "cycles": s["total_cycles"],
        "dram_bytes_per_ray": c["dram.bytes"] / rays,
        "dram_bvh_bytes_per_ray": (by["nodes"]["read_bytes"] + by["triangles"]["read_bytes"]) / rays,
        "dram_record_bytes_per_ray": (by["ray_records"]["read_bytes"] +
                                      by["ray_records"]["write_bytes"]) / rays,
        "l2_to_l1_bytes_per_ray": l1_fill / rays,
        "energy_nj_per_ray": s["energy"]["per_ray_nj"],
        "dram_energy_nj_per_ray": s["energy"]["blocks_pj"].get("dram", 0.0) / rays / 1000.0,
        "ray_buffer_energy_nj_per_ray":
            s["energy"]["blocks_pj"].get("ray_buffer", 0.0) / rays / 1000.0,
        "rays_per_batch": rb.get("rays_per_batch", 0.0),
        "crossings_per_ray": rb.get("crossings_per_ray", 0.0),
        "l2_hit_rate": s["caches"]["l2"]["hit_rate"],
        "bvh_bytes": s["bvh"]["bytes"],
        "treelets": s["bvh"]["layout"].get("treelets", 0),
    }


def pct(a, b):
    return 100.0 * (a - b) / b if b else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--res", default="1024x1024")
    ap.add_argument("-j", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    a = ap.parse_args()
    if not os.path.exists(ELEPHANT):
        sys.exit(f"{ELEPHANT}: missing; scripts/setup.sh unpacks libcgal-demo's meshes")
    if not os.path.exists(GRID):
        os.makedirs(os.path.dirname(GRID), exist_ok=True)
        subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "make_grid_scene.py"),
                        ELEPHANT, "3", GRID], check=True)
    work = tempfile.mkdtemp(prefix="bench_treelets_")
    pts = points()
    base_keys = sorted({(p["scene"], p["l2_kib"], p["spp"]) for _, _, p in pts})
    jobs = {}
    with concurrent.futures.ThreadPoolExecutor(a.j) as pool:
        for scene, l2, spp in base_keys:
            p = dict(CENTRE, scene=scene, l2_kib=l2, spp=spp)
            out = os.path.join(work, f"base_{scene}_{l2}_{spp}")
            jobs[("base", scene, l2, spp)] = pool.submit(run_stats, a.rtsim, frame_args(a, p), out,
                                                    "baseline")
        for k, (_, _, p) in enumerate(pts):
            out = os.path.join(work, f"p{k}")
            jobs[("point", k)] = pool.submit(run_stats, a.rtsim,
                                             frame_args(a, p) + treelet_args(p), out, "treelets")
        results = {key: figures(f.result()) for key, f in jobs.items()}

    data = {"res": a.res, "centre": CENTRE, "baselines": [], "points": []}
    for scene, l2, spp in base_keys:
        b = results[("base", scene, l2, spp)]
        data["baselines"].append(dict(b, scene=scene, l2_kib=l2, spp=spp))
    best = None
    for k, (group, label, p) in enumerate(pts):
        f = results[("point", k)]
        b = results[("base", p["scene"], p["l2_kib"], p["spp"])]
        d = {"group": group, "label": label, "settings": p, "treelets": f,
             "baseline": b,
             "dram_change_pct": pct(f["dram_bytes_per_ray"], b["dram_bytes_per_ray"]),
             "l2_to_l1_change_pct": pct(f["l2_to_l1_bytes_per_ray"], b["l2_to_l1_bytes_per_ray"]),
             "energy_change_pct": pct(f["energy_nj_per_ray"], b["energy_nj_per_ray"]),
             "cycles_change_pct": pct(f["cycles"], b["cycles"])}
        data["points"].append(d)
        if best is None or d["dram_change_pct"] < best["dram_change_pct"]:
            best = d

    lines = [
        "# Treelet queues against independent traversal",
        "",
        f"`scripts/bench_treelets.py --res {a.res}`: diffuse rays (one bounce from "
        "each primary hit) of libcgal-demo's refined_elephant.off and a 3x3 grid of it, BVH4, "
        "8 cores of 8 slots, L1 32 KiB, the default (simple) DRAM model at 162.5 pJ per byte. Each treelet point "
        "(configs/treelet.json with the settings named) is set against independent traversal "
        "of the same frame with the same L2. Centre point: "
        + ", ".join(f"{k} {v}" for k, v in CENTRE.items()) + ".",
        "",
        "Compulsory DRAM traffic (the BVH's bytes once, over the frame's rays):",
        "",
        "| scene | spp | L2 KiB | rays | BVH MB | compulsory B/ray | baseline DRAM B/ray | "
        "baseline L2->L1 B/ray | baseline nJ/ray | baseline Mcycles |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for b in data["baselines"]:
        lines.append(
            f"| {b['scene']} | {b['spp']} | {b['l2_kib']} | {b['rays']} | "
            f"{b['bvh_bytes'] / 1e6:.1f} | "
            f"{b['bvh_bytes'] / b['rays']:.1f} | {b['dram_bytes_per_ray']:.1f} | "
            f"{b['l2_to_l1_bytes_per_ray']:.1f} | {b['energy_nj_per_ray']:.1f} | "
            f"{b['cycles'] / 1e6:.2f} |")
    group = None
    for d in data["points"]:
        if d["group"] != group:
            group = d["group"]
            lines += ["", f"## {group}", "",
                      "| point | DRAM B/ray (BVH + records) | vs baseline | L2->L1 B/ray | vs baseline "
                      "| nJ/ray (DRAM, ray buffer) | vs baseline | Mcycles | vs baseline | "
                      "rays/batch | treelets |",
                      "|---|---|---|---|---|---|---|---|---|---|---|"]
        f = d["treelets"]
        lines.append(
            f"| {d['label']} | {f['dram_bytes_per_ray']:.1f} ({f['dram_bvh_bytes_per_ray']:.1f} + "
            f"{f['dram_record_bytes_per_ray']:.1f}) | {d['dram_change_pct']:+.1f}% | "
            f"{f['l2_to_l1_bytes_per_ray']:.1f} | {d['l2_to_l1_change_pct']:+.1f}% | "
            f"{f['energy_nj_per_ray']:.1f} ({f['dram_energy_nj_per_ray']:.1f}, "
            f"{f['ray_buffer_energy_nj_per_ray']:.1f}) | {d['energy_change_pct']:+.1f}% | "
            f"{f['cycles'] / 1e6:.2f} | {d['cycles_change_pct']:+.1f}% | "
            f"{f['rays_per_batch']:.0f} | {f['treelets']} |")
    lines += ["", f"Best DRAM reduction: {best['label']} ({best['group']}): "
              f"{best['dram_change_pct']:+.1f}% DRAM bytes, {best['l2_to_l1_change_pct']:+.1f}% "
              f"L2-to-L1 bytes, {best['energy_change_pct']:+.1f}% energy, "
              f"{best['cycles_change_pct']:+.1f}% cycles per ray against the baseline.", ""]
    data["best"] = best
    text = "\n".join(lines)
    write_results(a.out, "treelets", text + "\n", data)
    print(text)


if __name__ == "__main__":
    main()

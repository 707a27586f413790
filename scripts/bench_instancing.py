#!/usr/bin/env python3
"""What instancing costs and saves: an N x N grid of copies of a mesh, simulated once as a scene
file of instances (one BLAS, N*N instances, a TLAS over them) and once flattened into one mesh of
N*N copies (one BVH over all of it), on the same rays and chip. Per grid: preparation time and
peak memory, cycles, DRAM bytes per ray (and the instance records' share), L2 hit rate, box and
transform unit utilisation.

The largest grid again with treelet queues (configs/treelet.json, prefetch on): the two-level
scene cut into TLAS and BLAS treelets against the flattened mesh's, with the treelet loads and
crossings per ray.

Then the alpha-tested case: the --alpha-grid grid with its mesh cut out by a checker alpha mask
(so every candidate hit runs the any-hit shader), against the same instances opaque, with the
shader's latency swept (--shader-latencies) and once without an alpha read: any-hit calls per
ray, hits, cycles over the opaque run, the shader's share of ray-slot stalls and alpha DRAM bytes.

Last, real assets whose nodes share meshes (assimp-testmodels' glTF files, fetched by
scripts/setup.sh): read as instances against the same file read with --flatten.

    scripts/bench_instancing.py [--rtsim build/rtsim] [--mesh armadillo] [--grids 2,4,8]
        [--res 256x256] [--rays primary,ao] [--set KEY=VALUE] [--out bench/results]
        [--alpha-grid 4] [--shader-latencies 5,20,80,320]
        [--assets CesiumMilkTruck.gltf,2CylinderEngine.glb]

Writes bench/results/instancing.md (every run's figures to out/bench/instancing.json).
"""
import argparse
import json
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import ROOT, SCENES, run_stats, write_results  # noqa: E402
from make_grid_scene import read_off  # noqa: E402


def grid_files(mesh_path, n, folder, flattened=True):
    """The grid as a scene file and (unless `flattened` is false: then None) as one flattened OFF:
    copy (i, j) moved by (i, 0, j) times 1.1 mesh extents, as both files place it."""
    verts, faces = read_off(mesh_path)
    lo = [min(v[a] for v in verts) for a in range(3)]
    hi = [max(v[a] for v in verts) for a in range(3)]
    step = 1.1 * max(h - l for l, h in zip(lo, hi))
    scene = os.path.join(folder, f"grid{n}.json")
    with open(scene, "w") as f:
        json.dump({"meshes": {"m": mesh_path},
                   "instances": [{"mesh": "m", "grid": {"count": [n, 1, n],
                                                        "spacing": [step, 0, step]}}]}, f)
    if not flattened:
        return scene, None, len(faces)
    flat = os.path.join(folder, f"grid{n}.off")
    with open(flat, "w") as f:
        f.write(f"OFF\n{len(verts) * n * n} {len(faces) * n * n} 0\n")
        for j in range(n):
            for i in range(n):
                # The scene file's grid offsets in float32 as rtsim adds them; text keeps them.
                for v in verts:
                    f.write(f"{v[0] + i * step!r} {v[1]!r} {v[2] + j * step!r}\n")
        for c in range(n * n):
            base = c * len(verts)
            for face in faces:
                f.write(f"{len(face)} " + " ".join(str(base + k) for k in face) + "\n")
    return scene, flat, len(faces)


def alpha_grid_file(mesh_path, n, folder, opaque):
    """The n x n grid as a scene file whose mesh carries a checker alpha mask (2 x 2 squares per
    triangle: half of every triangle cut out); `opaque` makes the instances skip the shader."""
    scene, _, tris = grid_files(mesh_path, n, folder, flattened=False)
    with open(scene) as f:
        doc = json.load(f)
    doc["meshes"]["m"] = {"file": mesh_path, "alpha": {"pattern": "checker", "cells": 2}}
    doc["instances"][0]["opaque"] = opaque
    path = os.path.join(folder, f"alpha{n}_{'opaque' if opaque else 'masked'}.json")
    with open(path, "w") as f:
        json.dump(doc, f)
    return path, tris


def figures(s):
    rays = s["rays"]["total"]
    by = s["bandwidth"]["dram"]["by_region"]
    dram = sum(r["read_bytes"] + r["write_bytes"] for r in by.values())
    units = s["units"]
    return {"rays": rays, "hits": sum(s["rays"]["hits_by_kind"].values()),
            "cycles": s["total_cycles"], "steps": s["rays"]["steps"],
            "dram_bytes_per_ray": dram / rays,
            "instance_bytes_per_ray": by.get("instances", {}).get("read_bytes", 0) / rays,
            "l2_hit_rate": s["caches"]["l2"]["hit_rate"],
            "box_util": units["box_unit_total"]["utilization"],
            "transform_util": units.get("transform_unit_total", {}).get("utilization", 0.0),
            "any_hit_calls": units.get("any_hit_shader_total", {}).get("ops", 0),
            "any_hit_stall_share": s["stalls"]["total"]["share"].get("any_hit_shader", 0.0),
            "alpha_bytes_per_ray": by.get("alpha", {}).get("read_bytes", 0) / rays,
            "prepare_s": s["host"]["prepare_s"], "peak_rss_mib": s["host"]["peak_rss_mib"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtsim", default=os.path.join(ROOT, "build", "rtsim"))
    ap.add_argument("--mesh", default="armadillo")
    ap.add_argument("--grids", default="2,4,8")
    ap.add_argument("--res", default="256x256")
    ap.add_argument("--rays", default="primary,ao")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    ap.add_argument("--alpha-grid", type=int, default=4)
    ap.add_argument("--shader-latencies", default="5,20,80,320")
    ap.add_argument("--assets", default="CesiumMilkTruck.gltf,2CylinderEngine.glb")
    a = ap.parse_args()
    mesh = SCENES.get(a.mesh, a.mesh)
    if not mesh.endswith(".off"):
        sys.exit(f"bench_instancing: --mesh needs an OFF mesh, got {mesh}")
    common = ["--res", a.res, "--rays", a.rays, "--bvh-cache", "off"]
    for kv in a.set:
        common += ["--set", kv]
    rows, cells, files = [], [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in (int(g) for g in a.grids.split(",")):
            scene, flat, tris = files[n] = grid_files(mesh, n, tmp)
            got = {}
            for kind, path in (("instanced", scene), ("flattened", flat)):
                s = run_stats(a.rtsim, common + ["--scene", path],
                              os.path.join(tmp, f"{kind}{n}"), "bench_instancing")
                got[kind] = figures(s)
                cells.append({"grid": n, "kind": kind, **got[kind]})
            i, f = got["instanced"], got["flattened"]
            rows.append(f"| {n}x{n} | {tris * n * n:,} | {i['hits']} / {f['hits']}"
                        f" | {i['steps'] / i['rays']:.1f} / {f['steps'] / f['rays']:.1f}"
                        f" | {i['prepare_s']:.2f} / {f['prepare_s']:.2f}"
                        f" | {i['peak_rss_mib']:.0f} / {f['peak_rss_mib']:.0f}"
                        f" | {i['cycles'] / f['cycles']:.3f}"
                        f" | {i['dram_bytes_per_ray']:.1f} / {f['dram_bytes_per_ray']:.1f}"
                        f" | {i['instance_bytes_per_ray']:.2f}"
                        f" | {100 * i['l2_hit_rate']:.1f}% / {100 * f['l2_hit_rate']:.1f}%"
                        f" | {100 * i['box_util']:.1f}% / {100 * f['box_util']:.1f}%"
                        f" | {100 * i['transform_util']:.2f}% |")
            print(rows[-1], flush=True)
        # Treelet queues at the largest grid.
        treelet_rows = []
        n = max(files)
        scene, flat, tris = files[n]  # written by the grid loop above
        tl = ["--config", os.path.join(ROOT, "configs", "treelet.json"),
              "--set", "traversal.treelet_prefetch=true"]
        for kind, path in (("instanced", scene), ("flattened", flat)):
            s = run_stats(a.rtsim, common + tl + ["--scene", path],
                          os.path.join(tmp, f"treelet_{kind}"), "bench_instancing")
            f = figures(s)
            rb = s["ray_buffer"]
            f.update(treelets=s["bvh"]["layout"]["treelets"], loads=rb["treelet_loads"],
                     crossings=rb["crossings_per_ray"])
            cells.append({"treelet_grid": n, "kind": kind, **f})
            treelet_rows.append(
                f"| {kind} | {f['treelets']:,} | {f['hits']} | {f['cycles']:,}"
                f" | {f['dram_bytes_per_ray']:.1f} | {f['loads']:,} | {f['crossings']:.2f} |")
            print(treelet_rows[-1], flush=True)
        # The alpha-tested grid: opaque, then masked at each shader latency, then without reads.
        n = a.alpha_grid
        opaque_scene, tris = alpha_grid_file(mesh, n, tmp, True)
        masked_scene, _ = alpha_grid_file(mesh, n, tmp, False)
        runs = [("opaque", opaque_scene, [])]
        for lat in (int(x) for x in a.shader_latencies.split(",")):
            runs.append((f"latency {lat}", masked_scene,
                         ["--set", f"any_hit_shader.latency_cycles={lat}"]))
        runs.append(("latency 20, no alpha read", masked_scene,
                     ["--set", "any_hit_shader.alpha_read_bytes=0"]))
        alpha_rows, base = [], None
        for label, path, extra in runs:
            s = run_stats(a.rtsim, common + ["--scene", path] + extra,
                          os.path.join(tmp, "alpha_" + label.replace(" ", "_").replace(",", "")),
                          "bench_instancing")
            f = figures(s)
            cells.append({"alpha_grid": n, "case": label, **f})
            base = base or f
            alpha_rows.append(
                f"| {label} | {f['any_hit_calls'] / f['rays']:.2f} | {f['hits']}"
                f" | {f['steps'] / f['rays']:.1f}"
                f" | {f['cycles']:,} | {f['cycles'] / base['cycles']:.3f}"
                f" | {100 * f['any_hit_stall_share']:.1f}%"
                f" | {f['alpha_bytes_per_ray']:.2f} | {f['dram_bytes_per_ray']:.1f} |")
            print(alpha_rows[-1], flush=True)
        asset_rows = []
        for name in a.assets.split(","):
            path = os.path.join(ROOT, ".cache", "meshes", "assimp", name)
            if not os.path.exists(path):
                sys.exit(f"bench_instancing: {path} missing; run scripts/setup.sh")
            got = {}
            for kind, extra in (("instanced", []), ("flattened", ["--flatten"])):
                s = run_stats(a.rtsim, common + ["--scene", path] + extra,
                              os.path.join(tmp, f"asset_{kind}_{name}"), "bench_instancing")
                got[kind] = figures(s)
                got[kind]["scene"] = s["scene"]
                cells.append({"asset": name, "kind": kind, **got[kind]})
            i, f = got["instanced"], got["flattened"]
            sc = i["scene"]
            asset_rows.append(
                f"| {name} | {sc['meshes']} / {sc['instances']} | {sc['triangles']:,} / "
                f"{sc['instanced_triangles']:,} | {i['hits']} / {f['hits']}"
                f" | {i['steps'] / i['rays']:.1f} / {f['steps'] / f['rays']:.1f}"
                f" | {i['cycles'] / f['cycles']:.3f}"
                f" | {i['dram_bytes_per_ray']:.1f} / {f['dram_bytes_per_ray']:.1f}"
                f" | {100 * i['transform_util']:.2f}% |")
            print(asset_rows[-1], flush=True)
    text = (f"# Instanced against flattened (scripts/bench_instancing.py)\n\n"
            f"{a.mesh} in N x N grids, {a.res}, rays {a.rays}, default chip"
            f"{' with ' + ' '.join(a.set) if a.set else ''}; each pair of figures is instanced / "
            f"flattened (one mesh of all the copies). Prepare: scene reading and BVH builds, "
            f"no cache. Cycles: instanced over flattened.\n\n"
            "| grid | triangles (flattened) | hits | steps/ray | prepare s | peak MiB "
            "| cycles ratio | "
            "DRAM B/ray | instance records B/ray | L2 hit rate | box unit busy | "
            "transform unit busy |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n"
            + "\n".join(rows) + "\n\n"
            f"## Treelet queues ({a.mesh} {max(int(g) for g in a.grids.split(','))}x"
            f"{max(int(g) for g in a.grids.split(','))}, configs/treelet.json with prefetch)\n\n"
            "Instanced: the TLAS and every BLAS cut into treelets of their own (the TLAS's "
            "holding their leaves' instance records); flattened: the one mesh's tree cut.\n\n"
            "| scene | treelets | hits | cycles | DRAM B/ray | treelet loads | crossings/ray |\n"
            "|---|---|---|---|---|---|---|\n" + "\n".join(treelet_rows) + "\n\n"
            f"## Alpha-tested ({a.mesh} {n}x{n}, {tris * n * n:,} instanced triangles)\n\n"
            "The grid's mesh cut out by a checker alpha mask (2 x 2 squares per triangle in "
            "barycentric space), so every candidate hit runs the any-hit shader "
            "(core.any_hit_step_instructions 8, a 16-byte alpha read, then the shader's latency), "
            "against the same instances opaque. Cycles ratio: over the opaque run.\n\n"
            "| case | any-hit calls/ray | hits | steps/ray | cycles | cycles ratio "
            "| any-hit shader stall share | alpha DRAM B/ray | DRAM B/ray |\n"
            "|---|---|---|---|---|---|---|---|---|\n"
            + "\n".join(alpha_rows) + "\n\n"
            "## Real assets (assimp-testmodels)\n\n"
            "glTF files whose nodes share meshes, read as instances / with --flatten (one mesh). "
            "Cycles: instanced over flattened. The rays are not quite the same: the camera "
            "frames the scene's bounds, which for instances are their world boxes (looser than "
            "the triangles when a part is rotated), so hits differ by a few percent.\n\n"
            "| asset | meshes / instances | unique / instanced triangles | hits | steps/ray "
            "| cycles ratio | DRAM B/ray | transform unit busy |\n"
            "|---|---|---|---|---|---|---|---|\n"
            + "\n".join(asset_rows) + "\n")
    write_results(a.out, "instancing", text, cells)


if __name__ == "__main__":
    main()

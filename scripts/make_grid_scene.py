#!/usr/bin/env python3
"""Tiles a triangle mesh (OFF) N x N on a grid in the XZ plane, as one OFF file: a scene whose
BVH outgrows the L2 by a chosen factor while keeping the mesh's local structure (the treelet
study, bench/results/treelets.md, uses a 3x3 grid of libcgal-demo's refined_elephant.off), or a
big scene for build and memory tests (11x11 refined elephants: 10.8M triangles). With OUT.json
it writes the same grid as a scene file of N*N instances of the mesh instead (docs/scenes.md):
100x100 elephants are 889M instanced triangles in a file of a few hundred bytes.

    scripts/make_grid_scene.py MESH.off N OUT.off|OUT.json

Copies are 1.1 mesh extents apart, so rays between them see open space as well as geometry.
"""
import json
import os
import sys


def read_off(path):
    words = []
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if line:
                words.extend(line.split())
    if not words or not words[0].endswith("OFF"):
        sys.exit(f"{path}: not an OFF file")
    pos = 1
    nv, nf = int(words[pos]), int(words[pos + 1])
    pos += 3
    verts = []
    for _ in range(nv):
        verts.append(tuple(float(x) for x in words[pos:pos + 3]))
        pos += 3
    faces = []
    for _ in range(nf):
        k = int(words[pos])
        idx = [int(x) for x in words[pos + 1:pos + 1 + k]]
        pos += 1 + k
        for j in range(1, k - 1):  # fan-triangulate polygons
            faces.append((idx[0], idx[j], idx[j + 1]))
    return verts, faces


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    src, n, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    if n < 1:
        sys.exit(f"N: expected at least 1, got {n}")
    verts, faces = read_off(src)
    lo = [min(v[a] for v in verts) for a in range(3)]
    hi = [max(v[a] for v in verts) for a in range(3)]
    step_x, step_z = 1.1 * (hi[0] - lo[0]), 1.1 * (hi[2] - lo[2])
    if out.endswith(".json"):
        scene = {"meshes": {"m": os.path.abspath(src)},
                 "instances": [{"mesh": "m", "grid": {"count": [n, 1, n],
                                                      "spacing": [step_x, 0, step_z]}}]}
        with open(out + ".tmp", "w") as f:
            json.dump(scene, f, indent=1)
        os.replace(out + ".tmp", out)
        print(f"{out}: {n}x{n} instances of {src}, {len(faces) * n * n} instanced triangles")
        return
    lines = ["OFF", f"{len(verts) * n * n} {len(faces) * n * n} 0"]
    for i in range(n):
        for k in range(n):
            dx, dz = i * step_x, k * step_z
            lines.extend(f"{x + dx:.7g} {y:.7g} {z + dz:.7g}" for x, y, z in verts)
    for c in range(n * n):
        base = c * len(verts)
        lines.extend(f"3 {a + base} {b + base} {d + base}" for a, b, d in faces)
    tmp = out + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(tmp, out)
    print(f"{out}: {n}x{n} copies of {src}, {len(faces) * n * n} triangles")


if __name__ == "__main__":
    main()

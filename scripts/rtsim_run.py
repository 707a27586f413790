"""Shared by the benchmark scripts: the scenes they know by name, and one `rtsim run` whose
stats.json is returned."""
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CGAL = os.path.join(ROOT, ".cache", "meshes", "cgal")  # scripts/setup.sh unpacks libcgal-demo here
# Built-in scenes, glmark2-data's bunny and libcgal-demo's meshes (closed ones).
SCENES = {"cornell": "builtin:cornell", "sphere": "builtin:sphere",
          "bunny": "/usr/share/glmark2/models/bunny.obj"}
SCENES.update({m: os.path.join(CGAL, m + ".off")
               for m in ("armadillo", "camel", "elephant", "homer", "turbine")})


def run_stats(rtsim, args, out, who, prefix=()):
    """Runs `rtsim run -q --out OUT ARGS` (after `prefix`, e.g. a taskset command); exits naming
    `who` if it fails."""
    cmd = list(prefix) + [rtsim, "run", "-q", "--out", out] + args
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{who}: {' '.join(cmd)} failed: {r.stderr.strip()}")
    with open(os.path.join(out, "stats.json")) as f:
        return json.load(f)


def write_results(out_dir, name, text, data):
    """Writes a benchmark's summary to OUT_DIR/NAME.md and its cells to OUT_DIR/NAME.json."""
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, name + ".md"), "w") as f:
        f.write(text)
    with open(os.path.join(out_dir, name + ".json"), "w") as f:
        json.dump(data, f, indent=1)

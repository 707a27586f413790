"""Shared by the benchmark scripts: one `rtsim run` whose stats.json is returned."""
import json
import os
import subprocess
import sys


def run_stats(rtsim, args, out, who, prefix=()):
    """Runs `rtsim run -q --out OUT ARGS` (after `prefix`, e.g. a taskset command); exits naming
    `who` if it fails."""
    cmd = list(prefix) + [rtsim, "run", "-q", "--out", out] + args
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{who}: {' '.join(cmd)} failed: {r.stderr.strip()}")
    with open(os.path.join(out, "stats.json")) as f:
        return json.load(f)

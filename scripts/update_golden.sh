#!/usr/bin/env bash
# Regenerates the golden stats that tests/e2e compare against, one file per case of
# tests/golden/cases.json (the arguments of each case's `rtsim run`). Run it only for a
# deliberate change of simulated behaviour: it prints each file's diff before writing it, and
# the commit message says why the numbers moved.
set -euo pipefail
cd "$(dirname "$0")/.."
rtsim="${1:-build/rtsim}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
python3 - "$rtsim" "$tmp" <<'PY'
import json, os, subprocess, sys
rtsim, tmp = sys.argv[1], sys.argv[2]
cases = json.load(open("tests/golden/cases.json"))
for name, args in cases.items():
    out = os.path.join(tmp, name)
    subprocess.run([rtsim, "run", "-q"] + args + ["--out", out], check=True)
    s = json.load(open(os.path.join(out, "stats.json")))
    for k in ("host", "rtsim_version"):
        s.pop(k, None)
    with open(os.path.join(tmp, name + ".json"), "w") as f:
        json.dump(s, f, indent=1, sort_keys=True)
        f.write("\n")
PY
for name in $(python3 -c 'import json; print(" ".join(json.load(open("tests/golden/cases.json"))))'); do
    golden="tests/golden/$name.json"
    [ -f "$golden" ] || : > "$golden"
    # The diff is what a reviewer reads: every moved figure needs a reason in the commit message.
    if diff -u "$golden" "$tmp/$name.json"; then
        echo "$golden: unchanged"
    else
        cp "$tmp/$name.json" "$golden"
        echo "updated $golden (diff above)"
    fi
done

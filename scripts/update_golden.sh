#!/usr/bin/env bash
# Regenerates the golden stats that tests/e2e compare against. Run it only for a deliberate
# change of simulated behaviour, and say in the commit message why the numbers moved.
set -euo pipefail
cd "$(dirname "$0")/.."
rtsim="${1:-build/rtsim}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
# Keep these arguments in sync with Golden.CornellSmall in tests/e2e/test_run.cpp.
"$rtsim" run -q --rays primary,shadow,ao --res 32x32 --set core.count=2 --out "$tmp"
python3 - "$tmp/stats.json" "$tmp/golden.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
for k in ("host", "rtsim_version"):
    s.pop(k, None)
json.dump(s, open(sys.argv[2], "w"), indent=1, sort_keys=True)
open(sys.argv[2], "a").write("\n")
PY
# The diff is what a reviewer reads: every moved figure needs a reason in the commit message.
if diff -u tests/golden/cornell_small.json "$tmp/golden.json"; then
    echo "tests/golden/cornell_small.json: unchanged"
else
    cp "$tmp/golden.json" tests/golden/cornell_small.json
    echo "updated tests/golden/cornell_small.json (diff above)"
fi

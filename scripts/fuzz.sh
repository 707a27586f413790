#!/usr/bin/env bash
# Fuzzes the input readers: each libFuzzer target (fuzz/) runs SECONDS (default 10) from its seed
# corpus (fuzz/corpus/<target>, in the repository), built first in build-fuzz with clang, ASan and
# UBSan. The test command runs it for a few seconds per target; run it longer by hand:
#     scripts/fuzz.sh 600
# A crash, a hang (over 10 s per input) or a blow-up (over 2 GiB) fails the script and leaves the
# input in build-fuzz/crashes/<target>/: make it a regression test, then fix it.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-10}"
dir="${FUZZ_BUILD_DIR:-build-fuzz}"
targets=(off ray_file trace config sweep mesh)
# -O1 -g1 by default, as libFuzzer advises: fast enough to fuzz, symbols for the reports
# (FUZZ_CXX_FLAGS to change it; build type None, so that no build type's -O3 follows them).
flags="${FUZZ_CXX_FLAGS:--O1 -g1}"
CC=clang CXX=clang++ cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=None -DCMAKE_CXX_FLAGS="$flags" \
    -DRTSIM_FUZZ=ON -DRTSIM_BUILD_TESTS=OFF >/dev/null
cmake --build "$dir" -j"$(nproc)" --target "${targets[@]/#/fuzz_}" >/dev/null
# No LeakSanitizer: it needs to stop the process's threads the way a debugger does, which
# containers may deny (it then fails the run after the fuzzing itself passed). Unbounded memory
# is caught by the RSS and malloc limits instead.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=0}"
# The targets' scratch inputs (fuzz/fuzz_input.h) stay in the build folder, also after a crash.
export TMPDIR="$(cd "$dir" && pwd)/scratch"
mkdir -p "$TMPDIR"
for t in "${targets[@]}"; do
    mkdir -p "$dir/corpus/$t" "$dir/crashes/$t"
    # New inputs go to the first folder (build-fuzz/corpus); the seeds are read only.
    if ! "$dir/fuzz_$t" "$dir/corpus/$t" "fuzz/corpus/$t" -max_total_time="$seconds" \
        -max_len=65536 -rss_limit_mb=2048 -malloc_limit_mb=1024 -timeout=10 \
        -artifact_prefix="$dir/crashes/$t/" \
        >"$dir/fuzz_$t.log" 2>&1; then
        echo "[fuzz] fuzz_$t failed: see $dir/fuzz_$t.log and $dir/crashes/$t/" >&2
        tail -n 30 "$dir/fuzz_$t.log" >&2
        exit 1
    fi
    echo "[fuzz] fuzz_$t: $(grep -o 'Done [0-9]* runs in [0-9]* second(s)' "$dir/fuzz_$t.log" | tail -1), no crash"
done

#!/usr/bin/env python3
"""Mutation check of the timing rules: does the test suite notice when a scheduling rule breaks?

Each mutant below changes one rule of the memory system's timing (tie order within a cycle,
first come first served at the MSHRs, merging misses to a line in flight, bank conflicts,
crossbar contention, write-buffer stalls) in the engine that holds it. For each, the script
applies the change to a scratch copy of the tree (a git worktree of HEAD), builds it, runs the
whole ctest suite, and reports which tests failed: a mutant no test kills is a rule the suite
does not check.

    scripts/mutants.py [--work DIR] [-j 2] [--only NAME,...] [--out bench/results]

--work keeps the worktree and its build between runs (the first build is a full one). Writes
bench/results/mutants.md.
"""
import argparse
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rtsim_run import ROOT, write_results  # noqa: E402

# name, rule, engine, file, text to find (exactly once), its replacement.
MUTANTS = [
    ("fills_not_first", "tie order", "accurate", "models/fidelity/accurate.cpp",
     "uint64_t order = type == kFillDone ? 0 : 1;",
     "uint64_t order = 1;"),
    ("mshr_lifo", "FCFS at MSHRs", "accurate", "models/fidelity/accurate.cpp",
     "const uint32_t next = st.waiting.front();\n            st.waiting.pop_front();",
     "const uint32_t next = st.waiting.back();\n            st.waiting.pop_back();"),
    ("mshr_unlimited", "MSHR limit", "fast", "models/cache_impl.h",
     "issue_at = std::max(lookup_done, earliest_mshr());",
     "issue_at = lookup_done + 0 * earliest_mshr();"),
    ("merge_without_wait", "merge", "accurate", "models/fidelity/accurate.cpp",
     "if (it != caches_[cs].in_flight.end()) {  // still filling",
     "if (false && it != caches_[cs].in_flight.end()) {  // still filling"),
    ("hit_on_fill_without_wait", "merge", "fast", "models/cache.h",
     "merged_misses += ready > lookup_done;  // no branch: which lines are still filling is "
     "random\n        return ready;",
     "merged_misses += ready > lookup_done;  // no branch: which lines are still filling is "
     "random\n        return lookup_done + 0 * ready;"),
    ("multi_line_hit_on_fill_without_wait", "merge", "fast", "models/cache_impl.h",
     "slowest.hit(lookup_done, ready, line_addr);\n        return std::max(lookup_done, ready);",
     "slowest.hit(lookup_done, lookup_done, line_addr);\n        return lookup_done + 0 * ready;"),
    ("no_bank_conflicts", "bank conflicts", "both", "models/cache.h",
     "const Cycle start = banks_[first & bank_mask_].reserve(now, lines);",
     "const Cycle start = now + 0 * banks_[first & bank_mask_].reserve(now, lines);"),
    ("crossbar_without_queue", "crossbar contention", "both", "models/crossbar.cpp",
     "const auto [first, end] = link_.transfer(returned, size_bytes);\n    ++transfers;",
     "const auto [first0, end0] = link_.transfer(returned, size_bytes);\n"
     "    const Cycle first = returned, end = end0 - (first0 - returned);\n    ++transfers;"),
    ("write_buffer_never_full_fast", "write-buffer stall", "fast", "models/core.h",
     "if (write_buffer_.empty()) return t;",
     "if (write_buffer_.empty() || true) return t;"),
    ("write_buffer_never_full_accurate", "write-buffer stall", "accurate",
     "models/fidelity/accurate.cpp",
     "return n > 0 && states_[c].writes_in_flight >= n;",
     "return false && n > 0 && states_[c].writes_in_flight >= n;"),
]


def run(cmd, cwd, **kw):
    return subprocess.run(cmd, cwd=cwd, text=True, capture_output=True, **kw)


def failing_tests(build, jobs):
    """The names of the ctest tests that failed (empty: all passed)."""
    r = run(["ctest", "-j", str(jobs), "--timeout", "300"], build)
    failed = []
    for line in r.stdout.splitlines():
        # "  123 - Suite.Name (Failed)" in ctest's closing list
        parts = line.strip().split(" - ", 1)
        if len(parts) == 2 and parts[0].isdigit() and "(" in parts[1]:
            failed.append(parts[1].rsplit(" (", 1)[0])
    if r.returncode != 0 and not failed:
        raise RuntimeError("ctest failed without naming a test:\n" + r.stdout[-2000:])
    return failed


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", help="worktree folder to create or reuse (default: a temporary one)")
    ap.add_argument("-j", type=int, default=2)
    ap.add_argument("--only", help="comma-separated mutant names")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    a = ap.parse_args(argv)
    mutants = [m for m in MUTANTS if not a.only or m[0] in a.only.split(",")]
    if not mutants:
        sys.exit(f"mutants.py: no mutant named {a.only}")
    tmp = None
    work = a.work
    if not work:
        tmp = tempfile.TemporaryDirectory()
        work = os.path.join(tmp.name, "tree")
    head = run(["git", "rev-parse", "HEAD"], ROOT).stdout.strip()
    if not os.path.exists(work):
        r = run(["git", "worktree", "add", "--detach", work, head], ROOT)
        if r.returncode != 0:
            sys.exit(f"mutants.py: git worktree add {work}: {r.stderr.strip()}")
    else:
        run(["git", "checkout", "--detach", "-f", head], work)
    build = os.path.join(work, "build")
    # The meshes scripts/setup.sh fetched (not in git): the tests read them from the tree.
    cache = os.path.join(work, ".cache")
    if not os.path.exists(cache) and os.path.isdir(os.path.join(ROOT, ".cache")):
        os.symlink(os.path.join(ROOT, ".cache"), cache)
    try:
        for m in mutants:  # every mutant's text is there once before anything is built
            text = open(os.path.join(work, m[3])).read()
            if text.count(m[4]) != 1:
                sys.exit(f"mutants.py: {m[3]}: the text of mutant {m[0]} is not there once")
        r = run(["cmake", "-S", work, "-B", build, "-DCMAKE_BUILD_TYPE=Release"], work)
        if r.returncode != 0:
            sys.exit("mutants.py: cmake failed:\n" + r.stderr[-2000:])

        def build_all():
            r = run(["cmake", "--build", build, "-j", str(a.j)], work)
            if r.returncode != 0:
                raise RuntimeError("build failed:\n" + (r.stdout + r.stderr)[-3000:])

        print("mutants.py: building the unmutated tree", file=sys.stderr)
        build_all()
        baseline = failing_tests(build, a.j)
        if baseline:
            sys.exit(f"mutants.py: the unmutated suite fails: {baseline}")
        rows = []
        for name, rule, engine, path, old, new in mutants:
            full = os.path.join(work, path)
            original = open(full).read()
            try:
                open(full, "w").write(original.replace(old, new))
                print(f"mutants.py: {name} ({engine}): building and testing", file=sys.stderr)
                build_all()
                failed = failing_tests(build, a.j)
            finally:
                open(full, "w").write(original)
            rows.append((name, rule, engine, path, failed))
            print(f"  {'killed' if failed else 'SURVIVED'} by {len(failed)} tests",
                  file=sys.stderr)
        build_all()  # the worktree's build back to HEAD for the next use
    finally:
        if tmp:
            run(["git", "worktree", "remove", "--force", work], ROOT)
            tmp.cleanup()
    lines = ["# Mutation check of the timing rules (scripts/mutants.py)", "",
             f"Tree {head[:12]}; each mutant built and run against the whole ctest suite.", "",
             "| mutant | rule | engine | file | killed | tests that failed |",
             "|---|---|---|---|---|---|"]
    for name, rule, engine, path, failed in rows:
        shown = ", ".join(failed[:4]) + (f" and {len(failed) - 4} more" if len(failed) > 4 else "")
        lines.append(f"| {name} | {rule} | {engine} | {path} | {'yes' if failed else 'NO'} | "
                     f"{len(failed)}: {shown} |")
    survived = [r[0] for r in rows if not r[4]]
    lines += ["", f"{len(rows) - len(survived)} of {len(rows)} killed" +
              (f"; survived: {', '.join(survived)}" if survived else ".")]
    text = "\n".join(lines) + "\n"
    write_results(a.out, "mutants", text, {"head": head, "rows": [
        {"name": r[0], "rule": r[1], "engine": r[2], "file": r[3], "failed": r[4]}
        for r in rows]})
    print(text)
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main())

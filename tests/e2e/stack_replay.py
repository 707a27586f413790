#!/usr/bin/env python3
"""Independent model of short-stack traffic, for tests/e2e/test_write_traffic.cpp.

Reads a trace with scripts/rtt_reader.py and replays each ray's recorded stack depths against a
short stack of N entries, as docs/config.md describes core.short_stack_entries: the top N
entries on chip; pushes beyond N write the oldest out; a pop that finds the short stack empty
reads entries back (what the pops need, topping it up to N) in one read. Prints JSON totals.
Written apart from models/short_stack.h, keeping the entries as an explicit list.
"""
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "scripts"))
import rtt_reader  # noqa: E402


def replay(steps, n):
    on_chip, memory = [], []  # entries, bottom first
    spills = refills = spilled_entries = refilled_entries = 0
    for _kind, _count, _id, depth, popped in steps:
        before_pop = depth + (1 if popped else 0)
        # Entries pushed since the last step (or popped, when culled pops outnumber them).
        while len(on_chip) + len(memory) < before_pop:
            on_chip.append("e")
        if len(on_chip) > n:
            out = len(on_chip) - n
            memory.extend(on_chip[:out])
            on_chip = on_chip[out:]
            spills += 1
            spilled_entries += out
        pops = len(on_chip) + len(memory) - depth
        if pops > len(on_chip) and memory:
            need = min(pops - len(on_chip), len(memory))
            back = min(len(memory), max(need, n - len(on_chip)))
            on_chip = memory[len(memory) - back:] + on_chip
            memory = memory[:len(memory) - back]
            refills += 1
            refilled_entries += back
        for _ in range(min(pops, len(on_chip))):
            on_chip.pop()
    return spills, spilled_entries, refills, refilled_entries


def main():
    path, n = sys.argv[1], int(sys.argv[2])
    t = rtt_reader.Trace(path)
    total = [0, 0, 0, 0]
    for _ray, _kind, steps, _prim, _t in t.records():
        for i, v in enumerate(replay(steps, n)):
            total[i] += v
    print(json.dumps({"spills": total[0], "spilled_entries": total[1], "refills": total[2],
                      "refilled_entries": total[3]}))


if __name__ == "__main__":
    main()

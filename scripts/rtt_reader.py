#!/usr/bin/env python3
"""Minimal, independent reader of RTSim trace files (docs/trace-format.md), for other tools.

    scripts/rtt_reader.py TRACE.rtt            # summary: header, rays and steps per kind
    scripts/rtt_reader.py TRACE.rtt --json     # the same as JSON
    scripts/rtt_reader.py TRACE.rtt --dump N   # the first N rays, decoded

Uses the `zstandard` module when installed, otherwise the `zstd` command-line tool.
"""
import argparse
import json
import struct
import subprocess
import sys
import zlib

STEP_KINDS = ["node", "triangle", "transform", "any_hit"]  # by kind number (workloads/step.h)
KINDS = ["primary", "shadow", "ao", "diffuse", "reflection"]


class TraceError(Exception):
    pass


def decompress(data, size):
    try:
        import zstandard
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    except ImportError:
        r = subprocess.run(["zstd", "-d", "-q", "-c"], input=data, capture_output=True)
        if r.returncode != 0:
            raise TraceError("zstd could not decompress a chunk")
        return r.stdout


def read_varint(buf, pos):
    value, shift = 0, 0
    while True:
        if pos >= len(buf):
            raise TraceError("record truncated")
        b = buf[pos]
        pos += 1
        value |= (b & 0x7F) << shift
        if not b & 0x80:
            return value, pos
        shift += 7


def unzigzag(v):
    return (v >> 1) ^ -(v & 1)


class Trace:
    def __init__(self, path):
        with open(path, "rb") as f:
            self.data = f.read()
        d = self.data
        if len(d) < 40 or d[:8] != b"RTSIMTRC":
            raise TraceError(f"{path}: not an RTSim trace")
        self.version, flags, meta_len = struct.unpack_from("<III", d, 8)
        if self.version not in (1, 2, 3, 4) or flags != 0:
            raise TraceError(f"{path}: unsupported version {self.version} or flags {flags}")
        meta = d[20:20 + meta_len]
        (crc,) = struct.unpack_from("<I", d, 20 + meta_len)
        if zlib.crc32(meta) != crc:
            raise TraceError(f"{path}: header metadata checksum mismatch")
        self.metadata = json.loads(meta)
        layout = self.metadata.get("bvh", {}).get("layout", {})
        self.has_instances = self.version >= 4 and layout.get("instance_count", 0) > 0
        if d[-8:] != b"RTSIMEND":
            raise TraceError(f"{path}: footer missing")
        (index_offset,) = struct.unpack_from("<Q", d, len(d) - 16)
        if d[index_offset:index_offset + 4] != b"INDX":
            raise TraceError(f"{path}: index missing")
        n, self.rays, self.steps = struct.unpack_from("<IQQ", d, index_offset + 4)
        body = d[index_offset + 4:index_offset + 24 + 16 * n]
        (crc,) = struct.unpack_from("<I", d, index_offset + 24 + 16 * n)
        if zlib.crc32(body) != crc:
            raise TraceError(f"{path}: index checksum mismatch")
        self.chunks = [struct.unpack_from("<QI", d, index_offset + 24 + 16 * k) for k in range(n)]

    def chunk(self, k):
        """Yields (ray_id, kind, steps, prim, t) for chunk k; steps are (kind, count, id, stack depth, popped)."""
        offset, rays = self.chunks[k]
        d = self.data
        if d[offset:offset + 4] != b"CHNK":
            raise TraceError(f"chunk {k}: wrong magic")
        number, n, raw_size, comp_size, crc = struct.unpack_from("<IIIII", d, offset + 4)
        payload = d[offset + 24:offset + 24 + comp_size]
        if number != k or n != rays or zlib.crc32(payload) != crc:
            raise TraceError(f"chunk {k}: damaged")
        raw = decompress(payload, raw_size)
        pos, last_id = 0, 0
        for _ in range(n):
            v, pos = read_varint(raw, pos)
            last_id += unzigzag(v)
            kind = raw[pos]
            pos += 1
            count, pos = read_varint(raw, pos)
            prev = [0] * len(STEP_KINDS)
            depth = 0
            steps = []
            for _ in range(count):
                b = raw[pos]
                pos += 1
                if self.version == 1:  # bit 0 the kind, bits 1-7 the count
                    sk, n = b & 1, b >> 1
                else:  # low 4 bits the kind, high 4 the count (15: plus a varint)
                    sk, n = b & 15, b >> 4
                    if n == 15:
                        extra, pos = read_varint(raw, pos)
                        n += extra
                    if sk >= len(STEP_KINDS):
                        raise TraceError(f"chunk {k}: unknown step kind {sk}")
                v, pos = read_varint(raw, pos)
                prev[sk] += unzigzag(v)
                popped = False
                if self.version >= 3:  # zz(change of stack depth) << 1 | popped
                    v, pos = read_varint(raw, pos)
                    depth += unzigzag(v >> 1)
                    popped = bool(v & 1)
                    if not 0 <= depth <= 127:
                        raise TraceError(f"chunk {k}: stack depth {depth} outside 0..127")
                steps.append((STEP_KINDS[sk], n, prev[sk], depth, popped))
            prim, pos = read_varint(raw, pos)
            t = None
            if prim:
                (t,) = struct.unpack_from("<f", raw, pos)
                pos += 4
                if self.has_instances:  # version 4, two-level: the instance hit, plus one
                    _, pos = read_varint(raw, pos)
            yield last_id, KINDS[kind], steps, prim - 1 if prim else -1, t
        if pos != len(raw):
            raise TraceError(f"chunk {k}: trailing bytes")

    def records(self):
        for k in range(len(self.chunks)):
            yield from self.chunk(k)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("trace")
    p.add_argument("--json", action="store_true")
    p.add_argument("--dump", type=int, default=0)
    a = p.parse_args()
    try:
        t = Trace(a.trace)
        if a.dump:
            for i, (ray, kind, steps, prim, dist) in enumerate(t.records()):
                if i == a.dump:
                    break
                print(f"ray {ray} {kind}: {len(steps)} steps, prim {prim}, t {dist}")
                for s in steps:
                    print(f"    {s[0]} {s[2]} ({s[1]})")
            return
        by_kind = {}
        for ray, kind, steps, prim, dist in t.records():
            k = by_kind.setdefault(kind, {"rays": 0, "hits": 0, "node_steps": 0, "triangle_steps": 0})
            k["rays"] += 1
            k["hits"] += prim >= 0
            for s in steps:  # as rtsim trace-info counts them (two-level kinds when present)
                name = s[0] + "_steps"
                k[name] = k.get(name, 0) + 1
        summary = {"format_version": t.version, "chunks": len(t.chunks), "rays": t.rays, "steps": t.steps,
                   "scene": t.metadata.get("scene", {}).get("name"), "by_kind": by_kind}
        if a.json:
            print(json.dumps(summary, indent=2, sort_keys=True))
        else:
            print(f"{a.trace}: version {t.version}, {len(t.chunks)} chunks, {t.rays} rays, {t.steps} steps, "
                  f"scene {summary['scene']}")
            for kind, k in sorted(by_kind.items()):
                print(f"  {kind:10} {k['rays']} rays, {k['hits']} hits, {k['node_steps']} node steps, "
                      f"{k['triangle_steps']} triangle steps")
    except TraceError as e:
        sys.exit(f"rtt_reader: {e}")


if __name__ == "__main__":
    main()

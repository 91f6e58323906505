"""The two trace readers held to each other (docs/spec.md 12.2, 13).

Every checked-in malformed trace, every checked-in trace, and a set of
generated variants (lines of the checked-in traces with tokens replaced,
characters inserted or deleted, keys duplicated, lines swapped or cut) go
through both readers. Each must give the same verdict: a refusal on the same
line with the same error kind (the messages are each reader's own), or the
same parsed trace. The painter writes its verdict as JSON arrays
(`octopaint check --canonical`); they are compared here by value, floats bit
for bit, never by their text.

Variants are pseudo-random by hashing an index (lowbias32), so a failing one
can be rebuilt from its number in any language.
"""

from __future__ import annotations

import glob
import json
import os
import re
import struct
import subprocess

from octopaint_ref.trace import TraceError, read_trace

LITERALS = [
    "NaN", "Infinity", "-Infinity", "1e999", "-1e999", "-0.0", "-0", "0", "1", "-1", "1e-320", "2.2250738585072014e-308",
    "4.5", "1e300", "1e+300", "2.0", "65536", "65537", "4294967288", "4294967296", "1" + "0" * 30, "0.1", "1e-09",
    "true", "false", "null", '"x"', '""', "[]", "{}", "[1, 2]", "[0, 0, 0]", "[0, 0, 0, 0]", '"\\ud800"', '"\\u00e9"',
    '"sphere"', '"erase"', '"undo"', '"redo"', '"render"', '"a\\n"', '".."', "1.7976931348623157e308",
]
ALPHABET = list('{}[],:"\\ 0123456789eE+-.ntfNIau') + ["\x01", "\x1c", "\x85", "\xa0", "\u2028", "\ufeff", "é", "\t"]
EVENTS = ["brush", "stroke_begin", "sample", "stroke_end", "camera", "render", "snapshot", "undo", "redo", "paint"]


def hash32(x: int) -> int:
    x &= 0xFFFFFFFF
    x ^= x >> 16
    x = (x * 0x7FEB352D) & 0xFFFFFFFF
    x ^= x >> 15
    x = (x * 0x846CA68B) & 0xFFFFFFFF
    x ^= x >> 16
    return x


class Stream:
    """Pseudo-random integers from (seed, counter)."""

    def __init__(self, seed: int):
        self.seed = hash32(seed)
        self.i = 0

    def below(self, n: int) -> int:
        self.i += 1
        return hash32(self.seed ^ (self.i * 0x9E3779B9 & 0xFFFFFFFF)) % max(n, 1)


def _mutate_line(line: str, r: Stream) -> str:
    op = r.below(7)
    if op == 0 and line:  # replace a number, a string or a flat array with a literal
        spans = [m.span() for m in re.finditer(r'-?\d+(\.\d+)?([eE][-+]?\d+)?|"[^"]*"|\[[^\[\]]*\]', line)]
        if spans:
            a, b = spans[r.below(len(spans))]
            return line[:a] + LITERALS[r.below(len(LITERALS))] + line[b:]
    if op == 1 and line:  # delete a character
        i = r.below(len(line))
        return line[:i] + line[i + 1 :]
    if op == 2:  # insert a character
        i = r.below(len(line) + 1)
        return line[:i] + ALPHABET[r.below(len(ALPHABET))] + line[i:]
    if op == 3 and line.startswith("{"):  # a repeated or extra key first
        key = ["t", "ev", "p", "radius", "name", "q", "pressure", "size", "canvas", "version"][r.below(10)]
        return '{"' + key + '": ' + LITERALS[r.below(len(LITERALS))] + ", " + line[1:]
    if op == 4:  # cut the line
        return line[: r.below(len(line) + 1)]
    if op == 5 and '"ev": "' in line:  # another event kind
        i = line.index('"ev": "') + 7
        j = line.find('"', i)
        if j >= 0:
            return line[:i] + EVENTS[r.below(len(EVENTS))] + line[j:]
    return line + " " * r.below(2)


def variants(trace_paths: list[str], count: int, out_dir: str) -> list[str]:
    """Write `count` generated variants of the traces' first lines."""
    os.makedirs(out_dir, exist_ok=True)
    bases = []
    for p in trace_paths:
        with open(p, encoding="utf-8", errors="replace") as f:
            bases.append(f.read().split("\n")[:24])
    paths = []
    for k in range(count):
        r = Stream(k)
        lines = list(bases[r.below(len(bases))])
        lines = lines[: 2 + r.below(len(lines))]
        for _ in range(1 + r.below(3)):
            op = r.below(10)
            i = r.below(len(lines))
            if op == 0 and len(lines) > 1:  # swap two lines
                j = r.below(len(lines))
                lines[i], lines[j] = lines[j], lines[i]
            elif op == 1:  # repeat a line
                lines.insert(i, lines[i])
            elif op == 2 and len(lines) > 1:  # drop a line
                del lines[i]
            else:
                lines[i] = _mutate_line(lines[i], r)
        data = "\n".join(lines).encode("utf-8")
        if r.below(40) == 0:  # a byte that is not UTF-8
            i = r.below(len(data) + 1)
            data = data[:i] + b"\xc3\x28" + data[i:]
        path = os.path.join(out_dir, f"variant_{k:04d}.jsonl")
        with open(path, "wb") as f:
            f.write(data)
        paths.append(path)
    return paths


def canonical(path: str) -> list:
    """The reference reader's verdict on a trace, as the values the
    painter's `check --canonical` writes: `[["error", line, kind]]`, or the
    canvas, the warnings and one row per event."""
    try:
        t = read_trace(path)
    except TraceError as e:
        return [["error", e.line, e.kind]]
    c = t.canvas
    out = [["canvas", list(c.roots), c.max_depth, float(c.root_size), c.capacity, t.version]]
    out += [["warning", w] for w in t.warnings]
    for ev in t.events:
        v = ev.value
        row = [ev.line, float(ev.t), ev.kind]
        if ev.kind == "brush":
            n = v.noise
            row += [v.shape, v.mode, v.radius, list(v.color), v.opacity, v.hardness, v.spacing, v.mix_ratio,
                    v.pickup_rate, list(v.aspect), n.frequency, n.octaves, n.seed, n.gain]
        elif ev.kind == "mirror":
            row += [list(v.axes), list(v.centre)]
        elif ev.kind == "sample":
            row += [list(v.p), v.pressure, list(v.q)]
        elif ev.kind == "camera":
            row += [list(v.eye), list(v.q), list(v.fov), list(v.size), list(v.background)]
        elif ev.kind == "light":
            row += [True, list(v.dir), v.intensity, v.ambient, v.shadows] if v.on else [False]
        elif ev.kind in ("render", "snapshot"):
            row.append(v)
        elif ev.kind == "layer":
            row += [v.op, v.layer, v.name, v.to, v.visible, v.opacity, v.locked]
        elif ev.kind == "import":
            row += [v.file, v.sha256, v.name, v.voxels.depth, len(v.voxels)]
        out.append(row)
    return out


def same(a, b) -> bool:
    """Equal values: the same JSON types and, for floats, the same bits."""
    if isinstance(a, float) or isinstance(b, float):
        return isinstance(a, float) and isinstance(b, float) and struct.pack("<d", a) == struct.pack("<d", b)
    if isinstance(a, list) or isinstance(b, list):
        return isinstance(a, list) and isinstance(b, list) and len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


def painter_canonical(painter: str, paths: list[str]) -> dict[str, list]:
    """`octopaint check --canonical PATHS...`, split per trace."""
    res = subprocess.run([painter, "check", "--canonical", *paths], capture_output=True, timeout=600)
    if res.returncode not in (0, 2):
        raise RuntimeError(f"octopaint check failed ({res.returncode}): {res.stderr.decode(errors='replace')[-2000:]}")
    out: dict[str, list] = {}
    current = None
    for line in res.stdout.decode("utf-8").split("\n"):
        if line.startswith("== "):
            current = line[3:]
            out[current] = []
        elif current is not None and line:
            try:
                out[current].append(json.loads(line))
            except ValueError:
                out[current].append(["unreadable", line])
    return out


def compare_readers(painter: str, repo: str, work_dir: str, generated: int) -> tuple[int, list[tuple[str, list, list]]]:
    """Run both readers on the checked-in traces (valid and malformed) and
    `generated` variants. Returns (traces checked, disagreements)."""
    traces = sorted(glob.glob(os.path.join(repo, "traces", "*.jsonl")))
    malformed = sorted(glob.glob(os.path.join(repo, "traces", "malformed", "*.jsonl")))
    gen = variants(traces + malformed, generated, os.path.join(work_dir, "variants"))
    paths = traces + malformed + gen
    got = painter_canonical(painter, paths)
    bad = []
    for p in paths:
        want = canonical(p)
        have = got.get(p, [["no verdict from the painter"]])
        if not same(want, have):
            bad.append((p, want, have))
    return len(paths), bad

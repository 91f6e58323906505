"""A cell's history in both implementations: every event after which its
record (parent, first_child, depth, rgb, sigma) changed. The report shows
it for the first differing cell of a dump, so the first event where the two
stories part is in plain sight."""

from __future__ import annotations

import subprocess

import numpy as np
from octopaint_ref.replay import replay
from octopaint_ref.trace import read_trace

FREE_RECORD = (0xFFFFFFFF, 0xFFFFFFFF, 255, (0, 0, 0), 0.0)


def _record(tree, cell: int):
    if cell >= tree.n_used:
        return FREE_RECORD
    return (
        int(tree.parent[cell]),
        int(tree.first_child[cell]),
        int(tree.depth[cell]),
        tuple(int(v) for v in tree.rgb[cell]),
        float(tree.sigma[cell]),
    )


def _same(a, b) -> bool:
    # sigma by its f32 bits, like the painter
    return a[:4] == b[:4] and np.float32(a[4]).view(np.uint32) == np.float32(b[4]).view(np.uint32)


def reference_history(trace_path: str, cell: int) -> list[str]:
    lines = []
    last = [FREE_RECORD]

    def after_event(ev, painting):
        now = _record(painting.tree, cell)
        if not _same(now, last[0]):
            p, fc, d, rgb, s = now
            lines.append(
                f"line {ev.line} {ev.kind}: parent {p} first_child {fc} depth {d} rgb [{rgb[0]}, {rgb[1]}, {rgb[2]}] sigma {s!r}"
            )
            last[0] = now

    replay(read_trace(trace_path), None, renders=False, after_event=after_event)
    return lines


def painter_history(painter: str, trace_path: str, cell: int, scratch_dir: str) -> list[str]:
    res = subprocess.run(
        [painter, "replay", trace_path, "--out", scratch_dir, "--quiet", "--renderer", "none", "--history", str(cell)],
        capture_output=True,
        timeout=3600,
    )
    out = res.stdout.decode("utf-8", errors="replace").split("\n")
    return [line[len("history: ") :] for line in out if line.startswith("history: ")]

"""Replaying a trace: events in order, tree dumps at `snapshot` events and
images at `render` events (spec 12.3). The whole trace is validated before
the first event runs."""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field, replace

from .dump import dump_bytes, tree_arrays, write_atomic
from .paint import Painting
from .png import png_bytes
from .raycast import OVERFLOW, render
from .trace import Trace


@dataclass
class ReplayStats:
    samples: int = 0
    strokes: int = 0
    seconds: float = 0.0
    cells: int = 0
    max_depth_reached: int = 0
    written: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    render_seconds: float = 0.0


def replay(
    trace: Trace,
    out_dir: str | None,
    warn=None,
    after_segment=None,
    on_snapshot=None,
    on_render=None,
    renders=True,
    after_event=None,
) -> ReplayStats:
    """Replay `trace`; write `<name>.npz` into out_dir at snapshot events
    and `<name>.png` at render events (nothing when out_dir is None).
    on_snapshot(name, painting) and on_render(name, Rendered) are called at
    every snapshot and render (tests use them); after_event(event, painting)
    after every event (the conformance driver follows a cell's history). Images are f64 local-frame
    renders (raycast.py): the oracle for the GPU ray caster. renders=False
    skips them (timing the painting alone)."""
    stats = ReplayStats()

    def _warn(msg):
        stats.warnings.append(msg)
        if warn:
            warn(msg)

    for w in trace.warnings:
        _warn(w)
    painting = Painting(trace.canvas, warn=_warn)
    painting.after_segment = after_segment
    brush = None
    camera = None
    light = None  # unlit until a `light` event (spec 6.1)
    mirror = None  # no copies until a `mirror` event (spec 8.11)
    if out_dir is not None:
        os.makedirs(out_dir, exist_ok=True)
    t0 = time.perf_counter()
    for ev in trace.events:
        k = ev.kind
        if k == "brush":
            brush = ev.value
        elif k == "stroke_begin":
            painting.begin_stroke(brush if mirror is None else replace(brush, mirror=mirror), ev.line)
            stats.strokes += 1
        elif k == "sample":
            painting.add_sample(ev.value, ev.line)
            stats.samples += 1
        elif k == "stroke_end":
            painting.end_stroke()
        elif k == "undo":
            painting.undo()
        elif k == "redo":
            painting.redo()
        elif k == "snapshot":
            if on_snapshot:
                on_snapshot(ev.value, painting)
            if out_dir is not None:
                path = os.path.join(out_dir, ev.value + ".npz")
                write_atomic(path, dump_bytes(tree_arrays(painting.tree)))
                stats.written.append(path)
        elif k == "camera":
            camera = ev.value
        elif k == "light":
            light = ev.value
        elif k == "mirror":
            mirror = ev.value if any(ev.value.axes) else None
        elif k == "render" and renders and (out_dir is not None or on_render):
            # Every event before this one has been applied: the tree is the
            # one all pending work leads to.
            r0 = time.perf_counter()
            image = render(tree_arrays(painting.tree), camera, light=light)
            stats.render_seconds += time.perf_counter() - r0
            if image.count(OVERFLOW):
                _warn(f"line {ev.line}: {image.count(OVERFLOW)} ray(s) of render {ev.value!r} reached the step limit")
            if on_render:
                on_render(ev.value, image)
            if out_dir is not None:
                path = os.path.join(out_dir, ev.value + ".png")
                write_atomic(path, png_bytes(image.image))
                stats.written.append(path)
        if after_event:
            after_event(ev, painting)
    stats.seconds = time.perf_counter() - t0
    t = painting.tree
    stats.cells = t.n_used
    live = t.depth[: t.n_used]
    stats.max_depth_reached = int(live[live != 255].max())
    stats.painting = painting
    return stats


def print_stats(stats: ReplayStats, file=sys.stderr) -> None:
    print(
        f"replayed {stats.strokes} strokes, {stats.samples} samples in {stats.seconds:.2f} s: "
        f"{stats.cells} cells in use, deepest cell at depth {stats.max_depth_reached}"
        + (f" (rendering: {stats.render_seconds:.2f} s)" if stats.render_seconds else ""),
        file=file,
    )

"""Replaying a trace: events in order, tree dumps at `snapshot` events and
images at `render` events (spec 12.3). The whole trace is validated before
the first event runs."""

from __future__ import annotations

import os
import re
import sys
import time
from dataclasses import dataclass, field, replace

from .dump import dump_bytes, tree_arrays, write_atomic
from .layers import Document, document_arrays
from .lod import check_k
from .march import render_layers
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
    lods=(("0", 0.0),),
) -> ReplayStats:
    """Replay `trace`; write `<name>.npz` into out_dir at snapshot events
    and `<name>.png` at render events (nothing when out_dir is None).
    on_snapshot(name, painting) and on_render(name, Rendered) are called at
    every snapshot and render (tests use them); after_event(event, painting)
    after every event (the conformance driver follows a cell's history). Images are f64 local-frame
    renders (raycast.py): the oracle for the GPU ray caster. renders=False
    skips them (timing the painting alone). lods: the levels of detail of
    every image, (text, k) pairs (spec 7; parse_lods): k = 0 writes
    `<name>.png`, any other `<name>.lod<text>.png`."""
    stats = ReplayStats()

    def _warn(msg):
        stats.warnings.append(msg)
        if warn:
            warn(msg)

    for w in trace.warnings:
        _warn(w)
    doc = Document(trace.canvas, warn=_warn)
    doc.layers[0].painting.after_segment = after_segment
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
            doc.begin_stroke(brush if mirror is None else replace(brush, mirror=mirror), ev.line)
            stats.strokes += 1
        elif k == "sample":
            doc.add_sample(ev.value, ev.line)
            stats.samples += 1
        elif k == "stroke_end":
            doc.end_stroke()
        elif k == "import":
            doc.import_voxels(ev.value, ev.line)
        elif k == "undo":
            doc.undo()
        elif k == "redo":
            doc.redo()
        elif k == "layer":
            doc.apply(ev.value, ev.line)
            doc.current.painting.after_segment = after_segment
        elif k == "snapshot":
            if on_snapshot:
                on_snapshot(ev.value, doc.current.painting)
            if out_dir is not None:
                path = os.path.join(out_dir, ev.value + ".npz")
                arrays = document_arrays(doc) if trace.version == 2 else tree_arrays(doc.current.tree)
                write_atomic(path, dump_bytes(arrays))
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
            for text, k in lods:
                name = ev.value if k == 0 else f"{ev.value}.lod{text}"
                r0 = time.perf_counter()
                image = render_document(doc, camera, light=light, lod=k)
                stats.render_seconds += time.perf_counter() - r0
                if image.count(OVERFLOW):
                    _warn(f"line {ev.line}: {image.count(OVERFLOW)} ray(s) of render {name!r} reached the step limit")
                if on_render:
                    on_render(name, image)
                if out_dir is not None:
                    path = os.path.join(out_dir, name + ".png")
                    write_atomic(path, png_bytes(image.image))
                    stats.written.append(path)
        if after_event:
            after_event(ev, doc.current.painting)
    stats.seconds = time.perf_counter() - t0
    stats.cells = doc.used()
    stats.max_depth_reached = max(int(t.depth[: t.n_used][t.depth[: t.n_used] != 255].max()) for t in (la.tree for la in doc.layers))
    stats.painting = doc.current.painting
    stats.document = doc
    return stats


def render_document(doc: Document, camera, light=None, lod=0.0):
    """The image of a document (spec 6.2, 14.6) at level of detail `lod`
    (spec 7): the single-tree ray caster when one layer contributes at
    opacity 1, the march through every contributing layer otherwise."""
    layers = [la for la in doc.layers if la.visible and la.opacity > 0]
    if len(layers) == 1 and layers[0].opacity == 1.0:
        return render(tree_arrays(layers[0].tree), camera, light=light, lod=lod)
    return render_layers([(tree_arrays(la.tree), la.opacity) for la in layers], camera, light=light, lod=lod)


def parse_lods(text: str) -> list:
    """`--lod K[,K...]`: the levels of detail every render event is
    written at, as (text as given, k) pairs, or ValueError: each a decimal
    number in [0, lod.MAX_K], none twice."""
    out = []
    for part in text.split(","):
        if not re.fullmatch(r"[0-9]+(\.[0-9]+)?", part):
            raise ValueError(f"--lod {text!r}: {part!r} is not a decimal number such as 0, 1 or 0.5")
        k = check_k(float(part))
        if any(k == q for _, q in out):
            raise ValueError(f"--lod {text!r}: level {part} given twice")
        out.append((part, k))
    return out


def print_stats(stats: ReplayStats, file=sys.stderr) -> None:
    print(
        f"replayed {stats.strokes} strokes, {stats.samples} samples in {stats.seconds:.2f} s: "
        f"{stats.cells} cells in use, deepest cell at depth {stats.max_depth_reached}"
        + (f" (rendering: {stats.render_seconds:.2f} s)" if stats.render_seconds else ""),
        file=file,
    )

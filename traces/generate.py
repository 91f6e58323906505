#!/usr/bin/env python3
"""Generates every trace in traces/ (and traces/malformed/ with the error each
must produce). Never edit a trace by hand: change this script and run

    python3 traces/generate.py            # rewrite traces/
    python3 traces/generate.py --out DIR  # write elsewhere (the staleness test)

Pseudo-random values come from hashing an index (lowbias32), never from a
language's RNG, so any implementation can rebuild them. Only the standard
library is used.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import math
import os
import struct
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))


def hash32(x: int) -> int:
    x &= 0xFFFFFFFF
    x ^= x >> 16
    x = (x * 0x7FEB352D) & 0xFFFFFFFF
    x ^= x >> 15
    x = (x * 0x846CA68B) & 0xFFFFFFFF
    x ^= x >> 16
    return x


def rnd(stream: int, i: int) -> float:
    """Uniform in [0, 1) from (stream, index)."""
    return hash32(hash32(stream) ^ (i * 0x9E3779B9 & 0xFFFFFFFF)) / 4294967296.0


def r6(x: float) -> float:
    """Round to 6 significant-ish decimals so traces stay readable."""
    return float(f"{x:.9g}")


class Writer:
    def __init__(self, canvas: dict, title: str, version: int = 1):
        self.lines = [
            json.dumps(
                {
                    "format": "ddo-trace",
                    "version": version,
                    "canvas": canvas,
                    "meta": {"title": title, "recorded_by": "traces/generate.py", "created": "2026-11-23T00:00:00Z"},
                }
            )
        ]
        self.t = 0.0

    def ev(self, ev: str, dt: float = 0.0, **kw) -> None:
        self.t = r6(self.t + dt)
        self.lines.append(json.dumps({"ev": ev, "t": self.t, **kw}))

    def brush(self, shape, mode, radius, color, opacity=1.0, hardness=0.5, **kw):
        self.ev("brush", 0.5, shape=shape, mode=mode, radius=r6(radius), color=[r6(c) for c in color],
                opacity=r6(opacity), hardness=r6(hardness), **kw)

    def stroke(self, points, pressures=None, quats=None, dt=1 / 90):
        self.ev("stroke_begin", 0.2)
        for i, p in enumerate(points):
            kw = {"p": [r6(v) for v in p]}
            if pressures is not None:
                kw["pressure"] = r6(pressures[i])
            if quats is not None:
                kw["q"] = [r6(v) for v in quats[i]]
            self.ev("sample", dt if i else 0.0, **kw)
        self.ev("stroke_end", dt)

    def camera(self, eye, look_at, size=(320, 240), fov_deg=40.0, background=(0.05, 0.05, 0.08)):
        self.ev("camera", 0.1, eye=[r6(v) for v in eye], q=[r6(v) for v in look_quat(eye, look_at)],
                fov=[r6(-math.radians(fov_deg) / 2 * size[0] / size[1]), r6(math.radians(fov_deg) / 2 * size[0] / size[1]),
                     r6(math.radians(fov_deg) / 2), r6(-math.radians(fov_deg) / 2)],
                size=list(size), background=[r6(v) for v in background])

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def look_quat(eye, target):
    """Quaternion [x, y, z, w] turning -z towards target with +y up (world +z up is not assumed)."""
    f = [target[i] - eye[i] for i in range(3)]
    n = math.sqrt(sum(v * v for v in f))
    f = [v / n for v in f]
    up = [0.0, 1.0, 0.0] if abs(f[1]) < 0.99 else [1.0, 0.0, 0.0]
    z = [-v for v in f]
    x = [up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]]
    nx = math.sqrt(sum(v * v for v in x))
    x = [v / nx for v in x]
    y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
    m = [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]]
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        return [(m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, 0.25 * s]
    i = max(range(3), key=lambda k: m[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = math.sqrt(1.0 + m[i][i] - m[j][j] - m[k][k]) * 2
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (m[j][i] + m[i][j]) / s
    q[k] = (m[k][i] + m[i][k]) / s
    q[3] = (m[k][j] - m[j][k]) / s
    return q


def axis_quat(axis, angle):
    s = math.sin(angle / 2)
    n = math.sqrt(sum(a * a for a in axis))
    return [axis[0] / n * s, axis[1] / n * s, axis[2] / n * s, math.cos(angle / 2)]


def line(p0, p1, n):
    return [[p0[k] + (p1[k] - p0[k]) * i / (n - 1) for k in range(3)] for i in range(n)]


# ------------------------------------------------------------------ traces
def single_stamp() -> str:
    w = Writer({"roots": [1, 1, 1], "max_depth": 8, "root_size": 1.0, "capacity": 65536}, "One sphere stamp")
    w.brush("sphere", "paint", 0.1, [0.9, 0.3, 0.1], opacity=0.9, hardness=0.6)
    w.stroke([[0.5, 0.5, 0.5]])
    w.camera([0.5, 0.5, 2.0], [0.5, 0.5, 0.5])
    w.ev("render", 0.1, name="single_stamp")
    w.ev("snapshot", 0.0, name="single_stamp")
    return w.text()


SHAPES = ("sphere", "cylinder", "box", "cone", "noise")
MODES = ("paint", "erase", "recolor", "mix", "pickup")


def shapes_modes() -> str:
    """Each shape x mode stroke crosses a painted two-colour base bar, so
    erase, recolor, mix and pickup have something to act on. max_depth 7
    clamps the target depth (the brushes ask for 8)."""
    w = Writer({"roots": [2, 2, 1], "max_depth": 7, "root_size": 1.0, "capacity": 4194304}, "Every shape in every mode")
    for si, shape in enumerate(SHAPES):
        y = 0.2 + 0.4 * si
        # Base: a two-colour bar along x under this row.
        w.brush("sphere", "paint", 0.05, [0.2, 0.4, 0.9], opacity=0.9, hardness=0.7)
        w.stroke(line([0.1, y, 0.5], [1.0, y, 0.5], 10))
        w.brush("sphere", "paint", 0.05, [0.95, 0.85, 0.2], opacity=0.9, hardness=0.7)
        w.stroke(line([1.0, y, 0.5], [1.9, y, 0.5], 10))
        for mi, mode in enumerate(MODES):
            x = 0.2 + 0.38 * mi
            extra = {}
            if shape in ("cylinder", "box", "cone"):
                extra["aspect"] = [1.0, 0.6, 1.4] if shape != "box" else [1.0, 0.5, 0.8]
            if shape == "noise":
                extra["noise"] = {"frequency": 2.0, "octaves": 3, "seed": 7 + mi, "gain": 0.5}
            if mode == "mix":
                extra["mix_ratio"] = 0.7
            if mode == "pickup":
                extra["pickup_rate"] = 0.3
            color = [0.1 + 0.2 * mi, 0.8 - 0.15 * mi, 0.3 + 0.1 * si]
            w.brush(shape, mode, 0.045, color, opacity=0.4 + 0.12 * mi, hardness=0.2 + 0.15 * si,
                    spacing=0.3, **extra)
            pts = line([x - 0.12, y - 0.12, 0.5], [x + 0.12, y + 0.12, 0.52], 7)
            pres = [0.4 + 0.6 * math.sin(math.pi * i / 6) for i in range(7)]
            quats = [axis_quat([0.3, 1.0, 0.2], 0.4 * i) for i in range(7)]
            w.stroke(pts, pres, quats)
        if si == 1:
            w.ev("snapshot", 0.1, name="shapes_modes_half")
    w.camera([1.0, 1.0, 3.0], [1.0, 1.0, 0.5], size=(320, 320))
    w.ev("render", 0.1, name="shapes_modes")
    w.ev("snapshot", 0.0, name="shapes_modes")
    return w.text()


def undo_redo() -> str:
    w = Writer({"roots": [2, 1, 1], "max_depth": 9, "root_size": 1.0, "capacity": 1048576}, "Undo and redo")
    w.brush("sphere", "paint", 0.08, [0.8, 0.2, 0.2], opacity=0.7, hardness=0.4)
    w.stroke(line([0.3, 0.5, 0.5], [1.2, 0.5, 0.5], 6))
    w.ev("snapshot", 0.1, name="undo_redo_a")
    w.brush("box", "paint", 0.05, [0.2, 0.8, 0.2], opacity=0.8, hardness=0.8)
    w.stroke(line([0.5, 0.3, 0.5], [0.9, 0.7, 0.5], 5), quats=[axis_quat([0, 0, 1], 0.3 * i) for i in range(5)])
    w.ev("snapshot", 0.1, name="undo_redo_b")
    w.ev("undo", 0.1)
    w.ev("snapshot", 0.1, name="undo_redo_undone")  # must equal undo_redo_a
    w.ev("redo", 0.1)
    w.ev("snapshot", 0.1, name="undo_redo_redone")  # must equal undo_redo_b
    w.ev("undo", 0.1)
    w.ev("undo", 0.1)
    w.ev("snapshot", 0.1, name="undo_redo_empty")  # the bare root array
    w.ev("redo", 0.1)
    w.brush("sphere", "erase", 0.06, [0, 0, 0], opacity=1.0, hardness=0.9)
    w.stroke(line([0.6, 0.5, 0.4], [0.9, 0.5, 0.6], 4))
    w.ev("snapshot", 0.1, name="undo_redo_branch")  # redo history dropped
    return w.text()


def capacity_limit() -> str:
    w = Writer({"roots": [1, 1, 1], "max_depth": 12, "root_size": 1.0, "capacity": 4096}, "Cell budget exhausted")
    w.brush("sphere", "paint", 0.01, [0.3, 0.6, 0.9], opacity=0.9, hardness=0.5)
    w.stroke(line([0.2, 0.5, 0.5], [0.8, 0.5, 0.5], 30))
    w.ev("snapshot", 0.1, name="capacity_limit")
    return w.text()


def edges() -> str:
    """Samples outside the canvas, strokes across root faces, a stroke the
    trace leaves open (ended with a warning)."""
    w = Writer({"roots": [2, 2, 2], "max_depth": 9, "root_size": 0.5, "capacity": 2097152}, "Canvas edges")
    w.brush("sphere", "paint", 0.06, [0.7, 0.7, 0.2], opacity=0.8, hardness=0.5)
    w.stroke(line([-0.1, 0.5, 0.5], [0.2, 0.5, 0.5], 6))  # starts outside
    w.brush("cylinder", "mix", 0.05, [0.1, 0.2, 0.9], opacity=0.6, hardness=0.3, aspect=[1.0, 1.0, 2.0])
    w.stroke(line([0.4, 0.4, 0.4], [0.6, 0.6, 0.6], 8), quats=[axis_quat([1, 1, 0], 0.2 * i) for i in range(8)])
    w.brush("sphere", "paint", 0.05, [0.2, 0.9, 0.4], opacity=0.5, hardness=0.2)
    w.stroke(line([0.9, 0.95, 0.5], [1.05, 1.05, 0.5], 5))  # leaves through a corner
    w.ev("snapshot", 0.1, name="edges")
    w.brush("cone", "paint", 0.04, [0.9, 0.1, 0.5], opacity=0.9, hardness=0.6)
    w.ev("stroke_begin", 0.1)
    w.ev("sample", 0.0, p=[0.25, 0.75, 0.5])
    w.ev("sample", 0.01, p=[0.3, 0.75, 0.5])
    w.ev("snapshot", 0.01, name="edges_open")
    return w.text()


def scene() -> str:
    """A 40 km canvas with 0.3 mm cells (roots of 10 km, depth 25): a
    kilometre-wide translucent haze, hills of cone stamps, ~4,800 samples of
    brush work at depth 21 by a hand moving ~0.3 m/s at 90 Hz (paint, mix,
    pickup, recolor with box stamps), a stroke down at depth 25, then a
    translucent mist over all of it and an eraser through it."""
    w = Writer({"roots": [4, 4, 4], "max_depth": 25, "root_size": 10000.0, "capacity": 16777216}, "Island at dusk")
    c = (20000.0, 20000.0, 20000.0)  # where eight roots meet
    # Sky: a kilometre-wide translucent haze.
    w.brush("sphere", "paint", 1200.0, [0.55, 0.7, 0.95], opacity=0.08, hardness=0.2)
    w.stroke([[c[0] - 3000 + 1000 * i, c[1] + 1500 + 200 * math.sin(i), c[2] - 500] for i in range(7)],
             [0.6 + 0.05 * i for i in range(7)], dt=0.05)
    # Hills: cone stamps on the ground plane.
    w.brush("cone", "paint", 250.0, [0.25, 0.45, 0.2], opacity=0.9, hardness=0.7, aspect=[1.0, 1.0, 1.0], spacing=0.5)
    up = axis_quat([1, 0, 0], -math.pi / 2)  # cone axis (local +z) along canvas +y
    w.stroke([[c[0] - 1500 + 60 * i, c[1] - 200, c[2] - 300 + 400 * math.sin(i / 5)] for i in range(50)],
             quats=[up] * 50, dt=0.02)
    # Brush work near the centre, crossing the faces between the 8 roots.
    # radius 0.052 at pressure 0.9-1 (r = 0.048-0.052): r/10 just above a
    # depth-21 cell (4.77 mm), so the brush keeps ~10 cells per radius.
    base = (c[0] + 0.11, c[1] + 0.07, c[2] - 0.05)
    for s, (radius, color, shape, mode, n) in enumerate([
        (0.052, [0.95, 0.55, 0.2], "sphere", "paint", 1300),
        (0.052, [0.3, 0.2, 0.8], "sphere", "mix", 1200),
        (0.052, [0.95, 0.95, 0.9], "sphere", "pickup", 1200),
        (0.04, [0.1, 0.1, 0.1], "box", "recolor", 1000),
        (0.003, [1.0, 0.1, 0.1], "sphere", "paint", 150),
    ]):
        kw = {"pickup_rate": 0.15} if mode == "pickup" else {}
        w.brush(shape, mode, radius, color, opacity=0.85, hardness=0.55, spacing=0.5, **kw)
        pts, pres, quats = [], [], []
        for i in range(n):
            a = 0.0033 * i  # metres of path, about
            ph = 1.3 * s
            pts.append([base[0] + 0.15 * math.cos(a * 2.0 + ph) - 0.15 * math.cos(ph),
                        base[1] + 0.12 * math.sin(a * 2.9 + ph) + 0.03 * s,
                        base[2] + 0.2 * i / n - 0.1 + 0.002 * rnd(s, i)])
            pres.append(0.9 + 0.1 * math.sin(math.pi * (i + 0.5) / n))
            quats.append(axis_quat([0.2, 1.0, 0.4], 0.01 * i))
        if radius < 0.01:  # the finest stroke: 3 mm radius, cells of 0.3 mm
            pts = [[base[0] + 0.0003 * i, base[1] + 0.004 * math.sin(i / 9), base[2]] for i in range(n)]
        w.stroke(pts, pres, quats if shape == "box" else None)
    w.ev("snapshot", 0.1, name="scene_detail")
    # Mist: a translucent stroke across everything painted so far.
    w.brush("sphere", "paint", 400.0, [0.85, 0.85, 0.9], opacity=0.15, hardness=0.0)
    w.stroke([[c[0] - 300 + 300 * i, c[1] + 100, c[2]] for i in range(3)], dt=0.05)
    # And an eraser through the detail.
    w.brush("sphere", "erase", 0.06, [0, 0, 0], opacity=1.0, hardness=0.8)
    w.stroke(line([base[0] - 0.2, base[1], base[2]], [base[0] + 0.3, base[1] + 0.1, base[2]], 100))
    w.camera([c[0], c[1], c[2] + 1.5], base, size=(320, 240))
    w.ev("render", 0.1, name="scene_close")
    w.camera([c[0], c[1] + 500, c[2] + 6000], c, size=(320, 240))
    w.ev("render", 0.1, name="scene_far")
    # The close view again, lit with shadows: shading across the depth
    # changes of real brush work (depths 0 to 25).
    w.ev("light", 0.1, dir=[0.3, 1.0, 0.6], intensity=0.9, ambient=0.25, shadows=True)
    w.camera([c[0], c[1], c[2] + 1.5], base, size=(320, 240))
    w.ev("render", 0.1, name="scene_lit")
    w.ev("snapshot", 0.0, name="scene")
    return w.text()


def lit() -> str:
    """Lighting (spec 6.1): a slab, a ball resting above it, a thin tube
    (finer cells beside coarser ones), a noise blob and a faint haze, drawn
    unlit, lit, lit with shadow rays (the ball shades the slab), from the
    side, and with the light switched off again (the unlit pixels)."""
    w = Writer({"roots": [2, 2, 2], "max_depth": 8, "root_size": 0.5, "capacity": 4194304}, "Lit shapes")
    w.brush("box", "paint", 0.3, [0.8, 0.78, 0.7], opacity=0.95, hardness=0.9, aspect=[1.0, 0.12, 1.0])
    w.stroke([[0.5, 0.25, 0.5]])
    w.brush("sphere", "paint", 0.13, [0.9, 0.45, 0.15], opacity=0.95, hardness=0.85)
    w.stroke([[0.42, 0.52, 0.5]])
    w.brush("sphere", "paint", 0.035, [0.2, 0.5, 0.9], opacity=0.9, hardness=0.6, spacing=0.3)
    w.stroke([[0.62 + 0.2 * math.sin(i / 10), 0.45 + 0.1 * i / 30, 0.35 + 0.3 * i / 30] for i in range(31)])
    w.brush("noise", "paint", 0.1, [0.4, 0.8, 0.3], opacity=0.8, hardness=0.5,
            noise={"frequency": 3.0, "octaves": 3, "seed": 11, "gain": 0.5})
    w.stroke([[0.25, 0.4, 0.3]])
    w.brush("sphere", "paint", 0.22, [0.7, 0.75, 0.95], opacity=0.05, hardness=0.0)
    w.stroke([[0.75, 0.7, 0.7]])
    w.camera([0.5, 0.75, 1.6], [0.5, 0.4, 0.5], size=(256, 192))
    w.ev("render", 0.1, name="lit_unlit")
    w.ev("light", 0.1, dir=[0.45, 1.0, 0.35], intensity=0.8, ambient=0.3)
    w.ev("render", 0.1, name="lit_lambert")
    w.ev("light", 0.1, dir=[-0.5, 1.0, 0.2], intensity=1.2, ambient=0.2, shadows=True)
    w.ev("render", 0.1, name="lit_shadows")
    w.camera([1.6, 0.6, 0.5], [0.5, 0.4, 0.5], size=(192, 192))
    w.ev("render", 0.1, name="lit_side")
    w.ev("light", 0.1, on=False)
    w.camera([0.5, 0.75, 1.6], [0.5, 0.4, 0.5], size=(256, 192))
    w.ev("render", 0.1, name="lit_off")
    w.ev("snapshot", 0.0, name="lit")
    return w.text()


def mirror() -> str:
    """Mirror painting (spec 8.11): copies through planes at the canvas's
    middle, a lattice plane, so that a stroke at dyadic positions has an
    exact mirror image (reference/tests/test_mirror.py checks it on the
    first snapshot); a rotated box stamp mirrored on two axes, a noise
    brush mirrored on y (the grain mirrors too), a cone mixing through all
    seven copies, pickup and erase across the plane, undo and redo of a
    mirrored stroke."""
    w = Writer({"roots": [2, 2, 2], "max_depth": 8, "root_size": 0.5, "capacity": 4194304}, "Mirror painting")
    mid = [0.5, 0.5, 0.5]
    w.ev("mirror", 0.1, axes=[True, False, False], centre=mid)
    w.brush("sphere", "paint", 0.0625, [0.9, 0.4, 0.1], opacity=0.9, hardness=0.6)
    w.stroke([[0.25 + 0.03125 * i, 0.375 + 0.015625 * i, 0.5] for i in range(5)], [0.5 + 0.125 * i for i in range(5)])
    w.ev("snapshot", 0.1, name="mirror_x")
    w.ev("mirror", 0.1, axes=[True, False, True], centre=mid)
    w.brush("box", "paint", 0.05, [0.2, 0.6, 0.9], opacity=0.8, hardness=0.7, spacing=0.4, aspect=[1.0, 0.5, 0.8])
    w.stroke(line([0.2, 0.7, 0.2], [0.35, 0.75, 0.3], 6), quats=[axis_quat([0.3, 1.0, 0.2], 0.3 * i) for i in range(6)])
    w.ev("mirror", 0.1, axes=[False, True, False], centre=mid)
    w.brush("noise", "paint", 0.08, [0.4, 0.8, 0.3], opacity=0.8, hardness=0.5,
            noise={"frequency": 3.0, "octaves": 3, "seed": 5, "gain": 0.5})
    w.stroke([[0.3, 0.2, 0.7], [0.4, 0.22, 0.72]])
    w.ev("mirror", 0.1, axes=[True, True, True], centre=[0.53, 0.47, 0.51])
    w.brush("cone", "mix", 0.06, [0.9, 0.9, 0.2], opacity=0.7, hardness=0.4, mix_ratio=0.6, spacing=0.5)
    w.stroke(line([0.3, 0.35, 0.35], [0.42, 0.4, 0.4], 4), quats=[axis_quat([1, 0, 0], 0.4 * i) for i in range(4)])
    w.ev("mirror", 0.1, axes=[True, False, False], centre=mid)
    w.brush("sphere", "pickup", 0.04, [1.0, 1.0, 1.0], opacity=0.8, hardness=0.5, pickup_rate=0.3)
    w.stroke(line([0.3, 0.4, 0.5], [0.45, 0.42, 0.5], 8))
    w.ev("snapshot", 0.1, name="mirror_mixed")
    w.ev("mirror", 0.1, axes=[False, False, True], centre=mid)
    w.brush("cylinder", "erase", 0.03, [0, 0, 0], opacity=1.0, hardness=0.8)
    w.stroke(line([0.3, 0.39, 0.45], [0.35, 0.39, 0.4], 5))
    w.ev("mirror", 0.1, axes=[False, False, False], centre=mid)  # off again
    w.brush("sphere", "paint", 0.03, [0.9, 0.1, 0.6], opacity=0.9, hardness=0.6)
    w.stroke(line([0.6, 0.6, 0.6], [0.7, 0.62, 0.6], 4))
    w.ev("undo", 0.1)
    w.ev("undo", 0.1)
    w.ev("snapshot", 0.1, name="mirror_undone")  # must equal mirror_mixed
    w.ev("redo", 0.1)
    w.camera([0.5, 0.9, 1.8], [0.5, 0.45, 0.5], size=(256, 192))
    w.ev("render", 0.1, name="mirror")
    w.ev("snapshot", 0.0, name="mirror")
    # A hard sphere mirrored on y whose samples lie close together: leaves
    # inside its core are settled (spec 8.7) at the first sample and are
    # candidates again at every later sample's paint pass, where each copy
    # is a capsule of the segment (the painter once refined them there).
    w.ev("mirror", 0.1, axes=[False, True, False], centre=mid)
    w.brush("sphere", "paint", 0.1, [0.3, 0.7, 0.9], opacity=0.9, hardness=1.0)
    w.stroke(line([0.3, 0.3, 0.5], [0.33, 0.3, 0.5], 4))
    w.ev("snapshot", 0.1, name="mirror_settled")
    return w.text()


def settled() -> str:
    """Settled leaves (spec 8.7) under brushes whose pressure swings: a hard
    sphere settles leaves of its core at one sample that a wider capsule
    after it (a coarser target depth) paints unevenly, so they must refine
    then (deferred leaves); the same in erase and recolour, and a soft
    brush for contrast."""
    w = Writer({"roots": [1, 1, 1], "max_depth": 8, "root_size": 1.0, "capacity": 1048576}, "Settled and deferred leaves")
    w.brush("sphere", "paint", 0.3, [0.2, 0.6, 0.9], opacity=0.4, hardness=0.965)
    w.stroke([[0.5, 0.5, 0.75], [0.5, 0.5, 0.45], [0.52, 0.48, 0.3]], pressures=[0.4, 0.84, 0.6])
    w.ev("snapshot", 0.1, name="settled_paint")
    w.brush("sphere", "erase", 0.25, [0, 0, 0], opacity=0.5, hardness=0.97)
    w.stroke([[0.45, 0.5, 0.7], [0.5, 0.52, 0.5]], pressures=[0.35, 0.9])
    w.brush("sphere", "recolor", 0.25, [0.9, 0.3, 0.1], opacity=0.6, hardness=0.97)
    w.stroke([[0.55, 0.45, 0.35], [0.5, 0.5, 0.55]], pressures=[0.3, 1.0])
    w.brush("sphere", "mix", 0.2, [0.9, 0.9, 0.2], opacity=0.5, hardness=0.3)
    w.stroke([[0.4, 0.6, 0.5], [0.6, 0.4, 0.5]], pressures=[0.3, 1.0])
    w.camera([0.5, 0.6, 1.9], [0.5, 0.5, 0.5], size=(192, 144))
    w.ev("render", 0.1, name="settled")
    w.ev("snapshot", 0.0, name="settled")
    return w.text()


def layers() -> str:
    """Layers (spec 14, 6.2): a blue slab on the first layer, orange strokes
    crossing it on a second (finer cells over coarser ones, so the march
    steps through boundaries of either tree), rendered together, at half
    opacity, with a hidden haze layer; reorder, rename, duplicate, lock,
    merge down (the common refinement of both trees), undo and redo of the
    merge and of a delete, a stroke after them, and the composite lit with
    shadow rays."""
    w = Writer({"roots": [2, 2, 2], "max_depth": 7, "root_size": 0.5, "capacity": 4194304}, "Layers", version=2)
    w.brush("box", "paint", 0.3, [0.2, 0.45, 0.9], opacity=0.9, hardness=0.8, aspect=[1.0, 0.15, 1.0])
    w.stroke([[0.5, 0.35, 0.5]])
    w.ev("layer", 0.1, op="add", name="detail")
    w.brush("sphere", "paint", 0.05, [0.95, 0.55, 0.1], opacity=0.9, hardness=0.6, spacing=0.3)
    w.stroke([[0.3 + 0.4 * i / 12, 0.38 + 0.1 * math.sin(i / 3), 0.5] for i in range(13)])
    w.ev("snapshot", 0.1, name="layers_two")
    w.camera([0.5, 0.9, 1.7], [0.5, 0.38, 0.5], size=(192, 144))
    w.ev("render", 0.1, name="layers_two")
    w.ev("layer", 0.1, op="set", layer="detail", opacity=0.5)
    w.ev("render", 0.1, name="layers_half")
    w.ev("layer", 0.1, op="add", name="sky")
    w.brush("sphere", "paint", 0.25, [0.8, 0.85, 1.0], opacity=0.08, hardness=0.0)
    w.stroke([[0.5, 0.7, 0.5]])
    w.ev("render", 0.1, name="layers_haze")
    w.ev("layer", 0.1, op="set", layer="sky", visible=False)
    w.ev("layer", 0.1, op="move", layer="sky", to=0)
    w.ev("layer", 0.1, op="rename", layer="sky", name="ground haze")
    w.ev("layer", 0.1, op="duplicate", layer="detail", name="detail copy")
    w.ev("layer", 0.1, op="set", layer="detail copy", locked=True, visible=False)
    w.ev("snapshot", 0.1, name="layers_before_merge")
    w.ev("layer", 0.1, op="set", layer="detail", opacity=1.0)
    w.ev("layer", 0.1, op="merge_down", layer="detail")
    w.ev("snapshot", 0.1, name="layers_merged")
    w.ev("render", 0.1, name="layers_merged")
    w.ev("undo", 0.1)
    w.ev("undo", 0.1)
    w.ev("snapshot", 0.1, name="layers_unmerged")  # must equal layers_before_merge
    w.ev("redo", 0.1)
    w.ev("redo", 0.1)
    w.ev("layer", 0.1, op="delete", layer="ground haze")
    w.ev("undo", 0.1)
    w.ev("layer", 0.1, op="select", layer="Layer 1")
    w.brush("cylinder", "erase", 0.04, [0, 0, 0], opacity=1.0, hardness=0.8)
    w.stroke(line([0.35, 0.35, 0.45], [0.65, 0.35, 0.55], 6))
    w.ev("layer", 0.1, op="set", layer="ground haze", visible=True, opacity=0.6)
    w.ev("light", 0.1, dir=[-0.4, 1.0, 0.3], intensity=1.0, ambient=0.25, shadows=True)
    w.ev("render", 0.1, name="layers_lit")
    w.ev("snapshot", 0.0, name="layers")
    return w.text()


def layers_budget() -> str:
    """Layer operations the cell budget refuses at replay (spec 14.2): a
    duplicate and a merge that do not fit are skipped with a warning, and
    the events that name what they would have made are skipped in turn;
    painting goes on in the layers that exist."""
    w = Writer({"roots": [1, 1, 1], "max_depth": 6, "root_size": 1.0, "capacity": 6000}, "Layer budget", version=2)
    w.brush("sphere", "paint", 0.1, [0.9, 0.3, 0.2], opacity=0.9, hardness=0.5)
    w.stroke([[0.5, 0.5, 0.5]])
    w.ev("layer", 0.1, op="add", name="second")
    w.brush("sphere", "paint", 0.06, [0.2, 0.3, 0.9], opacity=0.9, hardness=0.5)
    w.stroke([[0.35, 0.55, 0.45]])
    w.ev("snapshot", 0.1, name="budget_two")
    w.ev("layer", 0.1, op="duplicate", layer="Layer 1", name="copy")
    w.ev("layer", 0.1, op="select", layer="copy")
    w.stroke([[0.6, 0.4, 0.5]])
    w.ev("layer", 0.1, op="merge_down", layer="second")
    w.ev("snapshot", 0.1, name="budget_after")
    w.camera([0.5, 0.5, 2.0], [0.5, 0.5, 0.5], size=(64, 48))
    w.ev("render", 0.1, name="budget_after")
    return w.text()


# ------------------------------------------------------------ voxel sets
def npy(descr: str, shape: tuple, fmt: str, values) -> bytes:
    """One .npy (format 1.0) without numpy: the header dict padded so the data
    starts at a multiple of 64 bytes, then the values little-endian."""
    shp = "(" + "".join(f"{n}, " for n in shape)[:-2] + ("," if len(shape) == 1 else "") + ")" if shape else "()"
    head = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {shp}, }}"
    pad = 64 - (10 + len(head) + 1) % 64
    head = head + " " * (pad % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(head)) + head.encode() + struct.pack("<" + fmt * len(values), *values)


def voxel_set(depth: int, voxels, compress=False, ijk_descr="<u4") -> bytes:
    """A voxel set file (spec 15.1): voxels are (i, j, k, r, g, b, sigma)."""
    ijk = [c for v in voxels for c in v[:3]]
    entries = [
        ("depth", npy("<u4", (), "I", [depth])),
        ("ijk", npy(ijk_descr, (len(voxels), 3), "I" if ijk_descr == "<u4" else "q", ijk)),
        ("rgb", npy("|u1", (len(voxels), 3), "B", [c for v in voxels for c in v[3:6]])),
        ("sigma", npy("<f4", (len(voxels),), "f", [v[6] for v in voxels])),
    ]
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, data in entries:
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
            info.external_attr = 0o644 << 16
            z.writestr(info, data)
    return buf.getvalue()


def ball_voxels(depth: int, centre, radius: float, root_size: float, colour):
    """The voxels at `depth` whose centres lie in a ball, coloured by
    colour(i, j, k); sigma per voxel from colour too."""
    h = root_size / (1 << depth)
    lo = [max(0, int((c - radius) / h) - 1) for c in centre]
    hi = [int((c + radius) / h) + 1 for c in centre]
    out = []
    for k in range(lo[2], hi[2] + 1):
        for j in range(lo[1], hi[1] + 1):
            for i in range(lo[0], hi[0] + 1):
                x = [(q + 0.5) * h for q in (i, j, k)]
                if sum((a - b) ** 2 for a, b in zip(x, centre)) <= radius * radius:
                    out.append((i, j, k) + colour(i, j, k))
    return out


IMPORT_FILES: dict[str, bytes] = {}


def import_event(w: Writer, folder_file: str, data: bytes, dt=0.1, **kw) -> None:
    IMPORT_FILES[folder_file] = data
    w.ev("import", dt, file=folder_file, sha256=hashlib.sha256(data).hexdigest(), **kw)


def imports() -> str:
    """Imports (spec 15): a ball of voxels imported into its own layer, half
    one colour (settled blocks stay coarse) and half a gradient (refined to
    the set's depth); an erasing slot of sigma-0 voxels cut through a slab
    painted finer than the set; a coarse import over fine paint (every finer
    leaf takes its voxel's value); undo and redo of an import; the result
    rendered and lit."""
    w = Writer({"roots": [2, 2, 2], "max_depth": 7, "root_size": 0.5, "capacity": 4194304}, "Imports", version=2)
    w.brush("box", "paint", 0.3, [0.2, 0.45, 0.9], opacity=0.9, hardness=0.8, aspect=[1.0, 0.15, 1.0])
    w.stroke([[0.5, 0.3, 0.5]])
    w.brush("sphere", "paint", 0.03, [0.95, 0.9, 0.2], opacity=0.9, hardness=0.7, spacing=0.3)
    w.stroke(line([0.3, 0.33, 0.6], [0.7, 0.33, 0.6], 9))
    w.ev("layer", 0.1, op="add", name="ball")

    def ball_colour(i, j, k):
        if i < 16:
            return (230, 120, 40, 40.0)
        return (40 + 8 * (k % 16), 60 + 12 * (j % 16), 200, 30.0 + (i % 5))

    import_event(w, "imports/ball.npz", voxel_set(5, ball_voxels(5, [0.5, 0.55, 0.5], 0.18, 0.5, ball_colour)), name="ball")
    w.ev("snapshot", 0.1, name="imports_ball")
    w.camera([0.5, 0.85, 1.7], [0.5, 0.45, 0.5], size=(192, 144))
    w.ev("render", 0.1, name="imports_ball")
    w.ev("layer", 0.1, op="select", layer="Layer 1")
    slot = [(i, j, 38, 0, 0, 0, 0.0) for j in range(34, 44) for i in range(36, 92)]
    import_event(w, "imports/slot.npz", voxel_set(7, slot), name="slot")
    w.ev("snapshot", 0.1, name="imports_slot")
    w.ev("undo", 0.1)
    w.ev("snapshot", 0.1, name="imports_undone")  # must equal imports_ball
    w.ev("redo", 0.1)
    coarse = [(i, j, k, 90, 200, 120, 12.5) for k in range(2, 4) for j in range(2, 3) for i in range(1, 4)]
    import_event(w, "imports/coarse.npz", voxel_set(3, coarse), name="coarse")
    w.ev("layer", 0.1, op="set", layer="ball", opacity=0.7)
    w.ev("render", 0.1, name="imports_layers")
    w.ev("light", 0.1, dir=[-0.4, 1.0, 0.3], intensity=1.0, ambient=0.25, shadows=True)
    w.ev("render", 0.1, name="imports_lit")
    w.ev("snapshot", 0.0, name="imports")
    return w.text()


def imports_budget() -> str:
    """An import the cell budget cannot hold (spec 15.3, 2.4): the refusal
    warns once and the import is painted at the resolution reached; then an
    empty import (a step that changes nothing) and one on a version 1 tree."""
    w = Writer({"roots": [1, 1, 1], "max_depth": 6, "root_size": 1.0, "capacity": 1200}, "Import budget")

    def colour(i, j, k):
        return ((i * 37) % 256, (j * 53) % 256, (k * 71) % 256, 5.0 + (i + j + k) % 3)

    import_event(w, "imports/budget.npz", voxel_set(5, ball_voxels(5, [0.5, 0.5, 0.5], 0.3, 1.0, colour)))
    w.ev("snapshot", 0.1, name="imports_budget")
    import_event(w, "imports/empty.npz", voxel_set(4, []))
    w.ev("undo", 0.1)
    w.ev("undo", 0.1)
    w.ev("snapshot", 0.1, name="imports_budget_undone")
    w.camera([0.5, 0.5, 2.0], [0.5, 0.5, 0.5], size=(64, 48))
    w.ev("redo", 0.1)
    w.ev("render", 0.1, name="imports_budget")
    return w.text()


TRACES = {
    "single_stamp.jsonl": single_stamp,
    "shapes_modes.jsonl": shapes_modes,
    "undo_redo.jsonl": undo_redo,
    "capacity_limit.jsonl": capacity_limit,
    "edges.jsonl": edges,
    "scene.jsonl": scene,
    "lit.jsonl": lit,
    "mirror.jsonl": mirror,
    "layers.jsonl": layers,
    "settled.jsonl": settled,
    "layers_budget.jsonl": layers_budget,
    "imports.jsonl": imports,
    "imports_budget.jsonl": imports_budget,
}

# --------------------------------------------------------------- malformed
H = '{"format": "ddo-trace", "version": 1, "canvas": {"roots": [1, 1, 1], "max_depth": 6, "root_size": 1.0, "capacity": 4096}}'
BR = '{"ev": "brush", "t": 0, "shape": "sphere", "mode": "paint", "radius": 0.1, "color": [1, 0, 0], "opacity": 1, "hardness": 0.5}'
SB = '{"ev": "stroke_begin", "t": 0}'
SE = '{"ev": "stroke_end", "t": 0}'
SA = '{"ev": "sample", "t": 0, "p": [0.5, 0.5, 0.5]}'
CAM = '{"ev": "camera", "t": 0, "eye": [0.5, 0.5, 2], "q": [0, 0, 0, 1], "fov": [-0.5, 0.5, 0.4, -0.4], "size": [64, 48]}'


H2 = H.replace('"version": 1', '"version": 2')


def _layer(**kw):
    return json.dumps({"ev": "layer", "t": 0, **kw})


def _brush(**over):
    b = json.loads(BR)
    b.update(over)
    return json.dumps(b)


def _cam(**over):
    c = json.loads(CAM)
    c.update(over)
    return json.dumps(c)


def _hdr(**canvas):
    h = json.loads(H)
    h["canvas"].update(canvas)
    return json.dumps(h)


# name: (lines, the line and the kind of error both readers must give: spec 12.2)
MALFORMED = {
    "empty": ([], 1, "header"),
    "not_json": ([H, '{"ev": "brush", "t": 0,'], 2, "json"),
    "not_object": ([H, "[1, 2, 3]"], 2, "type"),
    "no_header": ([BR], 1, "header"),
    "wrong_version": ([H.replace('"version": 1', '"version": 1.5')], 1, "header"),
    "max_depth_too_deep": ([_hdr(max_depth=29)], 1, "range"),
    "lattice_overflow": ([_hdr(roots=[32, 1, 1], max_depth=28)], 1, "range"),
    "capacity_below_roots": ([_hdr(roots=[4, 4, 4], capacity=32)], 1, "budget"),
    "too_many_roots": ([_hdr(roots=[1024, 1024, 32], max_depth=6, capacity=40000000)], 1, "budget"),
    "canvas_missing_roots": (['{"format": "ddo-trace", "version": 1, "canvas": {"max_depth": 6, "root_size": 1.0, "capacity": 4096}}'],
                             1, "missing"),
    "huge_integer": ([H, '{"ev": "undo", "t": 1' + "0" * 400 + '}'], 2, "json"),
    "unknown_event": ([H, '{"ev": "paint", "t": 0}'], 2, "event"),
    "missing_t": ([H, '{"ev": "undo"}'], 2, "missing"),
    "time_backwards": ([H, BR.replace('"t": 0', '"t": 2'), SB.replace('"t": 0', '"t": 1')], 3, "event-order"),
    "unknown_shape": ([H, _brush(shape="star")], 2, "range"),
    "unknown_mode": ([H, _brush(mode="smudge")], 2, "range"),
    "radius_zero": ([H, _brush(radius=0)], 2, "range"),
    "radius_string": ([H, _brush(radius="big")], 2, "type"),
    "color_out_of_range": ([H, _brush(color=[1.5, 0, 0])], 2, "range"),
    "color_short": ([H, _brush(color=[1, 0])], 2, "type"),
    "opacity_out_of_range": ([H, _brush(opacity=-0.1)], 2, "range"),
    "spacing_absurd": ([H, _brush(spacing=1e-9)], 2, "range"),
    "noise_octaves": ([H, _brush(shape="noise", noise={"octaves": 40})], 2, "range"),
    "nan_sample": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [NaN, 0, 0]}'], 4, "json"),
    "infinite_sample": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 1e999, 0]}'], 4, "json"),
    "zero_quaternion": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 0, 0], "q": [0, 0, 0, 0]}'], 4, "range"),
    "pressure_out_of_range": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 0, 0], "pressure": 2}'], 4, "range"),
    "sample_missing_p": ([H, BR, SB, '{"ev": "sample", "t": 0}'], 4, "missing"),
    "sample_outside_stroke": ([H, BR, SA], 3, "event-order"),
    "stroke_in_stroke": ([H, BR, SB, SA, SB], 5, "event-order"),
    "stroke_without_brush": ([H, SB], 2, "event-order"),
    "brush_in_stroke": ([H, BR, SB, BR], 4, "event-order"),
    "end_outside_stroke": ([H, SE], 2, "event-order"),
    "absurd_segment": ([H, _brush(shape="box", radius=1e-6), SB, SA, '{"ev": "sample", "t": 0, "p": [0.9, 0.5, 0.5]}'],
                       5, "budget"),
    "undo_nothing": ([H, '{"ev": "undo", "t": 0}'], 2, "event-order"),
    "redo_nothing": ([H, BR, SB, SA, SE, '{"ev": "redo", "t": 0}'], 6, "event-order"),
    "undo_in_stroke": ([H, BR, SB, '{"ev": "undo", "t": 0}'], 4, "event-order"),
    "fov_unordered": ([H, _cam(fov=[0.5, -0.5, 0.4, -0.4])], 2, "range"),
    "fov_too_wide": ([H, _cam(fov=[-2.0, 0.5, 0.4, -0.4])], 2, "range"),
    "size_zero": ([H, _cam(size=[0, 48])], 2, "range"),
    "size_huge": ([H, _cam(size=[64, 100000])], 2, "range"),
    "render_before_camera": ([H, '{"ev": "render", "t": 0, "name": "x"}'], 2, "event-order"),
    "name_traversal": ([H, '{"ev": "snapshot", "t": 0, "name": "../../etc/passwd"}'],
                       2, "name"),
    "name_dotdot": ([H, '{"ev": "snapshot", "t": 0, "name": ".."}'], 2, "name"),
    "name_duplicate": ([H, '{"ev": "snapshot", "t": 0, "name": "a"}', '{"ev": "snapshot", "t": 0, "name": "a"}'],
                       3, "name"),
    "name_newline": ([H, '{"ev": "snapshot", "t": 0, "name": "a\\n"}'], 2, "name"),
    "deep_nesting": ([H, '{"ev": "undo", "t": 0, "x": ' + "[" * 65 + "]" * 65 + "}"],
                     2, "json"),
    "long_integer": ([H, '{"ev": "undo", "t": ' + "1" * 4301 + "}"],
                     2, "json"),
    "overflowing_segment": ([H, _brush(shape="cone", radius=1e-300), SB, '{"ev": "sample", "t": 0, "p": [1e308, 0, 0]}',
                             '{"ev": "sample", "t": 0, "p": [-1e308, 0, 0]}'],
                            5, "budget"),
    "integral_float_too_big": ([_hdr(max_depth=1e300)],
                               1, "range"),
    "version_string": ([H.replace('"version": 1', '"version": "1"')], 1, "header"),
    "lone_surrogate_event": ([H, '{"ev": "\\ud800", "t": 0}'], 2, "json"),
    "infinity_literal": ([H, '{"ev": "undo", "t": Infinity}'], 2, "json"),
    "integer_beyond_f64": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 0, 2' + "0" * 308 + ']}'], 4, "json"),
    "float_beyond_f64": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 0, 1.8e308]}'], 4, "json"),
    "lone_surrogate_key": ([H, '{"ev": "undo", "t": 0, "\\udc00": 1}'], 2, "json"),
    "bom": (["\ufeff" + H], 1, "json"),
    "light_dir_zero": ([H, '{"ev": "light", "t": 0, "dir": [0, 0, 0]}'], 2, "range"),
    "light_missing_dir": ([H, '{"ev": "light", "t": 0, "intensity": 1}'], 2, "missing"),
    "light_on_string": ([H, '{"ev": "light", "t": 0, "on": "yes", "dir": [0, 1, 0]}'], 2, "type"),
    "light_intensity_absurd": ([H, '{"ev": "light", "t": 0, "dir": [0, 1, 0], "intensity": 1e9}'], 2, "range"),
    "light_shadows_number": ([H, '{"ev": "light", "t": 0, "dir": [0, 1, 0], "shadows": 1}'], 2, "type"),
    "mirror_in_stroke": ([H, BR, SB, SA, '{"ev": "mirror", "t": 0, "axes": [true, false, false], "centre": [0, 0, 0]}'], 5, "event-order"),
    "mirror_axes_short": ([H, '{"ev": "mirror", "t": 0, "axes": [true, false], "centre": [0, 0, 0]}'], 2, "type"),
    "mirror_axes_number": ([H, '{"ev": "mirror", "t": 0, "axes": [1, 0, 0], "centre": [0, 0, 0]}'], 2, "type"),
    "mirror_missing_centre": ([H, '{"ev": "mirror", "t": 0, "axes": [true, false, false]}'], 2, "missing"),
    "mirror_missing_axes": ([H, '{"ev": "mirror", "t": 0, "centre": [0, 0, 0]}'], 2, "missing"),
    "light_dir_overflow": ([H, '{"ev": "light", "t": 0, "dir": [1e200, 1e200, 0]}'], 2, "range"),
    "version_three": ([H.replace('"version": 1', '"version": 3')], 1, "header"),
    "layer_in_version_1": ([H, _layer(op="add", name="a")], 2, "event"),
    "layer_unknown": ([H2, _layer(op="select", layer="nope")], 2, "layer"),
    "layer_delete_only": ([H2, _layer(op="delete", layer="Layer 1")], 2, "layer"),
    "layer_paint_locked": ([H2, _layer(op="set", layer="Layer 1", locked=True), BR, SB, SA, SE], 4, "layer"),
    "layer_name_taken": ([H2, _layer(op="add", name="Layer 1")], 2, "layer"),
    "layer_name_control": ([H2, _layer(op="add", name="a\u0001b")], 2, "range"),
    "layer_name_empty": ([H2, _layer(op="add", name="")], 2, "range"),
    "layer_name_long": ([H2, _layer(op="add", name="x" * 65)], 2, "range"),
    "layer_name_number": ([H2, _layer(op="add", name=7)], 2, "type"),
    "layer_op_unknown": ([H2, _layer(op="flip", layer="Layer 1")], 2, "range"),
    "layer_op_number": ([H2, _layer(op=3)], 2, "type"),
    "layer_op_missing": ([H2, _layer(layer="Layer 1")], 2, "missing"),
    "layer_merge_bottom": ([H2, _layer(op="merge_down", layer="Layer 1")], 2, "layer"),
    "layer_merge_locked": ([H2, _layer(op="add", name="a"), _layer(op="set", layer="Layer 1", locked=True),
                            _layer(op="merge_down", layer="a")], 4, "layer"),
    "layer_move_past": ([H2, _layer(op="move", layer="Layer 1", to=1)], 2, "layer"),
    "layer_move_negative": ([H2, _layer(op="move", layer="Layer 1", to=-1)], 2, "range"),
    "layer_set_nothing": ([H2, _layer(op="set", layer="Layer 1")], 2, "missing"),
    "layer_opacity_range": ([H2, _layer(op="set", layer="Layer 1", opacity=2)], 2, "range"),
    "layer_visible_number": ([H2, _layer(op="set", layer="Layer 1", visible=1)], 2, "type"),
    "layer_in_stroke": ([H2, BR, SB, _layer(op="add", name="a")], 4, "event-order"),
    "layer_seventeen": ([H2] + [_layer(op="add", name=f"n{i}") for i in range(16)], 17, "layer"),
    "layer_after_undo": ([H2, _layer(op="add", name="a"), '{"ev": "undo", "t": 0}', _layer(op="select", layer="a")], 4, "layer"),
    "layer_redo_rename": ([H2, _layer(op="rename", layer="Layer 1", name="b"), '{"ev": "undo", "t": 0}',
                           '{"ev": "redo", "t": 0}', _layer(op="select", layer="Layer 1")], 5, "layer"),
    "layer_undo_select": ([H2, _layer(op="select", layer="Layer 1"), '{"ev": "undo", "t": 0}'], 3, "event-order"),
}

# Malformed imports: the voxel files live in traces/malformed/imports/.
_GOOD = voxel_set(2, [(1, 1, 1, 200, 10, 10, 3.0), (2, 1, 1, 10, 200, 10, 3.0)])
MALFORMED_FILES = {
    "imports/good.npz": _GOOD,
    "imports/deep.npz": voxel_set(7, [(1, 1, 1, 200, 10, 10, 3.0)]),
    "imports/outside.npz": voxel_set(2, [(4, 0, 0, 200, 10, 10, 3.0)]),
    "imports/twice.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, 3.0), (0, 0, 0, 1, 2, 3, 1.0), (1, 1, 1, 1, 2, 3, 1.0)]),
    "imports/nan.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, float("nan"))]),
    "imports/minus_zero.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, -0.0)]),
    "imports/negative.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, -1.0)]),
    "imports/compressed.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, 3.0)], compress=True),
    "imports/wide.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, 3.0)], ijk_descr="<i8"),
    "imports/not_zip.npz": b"ijk rgb sigma\n",
}


def _import(file="imports/good.npz", sha=None, **kw):
    data = MALFORMED_FILES.get(file, b"")
    return json.dumps({"ev": "import", "t": 0, "file": file, "sha256": sha or hashlib.sha256(data).hexdigest(), **kw})


MALFORMED.update({
    "import_missing_file": ([H, _import("imports/absent.npz", sha="0" * 64)], 2, "import"),
    "import_wrong_sha": ([H, _import(sha="a" * 64)], 2, "import"),
    "import_in_stroke": ([H, BR, SB, SA, _import()], 5, "event-order"),
    "import_path_up": ([H, _import("../imports/good.npz")], 2, "name"),
    "import_path_absolute": ([H, _import("/etc/passwd")], 2, "name"),
    "import_sha_short": ([H, _import(sha="abc")], 2, "range"),
    "import_sha_upper": ([H, _import(sha=hashlib.sha256(_GOOD).hexdigest().upper())], 2, "range"),
    "import_file_number": ([H, '{"ev": "import", "t": 0, "file": 3, "sha256": "%s"}' % ("0" * 64)], 2, "type"),
    "import_missing_sha": ([H, '{"ev": "import", "t": 0, "file": "imports/good.npz"}'], 2, "missing"),
    "import_name_empty": ([H, _import(name="")], 2, "range"),
    "import_locked": ([H2, _layer(op="set", layer="Layer 1", locked=True), _import()], 3, "layer"),
    "import_too_deep": ([H, _import("imports/deep.npz")], 2, "import"),
    "import_outside": ([H, _import("imports/outside.npz")], 2, "import"),
    "import_twice": ([H, _import("imports/twice.npz")], 2, "import"),
    "import_nan": ([H, _import("imports/nan.npz")], 2, "import"),
    "import_minus_zero": ([H, _import("imports/minus_zero.npz")], 2, "import"),
    "import_negative": ([H, _import("imports/negative.npz")], 2, "import"),
    "import_compressed": ([H, _import("imports/compressed.npz")], 2, "import"),
    "import_wide": ([H, _import("imports/wide.npz")], 2, "import"),
    "import_not_zip": ([H, _import("imports/not_zip.npz")], 2, "import"),
    "import_undo": ([H, _import(), '{"ev": "undo", "t": 0}', '{"ev": "undo", "t": 0}'], 4, "event-order"),
})


def _write_files(root: str, files: dict) -> list[str]:
    out = []
    for rel, data in sorted(files.items()):
        path = os.path.join(root, *rel.split("/"))
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as f:
            f.write(data)
        out.append(path)
    return out


def write_all(out: str) -> list[str]:
    os.makedirs(os.path.join(out, "malformed"), exist_ok=True)
    written = []
    for name, fn in TRACES.items():
        path = os.path.join(out, name)
        with open(path, "w", encoding="utf-8") as f:
            f.write(fn())
        written.append(path)
    written += _write_files(out, IMPORT_FILES)
    written += _write_files(os.path.join(out, "malformed"), MALFORMED_FILES)
    expected = {}
    for name, (lines, at, kind) in MALFORMED.items():
        path = os.path.join(out, "malformed", name + ".jsonl")
        with open(path, "w", encoding="utf-8") as f:
            f.write("".join(line + "\n" for line in lines))
        expected[name + ".jsonl"] = {"line": at, "kind": kind}
        written.append(path)
    bad_utf8 = os.path.join(out, "malformed", "bad_utf8.jsonl")
    with open(bad_utf8, "wb") as f:
        f.write(H.encode() + b'\n{"ev": "undo", "t": 0, "x": "\xff"}\n')
    expected["bad_utf8.jsonl"] = {"line": 2, "kind": "utf8"}
    written.append(bad_utf8)
    path = os.path.join(out, "malformed", "expected.json")
    with open(path, "w", encoding="utf-8") as f:
        json.dump(expected, f, indent=1, sort_keys=True)
        f.write("\n")
    written.append(path)
    return written


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=HERE, help="output folder (default: traces/)")
    args = ap.parse_args()
    for p in write_all(args.out):
        print(p)


if __name__ == "__main__":
    main()

"""The exact ray: cell sequence, exit points and compositing of one ray in
mpmath (at least 100 significant digits), for the precision study and the
ray caster's tests.

It shares nothing with raycast.py but the tree: positions are canvas
lattice coordinates (not cell frames), the next cell is found by point
location from the root with the cell origins of the dump (not by g3 or
sibling steps), and the exit distance is the ray parameter of the nearest
face. A point exactly on a face belongs to the cell the ray goes into, on
every axis. With 100 digits the rounding error of a path of a million cells
is below 1e-90 lattice units: "exact" for every comparison made with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import mpmath
import numpy as np

NONE = 0xFFFF_FFFF
DPS = 110
T_MIN = mpmath.mpf(1) / 256


@dataclass
class ExactPath:
    """cells [n] (the leaves crossed, in order), exit [n] (exit points,
    lattice coordinates as mpf triples), t [n] (the ray parameter at each
    exit, lattice units along the direction as given), colour (3 mpf,
    background not added), trans (mpf), and the step at which compositing
    stopped (T < 1/256) or n."""

    cells: list
    exit: list
    t: list
    colour: list
    trans: object
    opaque_at: int


def _root_of(x, d, extent, size0, roots):
    """Root index of lattice point x (mpf), boundaries to the side d goes."""
    r = []
    for a in range(3):
        q = int(mpmath.floor(x[a] / size0))
        if x[a] == q * size0 and d[a] < 0:
            q -= 1
        if not 0 <= q < roots[a]:
            return None
        r.append(q)
    return r[0] + roots[0] * (r[1] + roots[1] * r[2])


def locate(arrays, x, d):
    """The leaf containing lattice point x (mpf [3]), a point on a face
    going to the side d points to; None outside the canvas."""
    D = int(arrays["max_depth"])
    roots = [int(r) for r in arrays["roots"]]
    size0 = 1 << D
    extent = [r * size0 for r in roots]
    c = _root_of(x, d, extent, size0, roots)
    if c is None:
        return None
    fc_pool, origin, depth = arrays["first_child"], arrays["origin"], arrays["depth"]
    while int(fc_pool[c]) != NONE:
        half = 1 << (D - int(depth[c]) - 1)
        k = 0
        for a in range(3):
            mid = int(origin[c][a]) + half
            if x[a] > mid or (x[a] == mid and d[a] > 0):
                k |= 1 << a
        c = int(fc_pool[c]) + k
    return c


def exact_path(arrays, eye_lattice, frac, direction, max_steps=1 << 20, dps=DPS) -> ExactPath:
    """Trace one ray exactly. eye_lattice: 3 ints; frac: 3 floats in [0, 1)
    (taken as exact); direction: 3 floats (exact; the ray caster's rounded
    direction, so that the comparison measures traversal error alone).
    The eye must be inside the canvas. Compositing uses |direction| to turn
    parameters into lengths."""
    with mpmath.workdps(dps):
        D = int(arrays["max_depth"])
        lu = mpmath.mpf(float(arrays["root_size"])) * mpmath.mpf(2) ** -D
        eye = [mpmath.mpf(int(e)) + mpmath.mpf(float(f)) for e, f in zip(eye_lattice, frac)]
        d = [mpmath.mpf(float(v)) for v in direction]
        norm = mpmath.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        rgb, sigma = arrays["rgb"], arrays["sigma"]
        origin, depth = arrays["origin"], arrays["depth"]
        c = locate(arrays, eye, d)
        if c is None:
            raise ValueError("the eye must be inside the canvas")
        cells, exits, ts = [], [], []
        colour = [mpmath.mpf(0)] * 3
        trans = mpmath.mpf(1)
        opaque_at = None
        t_prev = mpmath.mpf(0)
        while c is not None and len(cells) < max_steps:
            size = 1 << (D - int(depth[c]))
            best, axis = None, None
            for a in range(3):
                if d[a] == 0:
                    continue
                face = int(origin[c][a]) + (size if d[a] > 0 else 0)
                t = (face - eye[a]) / d[a]
                if best is None or t < best:
                    best, axis = t, a
            x = [eye[a] + best * d[a] for a in range(3)]
            x[axis] = mpmath.mpf(int(origin[c][axis]) + (size if d[axis] > 0 else 0))
            if opaque_at is None:
                length = (best - t_prev) * norm * lu
                e = mpmath.exp(-mpmath.mpf(float(sigma[c])) * length)
                for k in range(3):
                    colour[k] += trans * (1 - e) * (mpmath.mpf(int(rgb[c][k])) / 255)
                trans *= e
                if trans < T_MIN:
                    opaque_at = len(cells) + 1
            cells.append(c)
            exits.append(x)
            ts.append(best)
            t_prev = best
            c = locate(arrays, x, d)
        return ExactPath(cells, exits, ts, colour, trans, len(cells) if opaque_at is None else opaque_at)


def exact_angle(eye_lattice, frac, direction, point, dps=DPS):
    """Angle (radians, mpf) between `direction` and point - eye, exactly:
    the reference for ray_error.angles."""
    with mpmath.workdps(dps):
        w = [mpmath.mpf(point[a]) - (mpmath.mpf(int(eye_lattice[a])) + mpmath.mpf(float(frac[a]))) for a in range(3)]
        d = [mpmath.mpf(float(v)) for v in direction]
        cx = w[1] * d[2] - w[2] * d[1]
        cy = w[2] * d[0] - w[0] * d[2]
        cz = w[0] * d[1] - w[1] * d[0]
        dot = w[0] * d[0] + w[1] * d[1] + w[2] * d[2]
        return mpmath.atan2(mpmath.sqrt(cx * cx + cy * cy + cz * cz), dot)


def as_floats(exits) -> np.ndarray:
    """Exit points as f64 [n, 3] (for plotting and rough comparisons)."""
    return np.array([[float(v) for v in x] for x in exits], np.float64).reshape(-1, 3)

"""Position and angle error of computed ray points, vectorised in
double-double arithmetic (about 106 bits), checked against mpmath in
tests/test_precision.py.

A point the ray caster holds (a local position p in a cell of origin o and
edge S, or a world position in canvas units) is a sum of exact binary
numbers; its offset from the exact eye, w = (o - E) + (p + 1/2) S - phi in
lattice units, is formed with error-free transformations (Knuth's two-sum,
Dekker's two-product: numpy rounds once per operation and never fuses), so
that angle errors of 1e-17 radians at a ray length of one lattice unit are
measured, not drowned in the measurement's own rounding.

Angle error (the paper's section 6 measure): the angle between the direction
the ray caster was given and w, the offset of the computed point from the
eye. Shapes: n points.
"""

from __future__ import annotations

import numpy as np

_SPLIT = 134217729.0  # 2^27 + 1


def two_sum(a, b):
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def two_prod(a, b):
    p = a * b
    c = _SPLIT * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLIT * b
    bh = c - (c - b)
    bl = b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def dd_sum(terms):
    """Sum of f64 arrays as (hi, lo), accurate to ~2^-106 of the largest."""
    hi = np.asarray(terms[0], np.float64)
    lo = np.zeros_like(hi)
    for t in terms[1:]:
        hi, e = two_sum(hi, np.asarray(t, np.float64))
        lo = lo + e
    return two_sum(hi, lo)


def offsets_local(origin, depth, p_local, eye_lattice, frac, max_depth):
    """w = o + (p + 1/2) S - (E + phi) per axis as (hi, lo) f64 [n, 3]
    in lattice units, for local positions p (values of any format, as f64)."""
    size = np.exp2(max_depth - np.asarray(depth, np.float64))[:, None]
    h, l = two_sum(np.asarray(p_local, np.float64), 0.5)
    a = (np.asarray(origin, np.int64) - np.asarray(eye_lattice, np.int64)).astype(np.float64)
    return dd_sum([a, h * size, l * size, -np.asarray(frac, np.float64)])


def offsets_world(p_canvas, eye_lattice, frac, lattice_unit):
    """w for world positions in canvas units (root_size a power of two, so
    that the division by the lattice unit is exact)."""
    x = np.asarray(p_canvas, np.float64) / lattice_unit
    return dd_sum([x, -np.asarray(eye_lattice, np.int64).astype(np.float64), -np.asarray(frac, np.float64)])


def _dd_mul(w, d):
    hi, lo = w
    p, e = two_prod(hi, d)
    return p, e + lo * d


def angles(w, direction):
    """Angle (radians) between direction [n, 3] and w ((hi, lo) [n, 3]),
    and the length |w| (lattice units)."""
    d = np.asarray(direction, np.float64)
    comps = []
    for a, b in ((1, 2), (2, 0), (0, 1)):
        p1 = _dd_mul((w[0][:, a], w[1][:, a]), d[:, b])
        p2 = _dd_mul((w[0][:, b], w[1][:, b]), d[:, a])
        hi, lo = dd_sum([p1[0], -p2[0], p1[1], -p2[1]])
        comps.append(hi + lo)
    cross = np.sqrt(comps[0] ** 2 + comps[1] ** 2 + comps[2] ** 2)
    wf = w[0] + w[1]
    dot = (wf * d).sum(axis=1)
    return np.arctan2(cross, dot), np.sqrt((wf * wf).sum(axis=1))


def position_error(w_computed, w_exact):
    """|computed - exact| (lattice units) of two offsets from the same eye."""
    diff = [dd_sum([w_computed[0][:, a], -w_exact[0][:, a], w_computed[1][:, a], -w_exact[1][:, a]]) for a in range(3)]
    return np.sqrt(sum((h + l) ** 2 for h, l in diff))


def bound(e0, length, eps):
    """The paper's worst case angle: asin(e0 / L + 5 eps) (pi/2 beyond 1)."""
    return np.arcsin(np.minimum(np.asarray(e0) / np.asarray(length) + 5.0 * eps, 1.0))

"""Level of detail (spec 7 "Level of detail"): rays that stop at cells no
wider than k footprints of their pixel and composite those cells'
prefiltered values (spec 4.4) instead of descending to the leaves.

Whether a cell is *small* depends on the cell and the camera alone, never
on the ray: every ray of an image walks the same cut through the tree, so
two neighbouring pixels never disagree about a cell. The camera gives the
pixel pitch alpha (the width of a central pixel at unit distance), its view
axis f, and lam = min(k * alpha, 1); a cell of edge S lattice units whose
centre lies at view depth z (lattice units) is small iff S <= lam * z.
With lam <= 1 the children of a small cell are small too, so the walk's
rule (ascend while the parent is small, descend while the cell is not)
finds the cut of the definition (the first cell from the root that is a
leaf or small).

Painter twin: painter/tree/src/raycast/lod.rs and shaders/raycast.wgsl.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .brush import quat_to_matrix

# The quality the window and the headset use unless the artist changes it
# (spec 7): about one cell per pixel.
DEFAULT_K = 1.0
# The largest quality accepted: beyond it every cell of a normal view is
# small anyway (lam is capped at 1).
MAX_K = 64.0


class Cut(NamedTuple):
    """The cut's constants for one camera, f64: lam = min(k * alpha, 1),
    the view axis f [3] (unit), and the eye as the ray caster splits it,
    E i64 [3] and phi [3] (spec 7 "Start")."""

    lam: jax.Array
    fwd: jax.Array
    eye_lattice: jax.Array
    frac: jax.Array


def check_k(k: float) -> float:
    """k as a float in [0, MAX_K], or ValueError (NaN, infinities, negative
    or absurd qualities)."""
    k = float(k)
    if not (0.0 <= k <= MAX_K):
        raise ValueError(f"level of detail {k!r}: must be a number in [0, {MAX_K:g}] (0: full depth)")
    return k


def pixel_pitch(camera) -> float:
    """alpha: the larger of a pixel's width and height in tangent units,
    max((tan r - tan l)/w, (tan u - tan d)/h), f64 (spec 7)."""
    left, right, up, down = camera.fov
    w, h = camera.size
    return max((math.tan(right) - math.tan(left)) / w, (math.tan(up) - math.tan(down)) / h)


def view_axis(camera) -> np.ndarray:
    """f = M(q) . (0, 0, -1): the third column of the camera rotation,
    negated (f64 [3])."""
    m = quat_to_matrix(camera.q)
    return np.array([-m[0][2], -m[1][2], -m[2][2]], np.float64)


def lam_of(camera, k: float) -> float:
    """lam = min(k * alpha, 1) in f64; 0 when k is 0."""
    return min(check_k(k) * pixel_pitch(camera), 1.0)


def small(cut: Cut, max_depth: int, depth, origin):
    """Whether the cell of `depth` and lattice `origin` (i64 [3]) is no
    wider than lam footprints at its centre's view depth:
    S <= lam * z, z = sum_a f_a * (((o_a - E_a) + S/2) - phi_a), summed in
    axis order (spec 7). Cells at or behind the eye are never small."""
    size = jnp.left_shift(jnp.int64(1), (max_depth - depth).astype(jnp.int64))
    s = size.astype(jnp.float64)
    v = ((origin - cut.eye_lattice).astype(jnp.float64) + s * 0.5) - cut.frac
    z = (v[0] * cut.fwd[0] + v[1] * cut.fwd[1]) + v[2] * cut.fwd[2]
    return s <= cut.lam * z

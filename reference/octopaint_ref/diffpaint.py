"""A sphere stroke painted on a fixed topology as a differentiable function
of its colour, opacity, radius and sample positions (spec 8.3, 8.5, 8.8),
built from brush.py's JAX coverage and blend: the same functions the
painter's jitted kernels run.

"Fixed topology": the cells are given (say the leaves of a uniformly
refined region); refinement, cleaning and the u8/f32 rounding of stored
values are decisions and roundings with no useful derivative, so they are
left out. Every sample has pressure 1 (r = radius, flow 1).

Shapes: n cells, k samples.
"""

from __future__ import annotations

import jax.numpy as jnp

from . import brush as B
from .jax_setup import require_x64


def stroke_values(centres, before_rgb, before_sigma, stroke: dict, hardness: float):
    """(rgb [n, 3], sigma [n]) after painting `stroke` ({colour [3] in [0, 1],
    opacity [], radius [], points [k, 3]}, mode paint) over the
    cells with centres [n, 3] and before-values rgb [n, 3] (floats in [0, 1])
    and sigma [n]: the stroke maximum over its capsules (the first sample a
    sphere, then one capsule per segment), then the paint blend."""
    require_x64()
    pts = stroke["points"]
    p0 = jnp.concatenate([pts[:1], pts[:-1]], axis=0)
    p1 = pts
    k = pts.shape[0]
    r = jnp.broadcast_to(stroke["radius"], (k,))
    ones = jnp.ones(k)
    cov = B.capsule_coverage(jnp, centres, p0, p1, r, r, ones, ones, hardness)
    a = jnp.max(cov, axis=1)
    sigma_b = B.sigma_brush(jnp, stroke["opacity"], stroke["radius"])
    colour = jnp.broadcast_to(stroke["colour"][None, :], before_rgb.shape)
    return B.blend(jnp, "paint", before_rgb, before_sigma, colour, sigma_b, stroke["opacity"], a, 1.0)

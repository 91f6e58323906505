"""Lighting (spec 6.1): every cell's factors of its emitted colour, from
the density gradient across its faces, in f64 jnp (differentiable in sigma
and the light's parameters). The ray caster (raycast.py, march.py) reads
them per cell as it composites."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .device import NONE, Canvas, DeviceTree


class Lighting(NamedTuple):
    """Per-cell factors of the emitted colour (spec 6.1), f64 [N]: a0 the
    part that needs no light (unlit cells 1; lit ones the ambient), a1 the
    direct part (w * intensity * max(n.l, 0)), scaled by the pixel's shadow
    transmittance; and the unit direction towards the light, f64 [3]."""

    a0: jax.Array
    a1: jax.Array
    to_light: jax.Array


# The ramp of the shading weight over the relative gradient r (spec 6.1):
# unlit below R_UNLIT, fully lit above R_LIT.
R_UNLIT = 0.004
R_LIT = 0.02


def _face(tree: DeviceTree, canvas: Canvas, a: int, side: int):
    """What every cell sees across its face on side `side` (+1/-1) of axis
    `a` (spec 6.1): (sigma f64 [N], distance between centres in edges of
    the cell f64 [N]). A same-depth leaf gives its sigma at 1; a same-depth
    cell with children the mean of the four children on the face at 3/4; a
    coarser leaf its sigma at 3/2; nothing (outside the canvas, or a cell
    of another depth) an empty cell at 1."""
    n = tree.parent.shape[0]
    c = jnp.arange(n, dtype=jnp.uint32)
    rx, ry, rz = canvas.roots
    ci = c.astype(jnp.int64)
    rc = [ci % rx, (ci // rx) % ry, ci // (rx * ry)]
    rc[a] = rc[a] + side
    ok = (rc[a] >= 0) & (rc[a] < canvas.roots[a])
    root_nb = jnp.where(ok, (rc[0] + rx * (rc[1] + ry * rc[2])).astype(jnp.uint32), jnp.uint32(NONE))
    bit = (c >> jnp.uint32(a)) & jnp.uint32(1)
    outward = (bit == 1) == (side > 0)
    nb = jnp.where(c < rx * ry * rz, root_nb, jnp.where(outward, tree.g3[:, a], c ^ jnp.uint32(1 << a)))
    gone = nb == NONE
    safe = jnp.where(gone, jnp.uint32(0), nb)
    dn = tree.depth[safe]
    same = ~gone & (dn == tree.depth)
    coarser = ~gone & (dn == tree.depth - 1)
    fc = tree.first_child[safe]
    kids = fc != NONE
    want = 0 if side > 0 else 1
    ks = [k for k in range(8) if (k >> a) & 1 == want]
    kid = [tree.sigma[jnp.where(kids, fc + jnp.uint32(k), jnp.uint32(0))] for k in ks]
    mean = ((kid[0] + kid[1]) + (kid[2] + kid[3])) * 0.25
    sigma = jnp.where(same, jnp.where(kids, mean, tree.sigma[safe]), jnp.where(coarser, tree.sigma[safe], 0.0))
    dist = jnp.where(same & kids, 0.75, jnp.where(coarser, 1.5, 1.0))
    return sigma, dist


def shading(tree: DeviceTree, canvas: Canvas, light) -> Lighting:
    """Every cell's lighting factors (spec 6.1) for `light` (trace.Light),
    in f64 jnp: differentiable in sigma and in the light's parameters.
    Free and empty cells get factors too; they are never composited."""
    ld = np.asarray(light.dir, np.float64)
    ld = ld / np.sqrt(ld[0] * ld[0] + ld[1] * ld[1] + ld[2] * ld[2])
    top = tree.sigma
    delta = []
    for a in range(3):
        s_hi, h_hi = _face(tree, canvas, a, 1)
        s_lo, h_lo = _face(tree, canvas, a, -1)
        delta.append((s_hi - s_lo) / (h_hi + h_lo))
        top = jnp.maximum(top, jnp.maximum(s_hi, s_lo))
    g2 = delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]
    # sqrt's derivative at 0 is infinite: keep it out of the gradient.
    g = jnp.where(g2 > 0, jnp.sqrt(jnp.where(g2 > 0, g2, 1.0)), 0.0)
    r = jnp.where(top > 0, g / jnp.where(top > 0, top, 1.0), 0.0)
    w = jnp.clip((r - R_UNLIT) / (R_LIT - R_UNLIT), 0.0, 1.0)
    # n = -grad / |grad|: the normal points out of the paint.
    n_dot_l = -(delta[0] * ld[0] + delta[1] * ld[1] + delta[2] * ld[2]) / jnp.where(g > 0, g, 1.0)
    a0 = (1.0 - w) + w * light.ambient
    a1 = w * (light.intensity * jnp.maximum(n_dot_l, 0.0))
    return Lighting(a0, a1, jnp.asarray(ld))

"""Lighting (spec 6.1): every cell's stored shading vector v = w n, from
the density gradient across its faces and quantised as the painter stores
it, and what each cell sees across its six faces, in f64 jnp
(differentiable in sigma and the light's parameters: the quantisation
passes gradients straight through). The ray casters (raycast.py,
march.py, diffrender.py) interpolate the vectors at each segment's midpoint
with `factors` as they composite."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .device import NONE, Canvas, DeviceTree


class Lighting(NamedTuple):
    """What the ray casters read to shade a segment (spec 6.1): v f64 [N, 3]
    every cell's stored shading vector, decoded; zero bool [N] where it is
    the zero vector (those cells are unlit); nb u32 [N, 6] the cell
    across each face (0 where there is none); inv_h f64 [N, 6] 1/h there
    (1 for the same depth, 2/3 for one coarser, 0 for nothing to
    interpolate towards); the unit direction towards the light f64 [3], the
    intensity and the ambient term (f64 scalars)."""

    v: jax.Array
    zero: jax.Array
    nb: jax.Array
    inv_h: jax.Array
    to_light: jax.Array
    intensity: jax.Array
    ambient: jax.Array


# The ramp of the shading weight over the relative gradient r (spec 6.1):
# unlit below R_UNLIT, fully lit above R_LIT.
R_UNLIT = 0.004
R_LIT = 0.02


def _across(tree: DeviceTree, canvas: Canvas, a: int, side: int):
    """The cell across every cell's face on side `side` (+1/-1) of axis `a`:
    root array arithmetic for roots, the sibling across an inward face, g3
    across an outward one. (gone bool [N]: none there; safe u32 [N]: the
    cell, 0 where gone)."""
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
    return gone, jnp.where(gone, jnp.uint32(0), nb)


def _face(tree: DeviceTree, canvas: Canvas, a: int, side: int):
    """What every cell sees across its face on side `side` (+1/-1) of axis
    `a` (spec 6.1): (sigma f64 [N], distance between centres in edges of
    the cell f64 [N]). A same-depth leaf gives its sigma at 1; a same-depth
    cell with children the mean of the four children on the face at 3/4; a
    coarser leaf its sigma at 3/2; nothing (outside the canvas, or a cell
    of another depth) an empty cell at 1."""
    gone, safe = _across(tree, canvas, a, side)
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


def quantise(v):
    """The stored components of spec 6.1: floor(v 511 + 1/2) clamped to
    [-511, 511], as f64 integers."""
    return jnp.clip(jnp.floor(v * 511.0 + 0.5), -511.0, 511.0)


def pack(v) -> np.ndarray:
    """The u32 words the painter stores (spec 6.1) for vectors v [N, 3]."""
    q = np.asarray(quantise(jnp.asarray(v))).astype(np.int64) + 512
    return (q[:, 0] | (q[:, 1] << 10) | (q[:, 2] << 20)).astype(np.uint32)


def unpack(words) -> np.ndarray:
    """Decoded vectors f64 [N, 3] of stored words u32 [N]."""
    w = np.asarray(words, np.int64)
    return np.stack([((w >> (10 * a)) & 1023) - 512 for a in range(3)], axis=1) / 511.0


def vectors(tree: DeviceTree, canvas: Canvas):
    """Every cell's shading vector w n (spec 6.1) before quantisation, f64
    [N, 3]: zero where the weight is. Free cells get one too; it is never
    read."""
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
    scale = jnp.where(g > 0, -w / jnp.where(g > 0, g, 1.0), 0.0)
    return jnp.stack([d * scale for d in delta], axis=1)


def _neighbours(tree: DeviceTree, canvas: Canvas):
    """The cell across each face f = 2a + (side > 0) of every cell, u32 [N,
    6] (0 where none), and 1/h there, f64 [N, 6]: 1 at the same depth, 2/3
    one coarser, 0 otherwise (spec 6.1, "Interpolated across the leaf")."""
    nbs, inv = [], []
    for a in range(3):
        for side in (-1, 1):
            gone, safe = _across(tree, canvas, a, side)
            dn = tree.depth[safe]
            h = jnp.where(~gone & (dn == tree.depth), 1.0, jnp.where(~gone & (dn == tree.depth - 1), 2.0 / 3.0, 0.0))
            nbs.append(safe)
            inv.append(h)
    return jnp.stack(nbs, axis=1), jnp.stack(inv, axis=1)


def shading(tree: DeviceTree, canvas: Canvas, light, exact: bool = False) -> Lighting:
    """What the ray casters need to shade by `light` (trace.Light; spec 6.1),
    in f64 jnp: the cells' stored vectors (quantised, gradients passed
    straight through; exact: not quantised, for finite differences), their
    face neighbours, and the light."""
    ld = np.asarray(light.dir, np.float64)
    ld = ld / np.sqrt(ld[0] * ld[0] + ld[1] * ld[1] + ld[2] * ld[2])
    v = vectors(tree, canvas)
    q = jax.lax.stop_gradient(quantise(v))
    zero = jnp.all(q == 0.0, axis=1) if not exact else jnp.all(jax.lax.stop_gradient(v) == 0.0, axis=1)
    if not exact:
        v = v + jax.lax.stop_gradient(q / 511.0 - v)
    nb, inv_h = _neighbours(tree, canvas)
    return Lighting(v, zero, nb, inv_h, jnp.asarray(ld), jnp.asarray(light.intensity, jnp.float64), jnp.asarray(light.ambient, jnp.float64))


def mix(v_cell, v_nb, inv_h, mu):
    """The vector at local point mu [..., 3] of a cell whose own vector is
    v_cell [..., 3], with v_nb [..., 3 axes, 3] and inv_h [..., 3 axes] the
    cell across its face on mu's side on each axis (spec 6.1): the axes'
    terms added in order x, y, z."""
    om = jnp.abs(mu) * inv_h
    v = v_cell
    for a in range(3):
        v = v + om[..., a, None] * (v_nb[..., a, :] - v_cell)
    return v


def sides(mu):
    """The face on mu's side on each axis, f = 2a + (mu_a > 0), int [..., 3]
    (mu_a = 0 takes the -a face, whose weight is 0 anyway)."""
    return jnp.arange(3, dtype=jnp.int32) * 2 + (mu > 0).astype(jnp.int32)


def factors_of(li: Lighting, v):
    """a0, a1 (spec 6.1 "Factors") of the interpolated vectors v [..., 3]."""
    nu2 = jnp.sum(v * v, axis=-1)
    nu = jnp.where(nu2 > 0, jnp.sqrt(jnp.where(nu2 > 0, nu2, 1.0)), 0.0)
    a0 = 1.0 - jnp.minimum(nu, 1.0) * (1.0 - li.ambient)
    a1 = li.intensity * jnp.maximum(jnp.sum(v * li.to_light, axis=-1), 0.0) / jnp.maximum(nu, 1.0)
    return a0, a1


def factors(li: Lighting, cell, mu):
    """a0, a1 of cell [...] (one tree) shaded at its local point mu [..., 3];
    a cell whose own stored vector is zero is unlit (1, 0)."""
    f = sides(mu)
    nb = jnp.take_along_axis(li.nb[cell], f, axis=-1)
    inv_h = jnp.take_along_axis(li.inv_h[cell], f, axis=-1)
    a0, a1 = factors_of(li, mix(li.v[cell], li.v[nb], inv_h, mu))
    z = li.zero[cell]
    return jnp.where(z, 1.0, a0), jnp.where(z, 0.0, a1)


def centre_factors(li: Lighting):
    """Every cell's a0, a1 at its centre: (1 - w) + w A and w I max(n.l, 0)
    of its own stored vector."""
    return factors_of(li, li.v)

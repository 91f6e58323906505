"""Differentiable rendering: images as functions of cell values and of the
eye position, for a fixed cell sequence.

`lax.while_loop` cannot be reverse-differentiated, so a render is split in
two. `record_paths` runs the ray caster (raycast.py, f64 local frame) with
density ignored and keeps, per ray, the cells crossed with their exit axes
and frame maps: that sequence is fixed. `composite` then replays the
sequence with `lax.scan` in plain f64: exit distances from the exit axis,
the exit point, the frame map, emission-absorption with the T < 1/256 stop
(spec 6). Its result equals the ray caster's image (tests/test_gradients.py)
and is differentiable with respect to

- every cell's rgb (as floats in [0, 1]: a relaxation of the stored u8) and
  sigma, through gathers along the paths;
- the eye position, through the start position in the first cell, as long
  as the perturbed rays still cross the recorded cells (a finite difference
  that changes the sequence measures a different function).

With a level of detail (spec 7) the recorded sequence is the cut's: rays
stop at small interior cells, whose values `prefiltered` makes functions of
the leaves below them (the prefilter is linear in sigma), so gradients
still reach the leaves.

Shapes: R rays, K recorded steps, N cells.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import lax

from .jax_setup import require_x64
from .prefilter import inner_units, pair_sum
from .raycast import LEFT, OVERFLOW, T_MIN, Canvas, DeviceTree, Ray, cast, start_points
from .shading import factors


class Paths(NamedTuple):
    """Fixed cell sequences: steps i32 [R]; cell, depth i32 [R, K]; axis i32
    [R, K]; visible bool [R, K]; scale f64 [R, K], shift f64 [R, K, 3] (the
    frame map p_next = p_exit * scale + shift); start_origin i64 [R, 3] and
    start_depth i32 [R] (the first cell), p0 f64 [R, 3] (the start in it)."""

    steps: np.ndarray
    cell: np.ndarray
    depth: np.ndarray
    axis: np.ndarray
    visible: np.ndarray
    scale: np.ndarray
    shift: np.ndarray
    start_origin: np.ndarray
    start_depth: np.ndarray
    p0: np.ndarray


class PathOverflow(ValueError):
    """A ray crossed more cells than the recording capacity."""


def record_paths(tree: DeviceTree, canvas: Canvas, rays: Ray, capacity: int = 256, lod=None) -> Paths:
    """Record each ray's full cell sequence to the canvas boundary (density
    ignored, so the sequence does not depend on the values being fitted).
    lod: (lam, f) of a level of detail's cut (raycast.camera_cut): the
    sequence of the cut's cells, interior ones among them; `prefiltered`
    gives those their values as functions of the leaves'."""
    require_x64()
    blind = tree._replace(sigma=jnp.zeros_like(tree.sigma))
    s, rec = cast(blind, canvas, rays, "f64", "local", max_steps=capacity, record=capacity, lod=lod)
    if np.any(s.status == OVERFLOW):
        raise PathOverflow(f"{int((s.status == OVERFLOW).sum())} ray(s) cross more than {capacity} cells")
    assert np.all(s.status == LEFT)
    hit, cell, depth, origin, p = start_points(tree, canvas, rays, "f64", "local", lod=lod)
    steps = np.where(hit, s.steps, 0)
    k = max(int(steps.max()), 1)  # the scan runs over the longest path only
    return Paths(steps, rec.cell[:, :k].astype(np.int64), rec.depth[:, :k], rec.axis[:, :k], rec.visible[:, :k], rec.scale[:, :k], rec.shift[:, :k], origin, depth, p)


def prefiltered(first_child, depth, rgb, sigma):
    """rgb [N, 3] and sigma [N] with every cell that has children given the
    prefilter of its 8 children (spec 4.4, prefilter.py), deepest first,
    as a differentiable function of the leaves' values: sigma the mean,
    rgb the sigma-weighted mean (octant 0's where all 8 are empty). The
    relaxation of the stored rule: no rounding to f32 or to bytes, as rgb
    is a float in [0, 1] here. first_child, depth: numpy (the topology)."""
    rgb, sigma = jnp.asarray(rgb), jnp.asarray(sigma)
    depth = np.asarray(depth)
    inner, units = inner_units(np.asarray(first_child), depth)
    if not len(inner):
        return rgb, sigma
    d_inner = depth[inner]
    for d in range(int(d_inner.max()), -1, -1):
        at, kids = inner[d_inner == d], units[d_inner == d]
        if not len(at):
            continue
        s = sigma[kids]
        w = pair_sum(s)
        num = pair_sum(s[:, :, None] * rgb[kids])
        pos = w > 0
        mean = num / jnp.where(pos, w, 1.0)[:, None]
        rgb = rgb.at[at].set(jnp.where(pos[:, None], mean, rgb[kids[:, 0]]))
        sigma = sigma.at[at].set(w * 0.125)
    return rgb, sigma


def start_from_eye(paths: Paths, eye_canvas, canvas: Canvas):
    """p0 [R, 3] as a differentiable function of the eye (canvas units, all
    rays sharing it, eye inside the canvas): (eye / lattice_unit - o)/S - 1/2."""
    lu = canvas.root_size * 2.0**-canvas.max_depth
    size = jnp.exp2((canvas.max_depth - jnp.asarray(paths.start_depth)).astype(jnp.float64))[:, None]
    rel = eye_canvas[None, :] / lu - jnp.asarray(paths.start_origin).astype(jnp.float64)
    return rel / size - 0.5


def composite(rgb, sigma, paths: Paths, p0, dirs, canvas: Canvas, background, lighting=None):
    """Colours [R, 3] (background added, not rounded) of the recorded paths
    with cell values rgb f64 [N, 3] (in [0, 1]) and sigma f64 [N], start
    positions p0 [R, 3] and unit directions dirs [R, 3]. lighting: lit
    without shadows (spec 6.1), a shading.Lighting (computed from the same
    sigma to differentiate through the normals), each segment shaded a0 + a1
    at its midpoint; None: unlit."""
    lu = canvas.root_size * 2.0**-canvas.max_depth
    K = paths.cell.shape[1]
    steps = jnp.asarray(paths.steps)
    d = jnp.asarray(dirs)
    safe_d = jnp.where(d != 0, d, 1.0)

    def step(carry, k):
        p, colour, trans = carry
        axis = jnp.asarray(paths.axis)[:, k]
        cell = jnp.asarray(paths.cell)[:, k]
        depth = jnp.asarray(paths.depth)[:, k]
        on_axis = jnp.arange(3, dtype=axis.dtype)[None, :] == axis[:, None]
        d_axis = jnp.sum(jnp.where(on_axis, d, 0.0), axis=1)
        p_axis = jnp.sum(jnp.where(on_axis, p, 0.0), axis=1)
        bound = jnp.where(d_axis > 0, 0.5, -0.5)
        t = jnp.maximum((bound - p_axis) / jnp.sum(jnp.where(on_axis, safe_d, 0.0), axis=1), 0.0)
        length = t * jnp.exp2((canvas.max_depth - depth).astype(jnp.float64)) * lu
        e = jnp.exp(-sigma[cell] * length)
        live = (k < steps) & jnp.asarray(paths.visible)[:, k] & (trans >= T_MIN)
        if lighting is None:
            emitted = rgb[cell]
        else:
            mu = jnp.clip(p + (t * 0.5)[:, None] * d, -0.5, 0.5)
            a0, a1 = factors(lighting, cell, mu)
            emitted = rgb[cell] * (a0 + a1)[:, None]
        colour = colour + jnp.where(live, trans * (1.0 - e), 0.0)[:, None] * emitted
        trans = jnp.where(live, trans * e, trans)
        p_exit = jnp.where(on_axis, bound[:, None], p + t[:, None] * d)
        p_next = p_exit * jnp.asarray(paths.scale)[:, k][:, None] + jnp.asarray(paths.shift)[:, k]
        return (p_next, colour, trans), None

    r = d.shape[0]
    (p, colour, trans), _ = lax.scan(step, (p0, jnp.zeros((r, 3)), jnp.ones(r)), jnp.arange(K, dtype=steps.dtype))
    return colour + trans[:, None] * jnp.asarray(background)[None, :]


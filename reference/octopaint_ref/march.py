"""Documents of several layers (spec 6.2): one cursor per contributing
layer, each walking its own tree by the rules of 7 (raycast.py); every step
composites the interval up to the nearest boundary of any layer."""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .arith import Arith, format_of
from .device import NONE, Canvas, DeviceTree, device_tree
from .jax_setup import require_x64
from .lod import Cut
from .raycast import (
    LEFT,
    MAX_STEPS,
    OPAQUE,
    OVERFLOW,
    RUNNING,
    T_MIN,
    TILE_RAYS,
    Ray,
    Rendered,
    Setup,
    State,
    _exit,
    _start,
    _state,
    _step,
    _tiles,
    camera_cut,
    camera_rays,
    to_pixels,
)
from .shading import Lighting, factors, shading


# A document of several layers (spec 6.2): one cursor per contributing
# layer, each walking its own tree by the rules of 7; every step composites
# the interval up to the nearest boundary of any layer. The cursors walk
# trees whose sigma is zeroed (`_step` then never stops them as opaque);
# compositing reads the real sigma, scaled by the layer's opacity.
class March(NamedTuple):
    cur: State  # [L]: per layer, the cell, depth, origin and point
    active: jax.Array  # bool [L]: still inside the canvas
    colour: jax.Array  # f64 [3] (lit: C0)
    direct: jax.Array  # f64 [3] (lit: C1)
    trans: jax.Array  # f64
    steps: jax.Array  # i32
    status: jax.Array  # i32
    found: jax.Array  # bool: T passed 1/2 (the shadow ray's start)
    s_cur: State  # [L]: the cursors at that point
    s_active: jax.Array  # bool [L]


def stack_trees(arrays_list: list) -> tuple[DeviceTree, Canvas]:
    """The DeviceTrees of several layers (dump arrays each), padded to one
    size and stacked along a leading layer axis."""
    require_x64()
    n = max(len(a["parent"]) for a in arrays_list)
    trees = []
    for a in arrays_list:
        a = dict(a)
        pad = n - len(a["parent"])
        if pad:
            for k, fill in (("parent", NONE), ("first_child", NONE), ("depth", 255), ("rgb", 0), ("sigma", 0)):
                v = np.asarray(a[k])
                a[k] = np.concatenate([v, np.full((pad,) + v.shape[1:], fill, v.dtype)])
            a["g3"] = np.concatenate([np.asarray(a["g3"], np.uint32), np.full((pad, 3), NONE, np.uint32)])
        tree, canvas = device_tree(a)
        trees.append(tree)
    return jax.tree_util.tree_map(lambda *x: jnp.stack(x), *trees), canvas


# The axes of a document's Lighting (shading.py) that run over its layers:
# the cells' arrays; the light is one for all.
PER_LAYER = Lighting(0, 0, 0, 0, None, None, None)


def _march_step(trees: DeviceTree, walk: DeviceTree, setup: Setup, m: Arith, d, opacity, s: March, lighting=None, shadow: bool = False, cut=None) -> March:
    """One step of the march of spec 6.2."""
    n_layers = opacity.shape[0]
    inv = jnp.exp2(-s.cur.depth.astype(jnp.float64))  # a cell edge in root edges, 2^-d_k: exact
    lo, hi = jnp.full(3, -0.5), jnp.full(3, 0.5)
    t_k = jax.vmap(lambda p: _exit(m, p, d, lo, hi)[0])(s.cur.p)
    u_k = jnp.where(s.active, t_k * inv, jnp.inf)
    u = jnp.min(u_k)
    exits = s.active & (u_k == u)
    rows = jnp.arange(n_layers)
    cells = s.cur.cell
    sig_k = jnp.where(s.active & s.cur.visible, opacity * trees.sigma[rows, cells], 0.0)
    sig = sig_k[0]
    for k in range(1, n_layers):
        sig = sig + sig_k[k]
    length = u * setup.canvas.root_size
    e = jnp.exp(-sig * length)
    w = s.trans * (1.0 - e)
    trans = s.trans * e
    colour, direct, found, s_cur, s_active = s.colour, s.direct, s.found, s.s_cur, s.s_active
    if not shadow:
        share = jnp.where(sig > 0, sig_k / jnp.where(sig > 0, sig, 1.0), 0.0)  # [L]
        rgb = trees.rgb[rows, cells]  # [L, 3]
        if setup.lit:
            # Each cursor's leaf shaded at the interval's midpoint in its
            # own frame (spec 6.1, 6.2).
            mu = jnp.clip(m.add(s.cur.p, m.mul(m.rnd(u / inv * 0.5)[:, None], d[None, :])), -0.5, 0.5)
            a0, a1 = jax.vmap(factors, in_axes=(PER_LAYER, 0, 0))(lighting, cells, mu)
            colour = colour + w * jnp.sum((share * a0)[:, None] * rgb, axis=0)
            direct = direct + w * jnp.sum((share * a1)[:, None] * rgb, axis=0)
            cross = ~s.found & (s.trans >= 0.5) & (trans < 0.5)
            per_unit = sig * setup.canvas.root_size
            t_half = jnp.minimum(jnp.log(2.0 * s.trans) / jnp.where(per_unit > 0, per_unit, 1.0), u)
            t_local = m.rnd(t_half / inv)
            p_half = jnp.clip(m.add(s.cur.p, m.mul(t_local[:, None], d[None, :])), -0.5, 0.5)
            found = s.found | cross
            s_cur = jax.tree_util.tree_map(lambda new, old: jnp.where(cross, new, old), s.cur._replace(p=p_half), s.s_cur)
            s_active = jnp.where(cross, s.active, s.s_active)
        else:
            colour = colour + w * jnp.sum(share[:, None] * rgb, axis=0)
    # Exiting cursors step to their next cell (7); the others move along.
    unlit = replace(setup, lit=0)  # the cursors only walk
    stepped = jax.vmap(lambda tr, st: _step(tr, unlit, m, d, st, cut=cut)[0])(walk, s.cur)
    moved = jnp.clip(m.add(s.cur.p, m.mul(m.rnd(u / inv)[:, None], d[None, :])), -0.5, 0.5)

    def pick(new, old):
        sel = exits.reshape((n_layers,) + (1,) * (new.ndim - 1))
        return jnp.where(sel, new, old)

    cur = jax.tree_util.tree_map(pick, stepped, s.cur._replace(p=moved))
    active = s.active & ~(exits & (stepped.status != RUNNING) & (stepped.status != OVERFLOW))
    steps = s.steps + 1
    status = jnp.where(
        trans < T_MIN,
        OPAQUE,
        jnp.where(~jnp.any(active), LEFT, jnp.where(steps >= setup.max_steps, OVERFLOW, RUNNING)),
    ).astype(jnp.int32)
    return March(cur, active, colour, direct, trans, steps, status, found, s_cur, s_active)


def trace_layers_ray(trees: DeviceTree, setup: Setup, opacity, ray: Ray, background, guard, lighting=None, lod=None) -> March:
    """One ray through every layer of `trees` (stacked [L]), spec 6.2."""
    m = Arith(setup.fmt, guard)
    d = m.rnd(ray.dir_canvas)
    walk = trees._replace(sigma=jnp.zeros_like(trees.sigma))
    cut = Cut(lod[0], lod[1], ray.eye_lattice, ray.frac) if setup.lod else None
    hit, cell, depth, origin, p = jax.vmap(lambda tr: _start(tr, setup, ray, m, d, cut))(trees)
    cur = jax.vmap(lambda tr, c, dp, o, pp, h: _state(tr, setup, c, dp, o, pp, h))(trees, cell, depth, origin, p, hit)
    n_layers = opacity.shape[0]
    s0 = March(
        cur,
        hit,
        jnp.zeros(3),
        jnp.zeros(3),
        jnp.float64(1.0),
        jnp.int32(0),
        jnp.where(jnp.any(hit), RUNNING, LEFT).astype(jnp.int32),
        jnp.bool_(False),
        cur,
        jnp.zeros(n_layers, bool),
    )
    s = lax.while_loop(lambda q: q.status == RUNNING, lambda q: _march_step(trees, walk, setup, m, d, opacity, q, lighting, cut=cut), s0)
    colour = s.colour
    if setup.lit == 1:
        colour = colour + s.direct
    elif setup.lit == 2:
        ld = m.rnd(lighting.to_light)
        s1 = s._replace(
            cur=s.s_cur,
            active=s.s_active & s.found,
            trans=jnp.float64(1.0),
            steps=jnp.int32(0),
            status=jnp.where(s.found & jnp.any(s.s_active), RUNNING, LEFT).astype(jnp.int32),
        )
        s1 = lax.while_loop(lambda q: q.status == RUNNING, lambda q: _march_step(trees, walk, setup, m, ld, opacity, q, shadow=True, cut=cut), s1)
        colour = colour + s1.trans * s.direct
    return s._replace(colour=colour + s.trans * background)


@partial(jax.jit, static_argnums=(1,))
def trace_layers_rays(trees: DeviceTree, setup: Setup, opacity, rays: Ray, background, guard, lighting=None, lod=None):
    one = lambda r: trace_layers_ray(trees, setup, opacity, r, background, guard, lighting, lod)
    return jax.vmap(one)(rays)


def render_layers(layers: list, camera, precision="f64", max_steps=MAX_STEPS, tile=TILE_RAYS, light=None, lod=0.0) -> Rendered:
    """The image of several layers, [(dump arrays, opacity)] bottom first
    (spec 6.2), seen by `camera`, lit by `light` as render() is. With no
    layer the image is the background."""
    w, h = camera.size
    if not layers:
        colour = np.broadcast_to(np.asarray(camera.background, np.float64), (h, w, 3)).copy()
        return Rendered(to_pixels(colour), colour, np.zeros((h, w), np.int32), np.full((h, w), LEFT, np.int32), 0)
    trees, canvas = stack_trees([a for a, _ in layers])
    opacity = jnp.asarray(np.array([o for _, o in layers], np.float32).astype(np.float64))
    lit = 0 if light is None or not light.on else (2 if light.shadows else 1)
    lighting = jax.vmap(lambda t: shading(t, canvas, light))(trees) if lit else None
    if lighting is not None:
        lighting = lighting._replace(to_light=lighting.to_light[0], intensity=lighting.intensity[0], ambient=lighting.ambient[0])
    cut = camera_cut(camera, lod)
    setup = Setup(canvas, format_of(precision), "local", int(max_steps), 0, lit, cut is not None)
    cut = (jnp.float64(cut[0]), jnp.asarray(cut[1])) if cut is not None else None
    rays = camera_rays(camera, canvas)
    bg = jnp.asarray(np.asarray(camera.background, np.float64))
    parts = []
    for chunk, k in _tiles(rays, tile):
        s = trace_layers_rays(trees, setup, opacity, chunk, bg, np.uint64(0), lighting, cut)
        parts.append((np.asarray(s.colour)[:k], np.asarray(s.steps)[:k], np.asarray(s.status)[:k]))
    colour = np.concatenate([p[0] for p in parts]).reshape(h, w, 3)
    steps = np.concatenate([p[1] for p in parts]).reshape(h, w)
    status = np.concatenate([p[2] for p in parts]).reshape(h, w)
    return Rendered(to_pixels(colour), colour, steps, status, 0)

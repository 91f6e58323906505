"""The reference ray caster (spec 6 and 7): cell-local traversal of the tree,
emission-absorption compositing, and the naive world-coordinate traversal
the paper's Fig. 12 warns about, for comparison.

One ray is a `lax.while_loop` over cells, written the way a fragment or
compute shader would be: every branch is a select, the state is a handful of
scalars, and the tree is read through `parent`, `first_child`, `depth` and
`g3` only (cell origins are carried along the ray, never looked up), so
shaders/raycast.wgsl and painter/gpu/src/raycast.rs can follow it line by
line. `jax.vmap` runs it over the pixels of a tile; tiles run one after the
other.

Precision (arith.py): positions, exit distances and the eye fraction are f16,
f32 or f64, rounded after every operation as IEEE would. Compositing is f64
in every mode, so that image differences between modes measure the
traversal alone (the subject of the paper's section 6 and its half-precision
question in section 9). The images written at `render` events use f64 in the
local frame: the oracle the GPU ray caster is compared against (spec 13).

Shapes: N cells (padded to a power of two), R rays, K recorded steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .arith import Arith, Format, format_of
from .camera import pixel_directions, split_eye
from .device import NONE, Canvas, DeviceTree, _bucket, device_tree
from .lod import Cut, lam_of, small, view_axis
from .shading import factors, shading

# Why a ray stopped.
RUNNING, LEFT, OPAQUE, LOST, OVERFLOW = 0, 1, 2, 3, 4
STATUS_NAMES = {LEFT: "left the canvas", OPAQUE: "opaque", LOST: "lost (broken depth)", OVERFLOW: "step limit"}
T_MIN = 1.0 / 256.0  # spec 6: stop once transmittance falls below this
MAX_STEPS = 1 << 16
TILE_RAYS = 4096


# ---------------------------------------------------------------- one ray
class Ray(NamedTuple):
    """One ray's input: eye_lattice i64 [3] (may be outside the canvas),
    frac f64 [3] in [0, 1), dir_canvas f64 [3] (unit, exact to f64)."""

    eye_lattice: jax.Array
    frac: jax.Array
    dir_canvas: jax.Array


class State(NamedTuple):
    cell: jax.Array  # u32
    depth: jax.Array  # i32
    origin: jax.Array  # i64 [3], lattice units: carried, never looked up
    p: jax.Array  # f64 [3] holding a value of the working format
    visible: jax.Array  # bool: composite this cell (False: skipped, spec 7)
    colour: jax.Array  # f64 [3]; lit: the part that needs no light (C0, spec 6.1)
    trans: jax.Array  # f64
    steps: jax.Array  # i32
    skipped: jax.Array  # i32: cells crossed without compositing
    status: jax.Array  # i32
    # Lit rays only (spec 6.1); zeros otherwise.
    direct: jax.Array  # f64 [3]: the directly lit part (C1), before shadows
    found: jax.Array  # bool: the opacity passed 0.5 (the shadow ray's start)
    s_cell: jax.Array  # u32: where it did: the cell,
    s_depth: jax.Array  # i32
    s_origin: jax.Array  # i64 [3]
    s_p: jax.Array  # f64 [3]: and the point in its frame


class Record(NamedTuple):
    """Per step k < steps: the cell left, its depth and origin, the exit
    point in that cell's frame (local: cell units; world: canvas units), the
    exit distance t (cell units; world: canvas units), the exit axis, and
    the affine map p_next = p_exit * scale + shift into the next cell's frame
    (local frame only; it includes the one descent)."""

    cell: jax.Array  # u32 [K]
    depth: jax.Array  # i32 [K]
    origin: jax.Array  # i64 [K, 3]
    p_exit: jax.Array  # f64 [K, 3]
    t: jax.Array  # f64 [K]
    axis: jax.Array  # i32 [K]
    visible: jax.Array  # bool [K]
    scale: jax.Array  # f64 [K]
    shift: jax.Array  # f64 [K, 3]


@dataclass(frozen=True)
class Setup:
    """Static parameters of one compiled traversal."""

    canvas: Canvas
    fmt: Format
    frame: str  # "local" or "world"
    max_steps: int
    record: int  # K, 0 for none
    lit: int = 0  # 0 unlit (spec 6), 1 lit, 2 lit with a shadow ray (spec 6.1)
    lod: bool = False  # walk the cut of a level of detail (spec 7, lod.py)

    @property
    def n_roots(self) -> int:
        r = self.canvas.roots
        return r[0] * r[1] * r[2]

    @property
    def lattice_unit(self) -> float:
        return self.canvas.root_size * 2.0**-self.canvas.max_depth


def _size_lattice(setup: Setup, depth):
    """Edge of a cell of `depth` in lattice units, i64."""
    return jnp.left_shift(jnp.int64(1), (setup.canvas.max_depth - depth).astype(jnp.int64))


def _inv_size(setup: Setup, depth):
    """2^-(D - depth), exact f64."""
    return jnp.exp2(-(setup.canvas.max_depth - depth).astype(jnp.float64))


def _locate(tree: DeviceTree, setup: Setup, q, cut=None):
    """The leaf containing lattice point q (i64 [3], inside the canvas) by
    descent from its root (spec 1.3), refusing a descent into a child whose
    parent does not point back; with a level of detail (setup.lod), not
    descending below a small cell either. Returns (cell, depth, origin)."""
    D = setup.canvas.max_depth
    rx, ry, _ = setup.canvas.roots
    root = q >> D
    cell = (root[0] + rx * (root[1] + ry * root[2])).astype(jnp.uint32)
    origin = root << D

    def level(_, s):
        cell, depth, origin = s
        fc = tree.first_child[cell]
        half = _size_lattice(setup, depth + 1)
        bits = (q - origin >= half).astype(jnp.int64)
        k = (bits[0] | (bits[1] << 1) | (bits[2] << 2)).astype(jnp.uint32)
        child = fc + k
        ok = (fc != NONE) & (tree.parent[jnp.where(fc != NONE, child, 0)] == cell)
        if setup.lod:
            ok = ok & ~small(cut, D, depth, origin)
        return (
            jnp.where(ok, child, cell),
            jnp.where(ok, depth + 1, depth),
            jnp.where(ok, origin + bits * half, origin),
        )

    return lax.fori_loop(0, D, level, (cell, jnp.int32(0), origin))


def _clip(setup: Setup, ray: Ray):
    """Entry of a ray into the canvas box, in f64 (spec 7: the entry point
    is split like an eye). Returns (hit, eye_lattice', frac', entry axis or
    -1 when the eye is inside)."""
    extent = jnp.asarray(np.array(setup.canvas.roots, np.int64) << setup.canvas.max_depth)
    e, f, d = ray.eye_lattice, ray.frac, ray.dir_canvas
    inside = jnp.all((e >= 0) & (e < extent))
    # Slab distances in lattice units; (bound - E) is an exact integer.
    t0 = ((0 - e).astype(jnp.float64) - f) / d
    t1 = ((extent - e).astype(jnp.float64) - f) / d
    in_slab = (e >= 0) & (e < extent)
    near = jnp.where(d != 0, jnp.minimum(t0, t1), jnp.where(in_slab, -jnp.inf, jnp.inf))
    far = jnp.where(d != 0, jnp.maximum(t0, t1), jnp.where(in_slab, jnp.inf, -jnp.inf))
    t_in, t_out = jnp.max(near), jnp.min(far)
    axis = jnp.argmax(near).astype(jnp.int32)
    hit = inside | ((t_in <= t_out) & (t_out > 0))
    q = f + t_in * d
    fl = jnp.floor(q)
    e2 = e + fl.astype(jnp.int64)
    f2 = q - fl
    on_axis = jnp.arange(3, dtype=jnp.int32) == axis
    e2 = jnp.where(on_axis, jnp.where(d[axis] > 0, 0, extent), e2)
    f2 = jnp.where(on_axis, 0.0, f2)
    return hit, jnp.where(inside, e, e2), jnp.where(inside, f, f2), jnp.where(inside, -1, axis)


def _start(tree: DeviceTree, setup: Setup, ray: Ray, m: Arith, d, cut=None):
    """The first cell and the position in it (spec 7 'Start')."""
    extent = jnp.asarray(np.array(setup.canvas.roots, np.int64) << setup.canvas.max_depth)
    hit, e, f, entry_axis = _clip(setup, ray)
    q = jnp.clip(e, 0, extent - 1)
    cell, depth, origin = _locate(tree, setup, q, cut)
    if setup.frame == "local":
        inv = _inv_size(setup, depth)
        # (E - o) is exact in integers; scaling it by 2^-(D-d) is exact in
        # f64, so it is rounded once to the working format.
        rel = m.rnd((e - origin).astype(jnp.float64) * inv)
        frac = m.rnd(m.rnd(f) * inv)  # ldexp: one rounding
        p = m.sub(m.add(rel, frac), 0.5)
        face = -0.5 * jnp.sign(d)
    else:
        lu = setup.lattice_unit
        p = m.rnd(e.astype(jnp.float64) * lu + f * lu)
        face = m.rnd(jnp.where(d > 0, 0.0, (extent.astype(jnp.float64)) * lu))
    on_axis = jnp.arange(3, dtype=jnp.int32) == entry_axis
    p = jnp.where(on_axis, face, p)
    if setup.frame == "local":
        p = jnp.clip(p, -0.5, 0.5)
    return hit, cell, depth, origin, p


def _consistent(tree: DeviceTree, setup: Setup, cell):
    """Links agree: a root, or a child whose parent's first_child is its unit."""
    par = tree.parent[cell]
    safe = jnp.where(par != NONE, par, 0)
    return (cell < setup.n_roots) | ((par != NONE) & (tree.first_child[safe] == (cell & jnp.uint32(0xFFFF_FFF8))))


def _exit(m: Arith, p, d, lo, hi):
    """Exit distances per axis, clamped at 0 (a coordinate rounded past its
    face exits at once), and the exit axis: the smallest, ties to the lowest."""
    bound = jnp.where(d > 0, hi, lo)
    t_axes = jnp.where(d != 0, jnp.maximum(m.div(m.sub(bound, p), d), 0.0), jnp.inf)
    axis = jnp.argmin(t_axes).astype(jnp.int32)
    return t_axes[axis], axis, bound[axis]


def _step(tree: DeviceTree, setup: Setup, m: Arith, d, s: State, lighting=None, shadow: bool = False, cut=None):
    """Composite the current cell over its exit distance, move to the exit
    point and into the next cell (spec 7 'Step' and 'Next cell'). Lit
    (setup.lit, spec 6.1): the emitted colour is split into C0 and C1 by the
    cell's factors, and the point where the opacity first passes 0.5 is
    kept for the shadow ray. shadow: a shadow ray, which only attenuates."""
    D = setup.canvas.max_depth
    local = setup.frame == "local"
    size = _size_lattice(setup, s.depth)
    lu = setup.lattice_unit
    if local:
        lo, hi = jnp.full(3, -0.5), jnp.full(3, 0.5)
    else:
        lo = m.rnd(s.origin.astype(jnp.float64) * lu)
        hi = m.rnd((s.origin + size).astype(jnp.float64) * lu)
    t, axis, face = _exit(m, s.p, d, lo, hi)

    # Compositing (f64): len = t * edge in canvas units (world: t already is).
    length = t * (size.astype(jnp.float64) * lu) if local else t
    e = jnp.exp(-tree.sigma[s.cell] * length)
    w = jnp.where(s.visible, s.trans * (1.0 - e), 0.0)
    trans = jnp.where(s.visible, s.trans * e, s.trans)
    direct, found, s_cell, s_depth, s_origin, s_p = s.direct, s.found, s.s_cell, s.s_depth, s.s_origin, s.s_p
    if shadow:
        colour = s.colour
    elif setup.lit:
        # Shaded at the segment's midpoint, in the cell's local frame (spec 6.1).
        mid = m.add(s.p, m.mul(m.rnd(t * 0.5), d))
        mu = jnp.clip(mid, -0.5, 0.5) if local else (mid - (lo + hi) * 0.5) / (hi - lo)
        a0, a1 = factors(lighting, s.cell, mu)
        emitted = w * tree.rgb[s.cell]
        colour = s.colour + emitted * a0
        direct = s.direct + emitted * a1
        # The shadow ray starts where T = 1/2: ln(2 T_before) / sigma canvas
        # units into this cell, at most its exit distance.
        cross = s.visible & ~s.found & (s.trans >= 0.5) & (trans < 0.5)
        per_unit = tree.sigma[s.cell] * ((size.astype(jnp.float64) * lu) if local else 1.0)
        t_half = jnp.minimum(jnp.log(2.0 * s.trans) / jnp.where(per_unit > 0, per_unit, 1.0), t)
        p_half = m.add(s.p, m.mul(m.rnd(t_half), d))
        if local:
            p_half = jnp.clip(p_half, -0.5, 0.5)
        found = s.found | cross
        s_cell = jnp.where(cross, s.cell, s.s_cell)
        s_depth = jnp.where(cross, s.depth, s.s_depth)
        s_origin = jnp.where(cross, s.origin, s.s_origin)
        s_p = jnp.where(cross, p_half, s.s_p)
    else:
        colour = s.colour + w * tree.rgb[s.cell]

    on_axis = jnp.arange(3, dtype=jnp.int32) == axis
    p_exit = jnp.where(on_axis, face, m.add(s.p, m.mul(t, d)))

    # The next cell: a sibling across an inward face, g3 across an outward
    # one, root array arithmetic for roots; NONE: the ray leaves the canvas.
    sgn = jnp.where(d[axis] > 0, 1, -1)
    cell = s.cell
    is_root = cell < setup.n_roots
    octant = cell & jnp.uint32(7)
    bits = jnp.stack([(octant >> jnp.uint32(a)) & jnp.uint32(1) for a in range(3)]).astype(jnp.int64)
    outward = (bits[axis] == 1) == (sgn > 0)
    sibling = cell ^ (jnp.uint32(1) << axis.astype(jnp.uint32))
    rx, ry, rz = setup.canvas.roots
    r = (s.origin >> D) + jnp.where(on_axis, sgn, 0).astype(jnp.int64)
    r_ok = jnp.all((r >= 0) & (r < jnp.array([rx, ry, rz], jnp.int64)))
    root_next = jnp.where(r_ok, (r[0] + rx * (r[1] + ry * r[2])).astype(jnp.uint32), jnp.uint32(NONE))
    nxt = jnp.where(is_root, root_next, jnp.where(outward, tree.g3[cell, axis], sibling))
    gone = nxt == NONE
    safe = jnp.where(gone, jnp.uint32(0), nxt)
    dn = tree.depth[safe]
    same = dn == s.depth
    coarser = dn == s.depth - 1
    lost = ~gone & ~same & ~coarser  # only mid-upload: a freed or unbalanced cell

    step_vec = jnp.where(on_axis, sgn, 0).astype(jnp.int64)
    if local:
        # Same depth: p - s*e_a. One coarser: p/2 + (centre(L) - centre(next))/edge(next)
        # = p/2 + (bit - 1/2)/2 - s*e_a, from L's octant bits (no origin lookup).
        entry = -0.5 * sgn.astype(jnp.float64)
        half_shift = (bits.astype(jnp.float64) - 0.5) * 0.5
        p_coarse = m.add(m.mul(p_exit, 0.5), half_shift)
        p_next = jnp.where(on_axis, entry, jnp.where(coarser, p_coarse, p_exit))
        scale = jnp.where(coarser, 0.5, 1.0)
        shift = jnp.where(on_axis, entry - p_exit * scale, jnp.where(coarser, half_shift, 0.0))
    else:
        p_next = p_exit
        scale, shift = jnp.float64(1.0), jnp.zeros(3)
    o_next = jnp.where(coarser, s.origin - bits * size + step_vec * (2 * size), s.origin + step_vec * size)
    visible = _consistent(tree, setup, safe)

    if setup.lod:
        # The cut (lod.py): up while the parent is small, down while the
        # cell is not (the one descent below is the second loop's first).
        moving = ~gone & ~lost
        cell_n, depth_n, origin_n, p_next, visible_n, scale, shift = _settle(tree, setup, m, cut, moving, safe, dn, o_next, p_next, visible, scale, shift)
    else:
        # At most one descent, into the child containing the entry point (on
        # the entry axis the entry side, which the exact +-0.5 there gives).
        fc = tree.first_child[safe]
        if local:
            cbits = (p_next >= 0).astype(jnp.int64)
        else:
            child_size = _size_lattice(setup, dn + 1)
            centre = m.rnd((o_next + child_size).astype(jnp.float64) * lu)
            cbits = jnp.where(on_axis, (sgn < 0).astype(jnp.int64), (p_next >= centre).astype(jnp.int64))
        k = (cbits[0] | (cbits[1] << 1) | (cbits[2] << 2)).astype(jnp.uint32)
        child = fc + k
        descend = visible & (fc != NONE) & (tree.parent[jnp.where(fc != NONE, child, 0)] == safe)
        if local:
            p_child = m.add(m.mul(p_next, 2.0), jnp.where(cbits == 1, -0.5, 0.5))
            p_next = jnp.where(descend, p_child, p_next)
            shift = jnp.where(descend, shift * 2.0 + jnp.where(cbits == 1, -0.5, 0.5), shift)
            scale = jnp.where(descend, scale * 2.0, scale)
        cell_n = jnp.where(descend, child, safe)
        depth_n = jnp.where(descend, dn + 1, dn)
        origin_n = jnp.where(descend, o_next + cbits * _size_lattice(setup, dn + 1), o_next)
        visible_n = visible | descend

    opaque = trans < T_MIN
    steps = s.steps + 1
    status = jnp.where(
        opaque,
        OPAQUE,
        jnp.where(gone, LEFT, jnp.where(lost, LOST, jnp.where(steps >= setup.max_steps, OVERFLOW, RUNNING))),
    ).astype(jnp.int32)
    new = State(
        cell=cell_n,
        depth=depth_n,
        origin=origin_n,
        p=p_next,
        visible=visible_n,
        colour=colour,
        trans=trans,
        steps=steps,
        skipped=s.skipped + jnp.where(s.visible, 0, 1),
        status=status,
        direct=direct,
        found=found,
        s_cell=s_cell,
        s_depth=s_depth,
        s_origin=s_origin,
        s_p=s_p,
    )
    return new, (s.cell, s.depth, s.origin, p_exit, t, axis, s.visible, scale, shift)


def _settle(tree: DeviceTree, setup: Setup, m: Arith, cut, moving, cell, depth, origin, p, visible, scale=1.0, shift=0.0):
    """From the next cell of a step (same depth or one coarser) to the cell
    of the cut there (spec 7 "Level of detail"): while the cell is not a
    root and its parent is small, go up (p/2 + (bit - 1/2)/2 per axis, the
    octant bits of the cell); then while it has a consistent child at p and
    is not small, go down into it (2p -+ 1/2). Both loops end within D
    rounds. scale, shift: the step's frame map so far (p = p_exit * scale +
    shift, exact f64, the record's), composed with every move. Returns
    (cell, depth, origin, p, visible, scale, shift)."""
    D = setup.canvas.max_depth
    n_roots = setup.n_roots

    def octant(c):
        return jnp.stack([(c >> jnp.uint32(a)) & jnp.uint32(1) for a in range(3)]).astype(jnp.int64)

    def up_ok(q):
        c, dp, o = q[:3]
        par = tree.parent[c]
        return moving & (c >= n_roots) & (par != NONE) & small(cut, D, dp - 1, o - octant(c) * _size_lattice(setup, dp))

    def up(q):
        c, dp, o, pp, _, sc, sh = q
        bits = octant(c)
        par = tree.parent[c]
        half = (bits.astype(jnp.float64) - 0.5) * 0.5
        pp = m.add(m.mul(pp, 0.5), half)
        return par, dp - 1, o - bits * _size_lattice(setup, dp), pp, _consistent(tree, setup, par), sc * 0.5, sh * 0.5 + half

    def child_at(q):
        c, pp = q[0], q[3]
        fc = tree.first_child[c]
        cbits = (pp >= 0).astype(jnp.int64)
        k = (cbits[0] | (cbits[1] << 1) | (cbits[2] << 2)).astype(jnp.uint32)
        return fc, fc + k, cbits

    def down_ok(q):
        c, dp, o, _, vis = q[:5]
        fc, child, _ = child_at(q)
        linked = (fc != NONE) & (tree.parent[jnp.where(fc != NONE, child, 0)] == c)
        return moving & vis & linked & ~small(cut, D, dp, o)

    def down(q):
        _, dp, o, pp, _, sc, sh = q
        _, child, cbits = child_at(q)
        off = jnp.where(cbits == 1, -0.5, 0.5)
        pp = m.add(m.mul(pp, 2.0), off)
        return child, dp + 1, o + cbits * _size_lattice(setup, dp + 1), pp, jnp.bool_(True), sc * 2.0, sh * 2.0 + off

    q0 = (cell, depth, origin, p, visible, jnp.float64(scale), jnp.broadcast_to(jnp.float64(shift), (3,)))
    q = lax.while_loop(up_ok, up, q0)
    return lax.while_loop(down_ok, down, q)


def _state(tree: DeviceTree, setup: Setup, cell, depth, origin, p, running) -> State:
    """A walk about to start in `cell` at `p`."""
    return State(
        cell=cell,
        depth=depth,
        origin=origin,
        p=p,
        visible=_consistent(tree, setup, cell),
        colour=jnp.zeros(3),
        trans=jnp.float64(1.0),
        steps=jnp.int32(0),
        skipped=jnp.int32(0),
        status=jnp.where(running, RUNNING, LEFT).astype(jnp.int32),
        direct=jnp.zeros(3),
        found=jnp.bool_(False),
        s_cell=jnp.uint32(NONE),
        s_depth=jnp.int32(0),
        s_origin=jnp.zeros(3, jnp.int64),
        s_p=jnp.zeros(3),
    )


def trace_ray(tree: DeviceTree, setup: Setup, ray: Ray, background, guard, last_only: bool = False, lighting=None, lod=None):
    """One ray. Returns (State at the end, Record or None); the State's
    colour already includes the background (spec 6), and lit (setup.lit)
    the direct light times the shadow ray's transmittance (spec 6.1).
    last_only: the Record holds only the last step (one row), for callers
    that need no more. lod: (lam, f) of the cut when setup.lod (lod.py)."""
    m = Arith(setup.fmt, guard)
    d = m.rnd(ray.dir_canvas)
    cut = Cut(lod[0], lod[1], ray.eye_lattice, ray.frac) if setup.lod else None
    hit, cell, depth, origin, p = _start(tree, setup, ray, m, d, cut)
    s0 = _state(tree, setup, cell, depth, origin, p, hit)
    K = 1 if last_only else setup.record
    if K:
        rec0 = Record(
            cell=jnp.full(K, NONE, jnp.uint32),
            depth=jnp.zeros(K, jnp.int32),
            origin=jnp.zeros((K, 3), jnp.int64),
            p_exit=jnp.zeros((K, 3)),
            t=jnp.zeros(K),
            axis=jnp.zeros(K, jnp.int32),
            visible=jnp.zeros(K, bool),
            scale=jnp.ones(K),
            shift=jnp.zeros((K, 3)),
        )

        def body(c):
            s, rec = c
            new, r = _step(tree, setup, m, d, s, lighting, cut=cut)
            i = 0 if last_only else s.steps
            rec = Record(*(a.at[i].set(v) for a, v in zip(rec, r)))
            return new, rec

        s, rec = lax.while_loop(lambda c: c[0].status == RUNNING, body, (s0, rec0))
    else:
        s = lax.while_loop(lambda s: s.status == RUNNING, lambda s: _step(tree, setup, m, d, s, lighting, cut=cut)[0], s0)
        rec = None
    if setup.lit == 1:
        s = s._replace(colour=s.colour + s.direct)
    elif setup.lit == 2:
        # One shadow ray towards the light from where the opacity passed
        # 1/2, the same walk with another direction; no start, no light.
        ld = m.rnd(lighting.to_light)
        s1 = _state(tree, setup, s.s_cell, s.s_depth, s.s_origin, s.s_p, s.found)
        s1 = lax.while_loop(lambda q: q.status == RUNNING, lambda q: _step(tree, setup, m, ld, q, shadow=True, cut=cut)[0], s1)
        s = s._replace(colour=s.colour + s1.trans * s.direct)
    s = s._replace(colour=s.colour + s.trans * background)
    return s, rec


@partial(jax.jit, static_argnums=(1,))
def trace_rays(tree: DeviceTree, setup: Setup, rays: Ray, background, guard, lighting=None, lod=None):
    """trace_ray over R rays (vmap): (State [R], Record [R, K] or None)."""
    one = lambda t, r, b, g, li, lo: trace_ray(t, setup, r, b, g, lighting=li, lod=lo)
    return jax.vmap(one, in_axes=(None, 0, None, None, None, None))(tree, rays, background, guard, lighting, lod)


# ---------------------------------------------------------------- images
def to_pixels(colour: np.ndarray) -> np.ndarray:
    """floor(C * 255 + 0.5), clamped (spec 6): uint8."""
    return np.clip(np.floor(np.asarray(colour, np.float64) * 255.0 + 0.5), 0, 255).astype(np.uint8)


@dataclass
class Rendered:
    image: np.ndarray  # uint8 [h, w, 3]
    colour: np.ndarray  # f64 [h, w, 3], before rounding
    steps: np.ndarray  # i32 [h, w]: cells visited
    status: np.ndarray  # i32 [h, w]
    skipped: int

    def count(self, status: int) -> int:
        return int((self.status == status).sum())


def camera_rays(camera, canvas: Canvas) -> Ray:
    """The rays of every pixel of `camera`, flattened row-major: Ray of [h*w]."""
    lu = canvas.root_size * 2.0**-canvas.max_depth
    e, f = split_eye(camera.eye, lu)
    dirs = pixel_directions(camera).reshape(-1, 3)
    n = len(dirs)
    return Ray(np.broadcast_to(e, (n, 3)).copy(), np.broadcast_to(f, (n, 3)).copy(), dirs)


def cast(
    tree: DeviceTree, canvas: Canvas, rays: Ray, precision="f64", frame="local", background=(0.0, 0.0, 0.0), max_steps=MAX_STEPS, record=0, tile=TILE_RAYS, light=None, lod=None, flat=False
):
    """Trace numpy rays in tiles of `tile` (the last one padded with rays
    that miss). Returns (State, Record or None) as numpy arrays [R, ...].
    light: a trace.Light (spec 6.1); None or off: unlit. lod: (lam, f) of a
    level of detail's cut (lod.py; camera_cut), None or lam 0: full depth.
    flat: every lit leaf shaded by its own stored vector alone, not
    interpolated across it (not the spec: a comparison for facets.py)."""
    lit = 0 if light is None or not light.on else (2 if light.shadows else 1)
    lighting = shading(tree, canvas, light) if lit else None
    if flat and lighting is not None:
        lighting = lighting._replace(inv_h=jnp.zeros_like(lighting.inv_h))
    on = lod is not None and float(lod[0]) > 0.0
    if on and frame != "local":
        raise ValueError("a level of detail walks the local frame")
    setup = Setup(canvas, format_of(precision), frame, int(max_steps), int(record), lit, on)
    lod = (jnp.float64(lod[0]), jnp.asarray(np.asarray(lod[1], np.float64))) if on else None
    bg = jnp.asarray(np.asarray(background, np.float64))
    parts = []
    for chunk, k in _tiles(rays, tile):
        s, rec = trace_rays(tree, setup, chunk, bg, np.uint64(0), lighting, lod)
        parts.append(jax.tree_util.tree_map(lambda a: np.asarray(a)[:k], (s, rec)))  # noqa: B023 (called in this iteration only)
    return jax.tree_util.tree_map(lambda *a: np.concatenate(a), *parts)


def _tiles(rays: Ray, tile: int):
    """The rays in tiles of `tile` (at most the rays' size class), the last
    one padded with rays that miss: (tile of rays, how many are real)."""
    n = len(rays.dir_canvas)
    tile = min(tile, _bucket(n)) if n else 1
    for r0 in range(0, n, tile):
        sl = slice(r0, r0 + tile)
        k = len(rays.dir_canvas[sl])
        pad = tile - k

        def padded(a, fill):
            a = np.asarray(a)[sl]  # noqa: B023 (called in this iteration only)
            return np.concatenate([a, np.broadcast_to(fill, (pad,) + a.shape[1:])]) if pad else a  # noqa: B023 (called in this iteration only)

        # Padding rays start far outside the canvas pointing away: they miss.
        chunk = Ray(
            padded(rays.eye_lattice, np.array([-1, -1, -1], np.int64)),
            padded(rays.frac, np.zeros(3)),
            padded(rays.dir_canvas, np.array([-1.0, 0.0, 0.0])),
        )
        yield chunk, k


def camera_cut(camera, k: float):
    """(lam, f) of the level of detail k for `camera` (lod.py), or None
    for k = 0 (full depth)."""
    lam = lam_of(camera, k)
    return (lam, view_axis(camera)) if lam > 0 else None


def render(arrays: dict, camera, precision="f64", frame="local", max_steps=MAX_STEPS, tile=TILE_RAYS, device=None, light=None, lod=0.0, flat=False) -> Rendered:
    """The image of the tree `arrays` (dump arrays) seen by `camera`, lit
    by `light` (a trace.Light; None or off: unlit, spec 6), at level of
    detail `lod` (k of spec 7; 0: every ray walks to the leaves). flat: as
    for cast."""
    tree, canvas = device if device is not None else device_tree(arrays)
    rays = camera_rays(camera, canvas)
    s, _ = cast(tree, canvas, rays, precision, frame, camera.background, max_steps, 0, tile, light, camera_cut(camera, lod), flat)
    w, h = camera.size
    colour = s.colour.reshape(h, w, 3)
    return Rendered(to_pixels(colour), colour, s.steps.reshape(h, w), s.status.reshape(h, w), int(s.skipped.sum()))


@partial(jax.jit, static_argnums=(1,))
def _starts(tree: DeviceTree, setup: Setup, rays: Ray, guard, lod=None):
    def one(ray):
        m = Arith(setup.fmt, guard)
        cut = Cut(lod[0], lod[1], ray.eye_lattice, ray.frac) if setup.lod else None
        return _start(tree, setup, ray, m, m.rnd(ray.dir_canvas), cut)

    return jax.vmap(one)(rays)


def start_points(tree: DeviceTree, canvas: Canvas, rays: Ray, precision="f64", frame="local", lod=None):
    """Where each ray starts: (hit, cell, depth, origin, p) as numpy [R, ...]
    (the position the traversal begins with, for measuring e0). lod: (lam,
    f) of a level of detail's cut, as for cast: the start in the cut."""
    on = lod is not None and float(lod[0]) > 0.0
    setup = Setup(canvas, format_of(precision), frame, 1, 0, 0, on)
    lod = (jnp.float64(lod[0]), jnp.asarray(np.asarray(lod[1], np.float64))) if on else None
    out = _starts(tree, setup, Ray(*(np.asarray(a) for a in rays)), np.uint64(0), lod)
    return tuple(np.asarray(a) for a in out)

"""Painting on the tree: per-segment processing, per-stroke maximum blending,
topology cleaning and undo (spec sections 8-10).

Everything here is exact f64 numpy on the host, in the operation order of
the spec: topology decisions (which leaves are in reach, which refine) and
also coverage and blending, so that the stored values are the IEEE results
the painter computes too, bit for bit (spec 13). XLA may fuse or vectorise
the same expressions differently for different batch shapes (an ulp here
and there), which once made colours differ by a step and, through the
equality test of cleaning, topology too. The same brush.py functions run
under JAX for differentiable painting (diffpaint.py). Painter twin:
painter/paint/src/paint/ (its mod.rs has a table of which file holds what).
"""

from __future__ import annotations

import numpy as np

from . import brush as B
from .history import History
from .noise import permutation
from .stroke import Prims, PrimsHistory, StrokePath, concat
from .trace import Brush, Sample
from .tree import NONE, UNIT, Tree

CHUNK_ENTRIES = 1 << 20  # n * k entries per vectorised evaluation


class Stroke:
    """The state of the stroke in progress (spec 8.8)."""

    def __init__(self, brush: Brush, line: int):
        self.brush = brush
        self.line = line
        # The stroke and its mirrored copies (spec 8.11), in that order.
        masks = (0,) + (brush.mirror.copies() if brush.mirror is not None else ())
        self.paths = [StrokePath(brush, m) for m in masks]
        self.colour = np.array(brush.color, np.float64)
        self.sigma_b = B.sigma_brush_host(brush.opacity, brush.radius)
        self.alpha = float(brush.opacity)
        self.prims = PrimsHistory()
        # Leaves may be settled (spec 8.7): a sphere brush whose colour stays
        # the same along the stroke (every mode but pickup).
        self.settles = brush.shape == "sphere" and brush.mode != "pickup"
        self.capacity_warned = False
        self._init_slots()
        # Deferred cells (spec 8.7), pool-sized: settled at a decision of
        # this stroke, or new children of a deferred cell.
        self.deferred = np.zeros(0, bool)

    def is_deferred(self, cells: np.ndarray) -> np.ndarray:
        """bool mask: which of `cells` are deferred."""
        out = np.zeros(len(cells), bool)
        inside = cells < len(self.deferred)
        out[inside] = self.deferred[cells[inside]]
        return out

    def defer(self, cells: np.ndarray) -> None:
        """Mark `cells` deferred for the rest of the stroke."""
        if not len(cells):
            return
        top = int(cells.max()) + 1
        if top > len(self.deferred):
            grown = np.zeros(max(top, 2 * len(self.deferred)), bool)
            grown[: len(self.deferred)] = self.deferred
            self.deferred = grown
        self.deferred[cells] = True

    def _init_slots(self) -> None:
        # Per touched cell (a slot): the value before the stroke, the stroke
        # maximum a, and the colour of the primitive that gave it.
        self.n = 0
        self.slot_of = np.full(0, -1, np.int64)  # pool-sized: cell -> slot
        self.cell = np.zeros(0, np.int64)
        self.before_rgb = np.zeros((0, 3), np.uint8)
        self.before_sigma = np.zeros(0, np.float32)
        self.a = np.zeros(0, np.float64)
        self.best_colour = np.zeros((0, 3), np.float64)

    def slots(self, cells: np.ndarray) -> np.ndarray:
        """Slot of each cell, -1 for cells the stroke has not touched."""
        out = np.full(len(cells), -1, np.int64)
        inside = cells < len(self.slot_of)
        out[inside] = self.slot_of[cells[inside]]
        return out

    def record(self, cells, before_rgb, before_sigma) -> np.ndarray:
        """Touch `cells` (not yet touched) with their before-values; a = 0."""
        n = len(cells)
        need = self.n + n
        if need > len(self.a):
            cap = max(1024, 2 * need)
            for name in ("cell", "before_rgb", "before_sigma", "a", "best_colour"):
                old = getattr(self, name)
                new = np.zeros((cap,) + old.shape[1:], old.dtype)
                new[: self.n] = old[: self.n]
                setattr(self, name, new)
        top = int(cells.max()) + 1 if n else 0
        if top > len(self.slot_of):
            grown = np.full(max(top, 2 * len(self.slot_of)), -1, np.int64)
            grown[: len(self.slot_of)] = self.slot_of
            self.slot_of = grown
        sl = slice(self.n, need)
        slots = np.arange(self.n, need)
        self.slot_of[cells] = slots
        self.cell[sl] = cells
        self.before_rgb[sl] = before_rgb
        self.before_sigma[sl] = before_sigma
        self.a[sl] = 0.0
        self.best_colour[sl] = 0.0
        self.n = need
        return slots

    def before_values(self, tree, cells):
        """Before-values of `cells` (spec 8.8): recorded for touched cells,
        the stored value otherwise."""
        slots = self.slots(cells)
        before_rgb = tree.rgb[cells].copy()
        before_sigma = tree.sigma[cells].copy()
        had = slots >= 0
        before_rgb[had] = self.before_rgb[slots[had]]
        before_sigma[had] = self.before_sigma[slots[had]]
        return before_rgb, before_sigma

    def history(self) -> Prims | None:
        """Every primitive of the stroke so far (None before the first)."""
        return self.prims.view()


class ImportStroke(Stroke):
    """An import in progress (spec 15.3): the touched cells and their
    before-values, as a stroke keeps them; no primitives."""

    def __init__(self, line: int):
        self.line = line
        self.capacity_warned = False
        self._init_slots()


class Painting:
    """A tree plus the strokes painted on it."""

    def __init__(self, canvas, warn=None):
        self.tree = Tree(canvas.roots, canvas.max_depth, canvas.root_size, canvas.capacity)
        self.stroke: Stroke | None = None
        self.history = History(self.tree)
        self.warn = warn or (lambda msg: None)
        self.after_segment = None  # test hook: called with the Painting
        self.capacity_refusals = 0
        # Settled leaves are left unrefined (spec 8.7); off only to test that
        # the rule changes no value (the painter's set_settling).
        self.settling = True

    # ------------------------------------------------------------ strokes
    def begin_stroke(self, brush: Brush, line: int = 0) -> None:
        assert self.stroke is None, "stroke already open"
        self.history.begin()
        self.stroke = Stroke(brush, line)
        self.stroke.settles &= self.settling
        if brush.shape == "noise":
            self._perm = permutation(brush.noise.seed)

    def add_sample(self, sample: Sample, line: int = 0) -> None:
        st = self.stroke
        assert st is not None, "sample outside a stroke"
        if st.brush.mode == "pickup":
            c = self.tree.leaf_at(sample.p)
            if c is not None and self.tree.sigma[c] > 0:
                canvas_rgb = self.tree.rgb[c].astype(np.float64) / 255.0
                st.colour = st.colour + (canvas_rgb - st.colour) * st.brush.pickup_rate
        seg = concat([path.segment(sample, st.colour.copy()) for path in st.paths])
        st.prims.append(seg)
        if len(seg):
            self._process_segment(st, seg, line)
        if self.after_segment is not None:
            self.after_segment(self)

    def end_stroke(self) -> None:
        st = self.stroke
        assert st is not None, "no stroke open"
        self.stroke = None
        self._clean_and_commit(st)

    def _clean_and_commit(self, st: Stroke) -> None:
        """The end of a stroke or an import: cleaning from the touched cells
        (spec 9), then one undo step (spec 10)."""
        from .clean import clean

        clean(self.tree, st.cell[: st.n].copy())
        self.history.commit()

    def _round(self, st: Stroke, candidates: np.ndarray, line: int):
        """One refinement round (spec 4.2) on `candidates`: the new cells
        and whether the cell budget refused part of it (the first refusal
        of a stroke or import warns, spec 2.4)."""
        tree = self.tree
        units, refused = tree.refine_round(candidates)
        if refused:
            self.capacity_refusals += 1
            if not st.capacity_warned:
                st.capacity_warned = True
                self.warn(
                    f"line {line}: the cell budget of {tree.capacity} cells is exhausted: "
                    "refinement refused, painting goes on at the resolution reached"
                )
        return (units[:, None] + np.arange(UNIT)[None, :]).ravel(), refused

    # ------------------------------------------------------------ imports
    def import_voxels(self, vs, line: int = 0) -> None:
        """Paint the voxel set `vs` as one undo step (spec 15.3)."""
        from .voxelset import VoxelIndex

        assert self.stroke is None, "import inside a stroke"
        tree = self.tree
        self.history.begin()
        st = ImportStroke(line)
        index = VoxelIndex(vs, tree.max_depth)
        d = vs.depth
        if len(vs):
            # 1. Traverse from the roots that hold a voxel.
            r = vs.ijk.astype(np.int64) >> d
            R = tree.roots
            frontier = np.unique(r[:, 0] + R[0] * (r[:, 1] + R[1] * r[:, 2]))
            paint = []
            while len(frontier):
                fc = tree.first_child[frontier]
                reached = index.reached(tree, frontier)
                leaf = fc == NONE
                paint.append(frontier[reached & leaf])
                inner = fc[reached & ~leaf].astype(np.int64)
                frontier = (inner[:, None] + np.arange(UNIT)[None, :]).ravel()
            leaves = np.concatenate(paint)
            # 2. Paint pass: touched, written their import value.
            st.record(leaves, tree.rgb[leaves].copy(), tree.sigma[leaves].copy())
            self._write_import(st, index, leaves)
            # 3-4. Refine what is not settled, round by round.
            candidates = self._import_candidates(st, index, leaves)
            while len(candidates):
                new, refused = self._round(st, candidates, line)
                if not len(new):
                    break
                before_rgb, before_sigma = st.before_values(tree, tree.parent[new].astype(np.int64))
                st.record(new, before_rgb, before_sigma)
                self._write_import(st, index, new)
                if refused:
                    break
                new = new[index.reached(tree, new)]
                candidates = self._import_candidates(st, index, new)
        # 5. Cleaning; one undo step.
        self._clean_and_commit(st)

    def _write_import(self, st, index, cells: np.ndarray) -> None:
        """Write each touched cell's import value: its centre voxel's value,
        or its before-value where the set has no voxel there."""
        tree = self.tree
        found, rgb, sigma = index.centre_values(tree, cells)
        slots = st.slots(cells)
        rgb[~found] = st.before_rgb[slots[~found]]
        sigma[~found] = st.before_sigma[slots[~found]]
        tree.rgb[cells] = rgb
        tree.sigma[cells] = sigma

    def _import_candidates(self, st, index, cells: np.ndarray) -> np.ndarray:
        """The reached leaves among `cells` above the set's depth that are
        not settled (15.3)."""
        tree = self.tree
        cells = cells[(tree.first_child[cells] == NONE) & (tree.depth[cells] < index.d)]
        slots = st.slots(cells)
        settled = index.settled(tree, cells, st.before_rgb[slots], st.before_sigma[slots])
        return cells[~settled]

    def undo(self) -> None:
        self.history.undo()

    def redo(self) -> None:
        self.history.redo()

    # ------------------------------------------------------- one segment
    def _process_segment(self, st: Stroke, seg: Prims, line: int) -> None:
        leaves, needs = self._leaves_in_reach(seg)
        # A deferred leaf needs refinement by any primitive of the stroke so
        # far (spec 8.7), sigma read before the paint pass as for the rest.
        again = ~needs & st.is_deferred(leaves)
        needs[again] = self._needs_by_stroke(st, leaves[again])
        a, best = self._evaluate(st, seg, leaves)
        hit = a > 0
        self._apply(st, leaves[hit], a[hit], seg.colour[best[hit]])
        candidates = self._unsettled(st, leaves[needs])
        while len(candidates):
            new, refused = self._round(st, candidates, line)
            if not len(new):
                break
            self._paint_new_cells(st, new)
            if refused:
                break
            need = self._needs_refinement(st, seg, new)
            inherit = st.is_deferred(self.tree.parent[new].astype(np.int64))
            st.defer(new[inherit])
            again = ~need & inherit
            need[again] = self._needs_by_stroke(st, new[again])
            candidates = self._unsettled(st, new[need])

    def _unsettled(self, st: Stroke, cells: np.ndarray) -> np.ndarray:
        """The cells among `cells` (each needing refinement) that are not
        settled; the settled ones become deferred (spec 8.7)."""
        settled = self._settled(st, cells)
        st.defer(cells[settled])
        return cells[~settled]

    def _needs_by_stroke(self, st: Stroke, cells: np.ndarray) -> np.ndarray:
        """bool mask: the leaves among `cells` that some capsule of the
        stroke so far must refine (a deferred leaf's test, spec 8.7). Only
        sphere strokes defer. The capsules tested are those whose boxes,
        grown by twice the largest h·K, meet the cells' centres: a capsule
        within reach of a ball has the ball's centre at most r(u) + h·K from
        its axis, inside its box grown by h·K."""
        out = np.zeros(len(cells), bool)
        hist = st.history()
        if not len(cells) or hist is None:
            return out
        tree = self.tree
        x = tree.centres(cells)
        h = float(tree.reach_radius[tree.depth[cells]].max())
        arr = hist.arrays
        grow = (2.0 * h * B.capsule_slacks(np, arr["p0"], arr["p1"], arr["r0"], arr["r1"]))[:, None]
        near = np.nonzero(np.all(hist.hi + grow >= x.min(axis=0), axis=1) & np.all(hist.lo - grow <= x.max(axis=0), axis=1))[0]
        if len(near):
            leaf = tree.first_child[cells] == NONE
            out = self._reach(st, hist.take(near), cells, leaf)[1]
        return out

    def _paint_new_cells(self, st: Stroke, cells: np.ndarray) -> None:
        """New children take their parent's before-value and their own
        stroke maximum over every segment so far (spec 8.8)."""
        tree = self.tree
        before_rgb, before_sigma = st.before_values(tree, tree.parent[cells].astype(np.int64))
        a = np.zeros(len(cells))
        colour = np.zeros((len(cells), 3))
        hist = st.history()
        if hist is not None:
            centres = tree.centres(cells)
            lo, hi = centres.min(axis=0), centres.max(axis=0)
            near = np.nonzero(np.all(hist.hi >= lo, axis=1) & np.all(hist.lo <= hi, axis=1))[0]
            if len(near):
                sub = hist.take(near)
                a, best = self._evaluate(st, sub, cells)
                colour = sub.colour[best]
        st.record(cells, before_rgb, before_sigma)
        # Every new cell is written: one outside the brush goes back to its
        # before-value, not its parent's painted value.
        self._apply(st, cells, a, colour, force=True)

    def _apply(self, st: Stroke, cells: np.ndarray, a: np.ndarray, colour: np.ndarray, force=False) -> None:
        """Raise the stroke maximum of `cells` to `a` where larger and write
        blend(before, brush, a) for the cells that changed (all if force)."""
        if len(cells) == 0:
            return
        tree = self.tree
        slots = st.slots(cells)
        fresh = slots < 0
        if fresh.any():
            fc = cells[fresh]
            slots[fresh] = st.record(fc, tree.rgb[fc].copy(), tree.sigma[fc].copy())
        up = a > st.a[slots]
        write = up | force
        slots_up = slots[up]
        st.a[slots_up] = a[up]
        st.best_colour[slots_up] = colour[up]
        if not write.any():
            return
        w = slots[write]
        with np.errstate(all="ignore"):
            rgb, sigma = B.blend(
                np,
                st.brush.mode,
                st.before_rgb[w].astype(np.float64) / 255.0,
                st.before_sigma[w].astype(np.float64),
                st.best_colour[w],
                st.sigma_b,
                st.alpha,
                st.a[w],
                st.brush.mix_ratio,
            )
        cw = cells[write]
        tree.rgb[cw] = B.quantize_rgb(rgb)
        tree.sigma[cw] = B.quantize_sigma(sigma)

    # ----------------------------------------------------- evaluation
    def _evaluate(self, st: Stroke, prims: Prims, cells: np.ndarray):
        """Stroke maximum of coverage * flow over `prims` at the centres of
        `cells`, and the index of the first primitive attaining it (exact
        numpy, in chunks of at most CHUNK_ENTRIES cell-primitive pairs). A
        primitive covers nothing outside its box (spec 8.5), so the painter
        may test the box first. A NaN coverage (only from absurd inputs)
        makes the maximum NaN, which never counts as a hit."""
        n, k = len(cells), len(prims)
        a = np.zeros(n)
        best = np.zeros(n, np.int64)
        if n == 0 or k == 0:
            return a, best
        x_all = self.tree.centres(cells)
        b = st.brush
        arr = prims.arrays
        step = max(1, CHUNK_ENTRIES // k)
        with np.errstate(all="ignore"):
            for n0 in range(0, n, step):
                x = x_all[n0 : n0 + step]
                if b.shape == "sphere":
                    cov = B.capsule_coverage(
                        np, x, arr["p0"], arr["p1"], arr["r0"], arr["r1"], arr["f0"], arr["f1"], b.hardness, arr["open"]
                    )
                else:
                    cov = B.stamp_coverage(
                        np,
                        b.shape,
                        x,
                        arr["c"],
                        arr["r"],
                        arr["f"],
                        arr["rot"],
                        np.array(b.aspect),
                        b.hardness,
                        self._perm if b.shape == "noise" else None,
                        b.noise.frequency / b.radius,
                        b.noise.octaves,
                        b.noise.gain,
                        arr["m"],
                        None if b.mirror is None else b.mirror.centre,
                    )
                inside = np.all((prims.lo[None, :, :] <= x[:, None, :]) & (x[:, None, :] <= prims.hi[None, :, :]), axis=2)
                ca, cb = B.max_and_argmax(np, np.where(inside, cov, 0.0))
                a[n0 : n0 + len(x)] = ca
                best[n0 : n0 + len(x)] = cb
        return a, best

    def _settled(self, st: Stroke, cells: np.ndarray) -> np.ndarray:
        """bool mask: the leaves among `cells` whose refinement could not
        change a value (spec 8.7). Over the ball of a leaf's reach radius h,
        every capsule of the stroke whose box meets the ball's box bounds
        its coverage * flow to [lo, hi]; the stroke maximum lies in
        [max lo, max hi], and the leaf is settled when the stored blend is
        the same at both ends (the blend and the rounding are monotone in
        a), or when nothing covers the ball."""
        n = len(cells)
        out = np.zeros(n, bool)
        hist = st.history()
        if not st.settles or n == 0 or hist is None:
            return out
        tree = self.tree
        x = tree.centres(cells)
        h = tree.reach_radius[tree.depth[cells]]
        ball_lo, ball_hi = x - h[:, None], x + h[:, None]
        arr = hist.arrays
        a_lo = np.zeros(n)
        a_hi = np.zeros(n)
        bad = np.zeros(n, bool)
        step = max(1, CHUNK_ENTRIES // len(hist))
        with np.errstate(all="ignore"):
            for n0 in range(0, n, step):
                sl = slice(n0, n0 + step)
                meets = np.all(hist.hi[None, :, :] >= ball_lo[sl, None, :], axis=2) & np.all(
                    hist.lo[None, :, :] <= ball_hi[sl, None, :], axis=2
                )
                lo, hi = B.capsule_coverage_bounds(
                    np, x[sl], h[sl], arr["p0"], arr["p1"], arr["r0"], arr["r1"], arr["f0"], arr["f1"], st.brush.hardness
                )
                bad[sl] = np.any(meets & ~((lo >= 0.0) & (hi >= 0.0)), axis=1)
                a_lo[sl] = np.max(np.where(meets, lo, 0.0), axis=1)
                a_hi[sl] = np.max(np.where(meets, hi, 0.0), axis=1)
        before_rgb, before_sigma = st.before_values(tree, cells)
        colour = np.broadcast_to(st.colour, (n, 3))
        b = st.brush

        def stored(a):
            with np.errstate(all="ignore"):
                rgb, sigma = B.blend(
                    np, b.mode, before_rgb.astype(np.float64) / 255.0, before_sigma.astype(np.float64),
                    colour, st.sigma_b, st.alpha, a, b.mix_ratio,
                )
            return B.quantize_rgb(rgb), B.quantize_sigma(sigma).view(np.uint32)

        rgb_lo, sig_lo = stored(a_lo)
        rgb_hi, sig_hi = stored(a_hi)
        same = np.all(rgb_lo == rgb_hi, axis=1) & (sig_lo == sig_hi)
        out = (a_hi < B.TINY) | ((a_lo >= B.TINY) & same)
        return out & ~bad

    def _reach(self, st: Stroke, prims: Prims, cells: np.ndarray, want_needs):
        """Exact host decisions for `cells`: within reach of any primitive of
        the segment, and, for the cells selected by the bool mask
        `want_needs`, needing refinement by any primitive (spec 8.7)."""
        if st.brush.shape == "sphere":
            # One capsule per copy of the stroke (spec 8.11): within reach of
            # any, needing refinement by any that reaches.
            reach, needs = self._reach_one_capsule(prims.take(slice(0, 1)), cells, want_needs)
            for k in range(1, len(prims)):
                rk, nk = self._reach_one_capsule(prims.take(slice(k, k + 1)), cells, want_needs)
                reach |= rk
                needs |= nk
        else:
            reach, needs = self._reach_stamps(st, prims, cells, want_needs)
        if st.brush.mode in ("erase", "recolor"):
            needs &= self.tree.sigma[cells] > 0  # nothing there to change
        return reach, needs

    def _reach_stamps(self, st: Stroke, prims: Prims, cells: np.ndarray, want_needs):
        tree = self.tree
        n, k = len(cells), len(prims)
        reach = np.zeros(n, bool)
        needs = np.zeros(n, bool)
        if n == 0 or k == 0:
            return reach, needs
        x_all = tree.centres(cells)
        d_all = tree.depth[cells]
        h_all = tree.reach_radius[d_all]
        b = st.brush
        arr = prims.arrays
        step = max(1, CHUNK_ENTRIES // k)
        for n0 in range(0, n, step):
            sl = slice(n0, n0 + step)
            x, h, d = x_all[sl], h_all[sl], d_all[sl]
            rk = B.stamp_reach(np, b.shape, x, arr["c"], arr["r"], arr["rot"], b.aspect, h)
            reach[sl] = rk.any(axis=1)
            sel = want_needs[sl] & reach[sl]
            if sel.any():
                td = B.target_depth(np.broadcast_to(arr["r"][None, :], rk.shape)[sel], tree.root_size, tree.max_depth)
                part = needs[sl]
                part[sel] = (rk[sel] & (d[sel][:, None] < td)).any(axis=1)
                needs[sl] = part
        return reach, needs

    def _reach_one_capsule(self, seg: Prims, cells: np.ndarray, want_needs: np.ndarray):
        """_reach for one capsule of a sphere segment (a segment holds one
        per copy of the stroke, spec 8.11), written out on 1-D columns: the same operations in the same order as
        capsule_geometry (the traversal calls this once per depth level, so
        its overhead counts)."""
        assert len(seg) == 1
        tree = self.tree
        a = seg.arrays
        p0, p1 = a["p0"][0], a["p1"][0]
        r0, r1 = a["r0"][0], a["r1"][0]
        d0, d1, d2 = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
        dd = d0 * d0 + d1 * d1 + d2 * d2
        depth = tree.depth[cells]
        half = tree.half_lattice[depth]
        o = tree.origin[cells]
        unit = tree.lattice_unit
        x0 = (o[:, 0] + half) * unit
        x1 = (o[:, 1] + half) * unit
        x2 = (o[:, 2] + half) * unit
        w0, w1, w2 = x0 - p0[0], x1 - p0[1], x2 - p0[2]
        t = w0 * d0 + w1 * d1 + w2 * d2
        if dd >= B.TINY:
            u = t / dd
            np.clip(u, 0.0, 1.0, out=u)
        else:
            u = np.zeros(len(cells))
        e0 = x0 - (p0[0] + u * d0)
        e1 = x1 - (p0[1] + u * d1)
        e2 = x2 - (p0[2] + u * d2)
        r = r0 + (r1 - r0) * u
        slack = B.capsule_slack(p0, p1, r0, r1)
        h = tree.reach_radius[depth]
        reach = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2) - r <= h * slack
        if a["open"][0]:
            # An open start (spec 8.3): a cell whose ball lies behind the
            # start plane, with a margin far above the rounding of t, holds
            # no point this capsule covers (spec 8.7).
            dn = np.sqrt(dd)
            wabs = np.abs(w0) + np.abs(w1) + np.abs(w2)
            reach &= ~(t < -(h * dn + 1e-12 * (wabs + h) * dn))
        sel = want_needs & reach
        needs = np.zeros(len(cells), bool)
        if sel.any():
            needs[sel] = depth[sel] < B.target_depth(r[sel], tree.root_size, tree.max_depth)
        return reach, needs

    def _needs_refinement(self, st: Stroke, seg: Prims, cells: np.ndarray) -> np.ndarray:
        """bool mask: the leaves among `cells` this segment must refine."""
        leaf = self.tree.first_child[cells] == NONE
        return self._reach(st, seg, cells, leaf)[1]

    def _leaves_in_reach(self, seg: Prims):
        """Every leaf within reach of the segment, and which of them it must
        refine: a top-down traversal from the roots whose boxes touch the
        segment's bounds."""
        tree = self.tree
        st = self.stroke
        rs = tree.root_size
        # Clamped as floats before the conversion: a huge brush makes these
        # infinite (fmax/fmin, like the painter's max/min, ignore NaN).
        lo = np.fmax(np.floor((seg.lo.min(axis=0) - rs) / rs), 0.0)
        hi = np.fmin(np.floor((seg.hi.max(axis=0) + rs) / rs), np.array(tree.roots) - 1.0)
        if not np.all(hi >= lo):
            return np.zeros(0, np.int64), np.zeros(0, bool)
        lo, hi = lo.astype(np.int64), hi.astype(np.int64)
        gx, gy, gz = np.meshgrid(*(np.arange(lo[a], hi[a] + 1) for a in range(3)), indexing="ij")
        frontier = (gx + tree.roots[0] * (gy + tree.roots[1] * gz)).ravel().astype(np.int64)
        leaves, needs = [], []
        while len(frontier):
            fc = tree.first_child[frontier]
            leaf = fc == NONE
            reach, need = self._reach(st, seg, frontier, leaf)
            keep = reach & leaf
            leaves.append(frontier[keep])
            needs.append(need[keep])
            inner = fc[reach & ~leaf].astype(np.int64)
            frontier = (inner[:, None] + np.arange(UNIT)[None, :]).ravel()
        return np.concatenate(leaves), np.concatenate(needs)

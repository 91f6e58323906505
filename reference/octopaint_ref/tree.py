"""The octree: pools, the allocator, refinement with 2:1 face balance, coarsening.

Rules: docs/spec.md sections 2-4. The painter's twin is painter/octree/src/pool/mod.rs
and painter/octree/src/balance.rs; both must produce identical indices.

Pools are numpy arrays in structure-of-arrays layout, grown by doubling:

    parent      u32   index of the parent, NONE for roots and free cells
    first_child u32   index of child octant 0, NONE for leaves and free cells
    depth       u8    0 = root, FREE (255) = free cell
    rgb         u8x3  sRGB colour
    sigma       f32   extinction per canvas unit

The reference also keeps `origin` (u32x3, lattice units) as a side table the
painter derives instead of storing. Every topology operation works on whole
batches of cells (numpy), with results identical to doing them one cell at a
time in the normative order.
"""

from __future__ import annotations

import numpy as np

NONE = np.uint32(0xFFFF_FFFF)
NONE_INT = 0xFFFF_FFFF
FREE = 255
EMPTY = np.zeros(0, np.int64)
UNIT = 8
# Faces in the normative balance order: -x, +x, -y, +y, -z, +z (axis, sign).
FACES = ((0, -1), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1))


class CapacityError(Exception):
    """The cell budget is exhausted: the refinement was refused."""


def _units_to_cells(units: np.ndarray) -> np.ndarray:
    return (np.asarray(units, np.int64)[:, None] + np.arange(UNIT)[None, :]).ravel()


class Tree:
    """A root array of octrees with pooled cells."""

    POOL_NAMES = ("parent", "first_child", "depth", "rgb", "sigma", "origin")

    def __init__(self, roots=(4, 4, 4), max_depth=24, root_size=1.0, capacity=1 << 24):
        self.roots = tuple(int(r) for r in roots)
        self.max_depth = int(max_depth)
        self.root_size = float(root_size)
        self.capacity = int(capacity)
        self.n_roots = self.roots[0] * self.roots[1] * self.roots[2]
        self.n_padded = (self.n_roots + UNIT - 1) // UNIT * UNIT
        if self.capacity < self.n_padded:
            raise ValueError(f"capacity {self.capacity} is below the {self.n_padded} cells the roots need")
        # Canvas units per lattice unit: exact (a power-of-two scaling).
        self.lattice_unit = self.root_size * 2.0**-self.max_depth
        self.extent = np.array(self.roots, np.int64) << self.max_depth  # lattice units per axis
        # Per depth: half a cell in lattice units, and the edge in canvas units.
        d = np.arange(self.max_depth + 1)
        self.half_lattice = np.ldexp(0.5, self.max_depth - d)  # exact powers of two
        self.size_canvas = np.ldexp(self.lattice_unit, self.max_depth - d)
        # The reach radius: how far any centre inside a cell (its own, its
        # descendants') lies from its centre, HALF_DIAG * (size - finest
        # size) (spec 8.7). 0.8660254037844386 is brush.HALF_DIAG.
        self.reach_radius = 0.8660254037844386 * (self.size_canvas - self.size_canvas[self.max_depth])
        self._alloc_arrays(max(self.n_padded, 64))
        self.n_used = self.n_padded
        r = np.arange(self.n_roots, dtype=np.int64)
        rx, ry, _ = self.roots
        size = 1 << self.max_depth
        self.depth[: self.n_roots] = 0
        self.origin[: self.n_roots, 0] = (r % rx) * size
        self.origin[: self.n_roots, 1] = ((r // rx) % ry) * size
        self.origin[: self.n_roots, 2] = (r // (rx * ry)) * size
        self.free_units = EMPTY.copy()  # sorted, all below n_used
        # Topology changes since the last take_dirty(): the cells that gained
        # or lost children, and the units created or freed (spec 3.4).
        self._changed_cells: list[np.ndarray] = []
        self._changed_units: list[np.ndarray] = []
        self.dirty: set[int] = set()  # cells marked dirty directly (undo/redo)

    # ------------------------------------------------------------------ pools
    def _alloc_arrays(self, n: int) -> None:
        self.parent = np.full(n, NONE, np.uint32)
        self.first_child = np.full(n, NONE, np.uint32)
        self.depth = np.full(n, FREE, np.uint8)
        self.rgb = np.zeros((n, 3), np.uint8)
        self.sigma = np.zeros(n, np.float32)
        self.origin = np.full((n, 3), NONE, np.uint32)

    def _grow_to(self, n: int) -> None:
        cap = len(self.parent)
        if n <= cap:
            return
        new_cap = cap
        while new_cap < n:
            new_cap *= 2
        new_cap = min(new_cap, max(n, self.capacity))
        old = {k: getattr(self, k) for k in self.POOL_NAMES}
        self._alloc_arrays(new_cap)
        for k, a in old.items():
            getattr(self, k)[: len(a)] = a

    def available_units(self) -> int:
        return len(self.free_units) + (self.capacity - self.n_used) // UNIT

    def allocate_units(self, m: int) -> np.ndarray:
        """m units, exactly those m single lowest-free-unit allocations would
        return (spec 2.3): the lowest free units, then new units at the end.
        The caller checks available_units() first."""
        assert m <= self.available_units()
        take = min(m, len(self.free_units))
        units = self.free_units[:take]
        self.free_units = self.free_units[take:]
        grow = m - take
        if grow:
            new = self.n_used + UNIT * np.arange(grow, dtype=np.int64)
            self._grow_to(self.n_used + UNIT * grow)
            self.n_used += UNIT * grow
            units = np.concatenate([units, new])
        return units

    def free(self, units: np.ndarray) -> None:
        cells = _units_to_cells(units)
        self.parent[cells] = NONE
        self.first_child[cells] = NONE
        self.depth[cells] = FREE
        self.rgb[cells] = 0
        self.sigma[cells] = 0
        self.origin[cells] = NONE
        self.free_units = np.union1d(self.free_units, np.asarray(units, np.int64))
        self._trim()

    def _trim(self) -> None:
        """Trailing free units are given back: the used length stays minimal."""
        fu = self.free_units
        n = self.n_used
        k = len(fu)
        while k and fu[k - 1] == n - UNIT:
            n -= UNIT
            k -= 1
        self.n_used = n
        self.free_units = fu[:k]

    def rebuild_free_units(self) -> None:
        """Recompute the free-unit list from the depth pool (after undo/redo)."""
        units = np.arange(self.n_padded, self.n_used, UNIT, dtype=np.int64)
        self.free_units = units[self.depth[units] == FREE]

    # -------------------------------------------------------------- geometry
    def cell_size_lattice(self, d):
        return np.left_shift(np.int64(1), self.max_depth - np.asarray(d, np.int64))

    def centres(self, cells: np.ndarray) -> np.ndarray:
        """Cell centres in canvas units, f64 [n, 3]: (origin + size/2) times
        the lattice unit (spec 1.3)."""
        half = self.half_lattice[self.depth[cells]]
        return (self.origin[cells] + half[:, None]) * self.lattice_unit

    def sizes(self, cells: np.ndarray) -> np.ndarray:
        """Cell edge lengths in canvas units, f64 [n]."""
        return self.size_canvas[self.depth[cells]]

    def cell_at(self, q: np.ndarray, max_d: np.ndarray) -> np.ndarray:
        """The cell containing lattice points q [n, 3] (all inside the
        canvas) of the greatest depth <= max_d [n]: a descent from the root."""
        q = np.asarray(q, np.int64)
        size0 = np.int64(1) << self.max_depth
        r = q // size0
        c = r[:, 0] + self.roots[0] * (r[:, 1] + self.roots[1] * r[:, 2])
        active = np.arange(len(q))
        qa = q
        md = np.asarray(max_d, np.int64)
        octant_weights = np.array([1, 2, 4], np.int64)
        while len(active):
            ca = c[active]
            fc = self.first_child[ca]
            dep = self.depth[ca]
            go = (fc != NONE) & (dep < md)
            if not go.all():
                active, ca, fc, dep, qa, md = active[go], ca[go], fc[go], dep[go], qa[go], md[go]
                if not len(active):
                    break
            half = np.left_shift(np.int64(1), self.max_depth - 1 - dep.astype(np.int64))
            k = ((qa - self.origin[ca]) >= half[:, None]) @ octant_weights
            c[active] = fc + k
        return c

    def across(self, cells: np.ndarray) -> np.ndarray:
        """[n, 6] in face order: for each cell and face, the cell of greatest
        depth <= the cell's own covering the cell-sized region across that
        face; -1 at the canvas boundary. One batched descent for all faces."""
        cells = np.asarray(cells, np.int64)
        n = len(cells)
        d = self.depth[cells].astype(np.int64)
        size = self.cell_size_lattice(d)
        o = self.origin[cells].astype(np.int64)
        q = np.repeat(o[:, None, :], 6, axis=1)
        for f, (axis, sign) in enumerate(FACES):
            q[:, f, axis] += sign * size
        q = q.reshape(-1, 3)
        inside = np.all((q >= 0) & (q < self.extent[None, :]), axis=1)
        out = np.full(6 * n, -1, np.int64)
        out[inside] = self.cell_at(q[inside], np.repeat(d, 6)[inside])
        return out.reshape(n, 6)

    # ------------------------------------------------------------- topology
    def _across_where(self, cells: np.ndarray, keep) -> np.ndarray:
        """across(cells), with -1 where keep(neighbour depth, cell depth) fails."""
        cells = np.asarray(cells, np.int64)
        nb = self.across(cells)
        ok = nb >= 0
        ok[ok] = keep(self.depth[nb[ok]], np.repeat(self.depth[cells][:, None], 6, axis=1)[ok])
        return np.where(ok, nb, -1)

    def coarser_neighbours(self, cells: np.ndarray) -> np.ndarray:
        """[n, 6] in face order: the coarser leaf across each face, or -1."""
        return self._across_where(cells, np.less)

    def refine_round(self, candidates: np.ndarray) -> tuple[np.ndarray, bool]:
        """Refine the leaves `candidates` as if one at a time in ascending
        index order, each first refining (recursively, faces in the normative
        order) every coarser face-neighbour leaf (spec 4.2). Returns the new
        units in allocation order, and whether the cell budget stopped the
        round (the refinements before that point stand)."""
        cand = np.unique(np.asarray(candidates, np.int64))
        cand = cand[self.first_child[cand] == NONE]
        if not len(cand):
            return EMPTY, False
        # The closure: every leaf the balance recursion reaches, with its
        # coarser neighbours in the original tree. A neighbour found coarser
        # here is still the coarser one when the sequential recursion reaches
        # it, unless it was refined earlier in the same round (visited).
        nbrs: dict[int, list[int]] = {}
        frontier = cand
        while len(frontier):
            cn = self.coarser_neighbours(frontier)
            found = []
            for c, row in zip(frontier.tolist(), cn.tolist()):
                ns = [n for n in row if n >= 0]
                nbrs[c] = ns
                found.extend(n for n in ns if n not in nbrs)
            frontier = np.unique(np.array(found, np.int64)) if found else EMPTY
        order: list[int] = []
        seen: set[int] = set()

        def visit(c: int) -> None:
            seen.add(c)
            for n in nbrs[c]:
                if n not in seen:
                    visit(n)
            order.append(c)

        for c in cand.tolist():
            if c not in seen:
                visit(c)
        refused = len(order) > self.available_units()
        if refused:
            order = order[: self.available_units()]
        if not order:
            return EMPTY, refused
        parents = np.array(order, np.int64)
        units = self.allocate_units(len(parents))
        self._make_children(parents, units)
        return units, refused

    def _make_children(self, parents: np.ndarray, units: np.ndarray) -> None:
        cells = _units_to_cells(units)
        p = np.repeat(parents, UNIT)
        k = np.tile(np.arange(UNIT, dtype=np.int64), len(parents))
        d = self.depth[p].astype(np.int64) + 1
        half = self.cell_size_lattice(d)
        self.parent[cells] = p
        self.first_child[cells] = NONE
        self.depth[cells] = d
        self.rgb[cells] = self.rgb[p]
        self.sigma[cells] = self.sigma[p]
        o = self.origin[p].astype(np.int64)
        o[:, 0] += (k & 1) * half
        o[:, 1] += ((k >> 1) & 1) * half
        o[:, 2] += ((k >> 2) & 1) * half
        self.origin[cells] = o
        self.first_child[parents] = units
        self._changed_cells.append(parents)
        self._changed_units.append(units)

    def coarsen(self, cells: np.ndarray) -> None:
        """Collapse the 8 leaf children of each cell into it (the caller has
        checked mergeable() and balance_allows_coarsen()). A collapsed cell
        takes child octant 0's values."""
        cells = np.asarray(cells, np.int64)
        if not len(cells):
            return
        units = self.first_child[cells].astype(np.int64)
        self._changed_cells.append(cells)
        self._changed_units.append(units)
        self.rgb[cells] = self.rgb[units]
        self.sigma[cells] = self.sigma[units]
        self.first_child[cells] = NONE
        self.free(units)

    def _facing_children(self, cells: np.ndarray) -> np.ndarray:
        """[n, 6, 4]: per face, the children facing the cell of its internal
        same-depth neighbour across that face; -1 where there is none."""
        cells = np.asarray(cells, np.int64)
        nb = self.same_depth_neighbours(cells)
        out = np.full((len(cells), 6, 4), -1, np.int64)
        for f, (axis, sign) in enumerate(FACES):
            n = nb[:, f]
            ok = n >= 0
            ok[ok] = self.first_child[n[ok]] != NONE
            side = 0 if sign > 0 else 1
            ks = np.array([k for k in range(UNIT) if (k >> axis) & 1 == side])
            out[ok, f] = self.first_child[n[ok]].astype(np.int64)[:, None] + ks[None, :]
        return out

    def balance_allows_coarsen(self, cells: np.ndarray) -> np.ndarray:
        """bool [n]: collapsing each cell's children keeps 2:1 face balance:
        every child of a same-depth face neighbour that faces the cell is a leaf."""
        fc = self._facing_children(np.asarray(cells, np.int64))
        has = fc >= 0
        inner = np.zeros_like(has)
        inner[has] = self.first_child[fc[has]] != NONE
        return ~inner.reshape(len(fc), 24).any(axis=1)

    def mergeable(self, cells: np.ndarray) -> np.ndarray:
        """bool [n]: all 8 children are leaves and all empty or all identical."""
        cells = np.asarray(cells, np.int64)
        fc = self.first_child[cells]
        ok = fc != NONE
        kids = _units_to_cells(fc[ok].astype(np.int64)).reshape(-1, UNIT)
        leaves = np.all(self.first_child[kids] == NONE, axis=1)
        sigma = self.sigma[kids]
        rgb = self.rgb[kids]
        empty = np.all(sigma == 0, axis=1)
        same = np.all(sigma == sigma[:, :1], axis=1) & np.all(rgb == rgb[:, :1, :], axis=(1, 2))
        ok[ok] = leaves & (empty | same)
        return ok

    def same_depth_neighbours(self, cells: np.ndarray) -> np.ndarray:
        """[n, 6]: the same-depth face neighbours of each cell, -1 if none."""
        return self._across_where(cells, np.equal)

    def collapsible(self, cells: np.ndarray) -> np.ndarray:
        """bool [n]: mergeable and balance allows the collapse (spec 9)."""
        m = self.mergeable(cells)
        m[m] = self.balance_allows_coarsen(np.asarray(cells, np.int64)[m])
        return m

    def take_dirty(self) -> np.ndarray:
        """The cells whose g3 must be recomputed since the last call, sorted
        (spec 3.4): every cell created or freed, and for every cell that
        gained or lost children, the 4 children facing it of each internal
        same-depth face neighbour. Computed on demand from the changes
        recorded since the last call; a cell whose g3 changed is a facing
        child of a changed cell's neighbour at any later time too, so the
        set is exact or larger, never smaller."""
        marks = [np.array(sorted(self.dirty), np.int64)]
        if self._changed_units:
            marks.append(_units_to_cells(np.concatenate(self._changed_units)))
            cells = np.unique(np.concatenate(self._changed_cells))
            cells = cells[self.depth[cells] != FREE]
            fc = self._facing_children(cells)
            marks.append(fc[fc >= 0])
        self._changed_cells, self._changed_units, self.dirty = [], [], set()
        return np.unique(np.concatenate(marks))

    def dirty_regions(self, cells: np.ndarray, mask_shape=(64, 32)) -> np.ndarray:
        """The neighbour-mask bits (spec 3.5) covering `cells`: bool[32, 64]
        (row-major: region i is row i // 64, column i % 64)."""
        w, h = mask_shape
        n_regions = w * h
        region_cells = -(-self.capacity // n_regions)
        bits = np.zeros(n_regions, bool)
        bits[np.asarray(cells, np.int64) // region_cells] = True
        return bits.reshape(h, w)

    # --------------------------------------------------------------- queries
    def leaf_at(self, p_canvas) -> int | None:
        """The leaf containing a canvas point, or None outside the canvas.
        Lattice coordinate: floor(p / lattice_unit)."""
        lat = []
        for a in range(3):
            x = float(p_canvas[a]) / self.lattice_unit
            if not 0.0 <= x < float(self.extent[a]):
                return None
            lat.append(int(np.floor(x)))
        c = self.cell_at(np.array([lat], np.int64), np.array([self.max_depth], np.int64))
        return int(c[0])

    def leaves(self) -> np.ndarray:
        n = self.n_used
        return np.nonzero((self.depth[:n] != FREE) & (self.first_child[:n] == NONE))[0]

    def check_allocator(self) -> list[str]:
        """Allocator invariants (tests): the free list is exactly the free
        units below the used length, sorted, and the last unit is in use."""
        problems = []
        units = np.arange(self.n_padded, self.n_used, UNIT, dtype=np.int64)
        expect = units[self.depth[units] == FREE]
        if not np.array_equal(expect, self.free_units):
            problems.append("free-unit list differs from the free units in the pools")
        if self.n_used > self.n_padded and self.depth[self.n_used - UNIT] == FREE:
            problems.append("the last unit is free but the used length was not trimmed")
        beyond = self.depth[self.n_used :]
        if np.any(beyond != FREE):
            problems.append("cells beyond the used length are not free")
        return problems

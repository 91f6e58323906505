"""The octree: pools, the allocator, refinement with 2:1 face balance, coarsening.

Rules: docs/spec.md sections 2-4. The painter's twin is painter/tree/src/pool.rs
and painter/tree/src/balance.rs; both must produce identical indices.

Pools are numpy arrays in structure-of-arrays layout, grown by doubling:

    parent      u32   index of the parent, NONE for roots and free cells
    first_child u32   index of child octant 0, NONE for leaves and free cells
    depth       u8    0 = root, FREE (255) = free cell
    rgb         u8x3  sRGB colour
    sigma       f32   extinction per canvas unit

The reference also keeps `origin` (u32x3, lattice units) and a dictionary from
(depth, origin) to index: side tables the painter derives instead of storing.
"""

from __future__ import annotations

import heapq

import numpy as np

NONE = np.uint32(0xFFFF_FFFF)
NONE_INT = 0xFFFF_FFFF
FREE = 255
UNIT = 8
# Faces in the normative balance order: -x, +x, -y, +y, -z, +z (axis, sign).
FACES = ((0, -1), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1))


class CapacityError(Exception):
    """The cell budget is exhausted: the refinement was refused."""


def _key(depth: int, x: int, y: int, z: int) -> int:
    return (((depth << 32 | x) << 32 | y) << 32) | z


class Tree:
    """A root array of octrees with pooled cells."""

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
        self.lattice_unit = self.root_size * 2.0 ** -self.max_depth
        self._alloc_arrays(max(self.n_padded, 64))
        self.n_used = self.n_padded
        r = np.arange(self.n_roots, dtype=np.int64)
        rx, ry, rz = self.roots
        size = 1 << self.max_depth
        self.depth[: self.n_roots] = 0
        self.origin[: self.n_roots, 0] = (r % rx) * size
        self.origin[: self.n_roots, 1] = ((r // rx) % ry) * size
        self.origin[: self.n_roots, 2] = (r // (rx * ry)) * size
        self.keys = {}
        for i in range(self.n_roots):
            o = self.origin[i]
            self.keys[_key(0, int(o[0]), int(o[1]), int(o[2]))] = i
        self._free_heap: list[int] = []
        self._free_set: set[int] = set()
        self.dirty: set[int] = set()

    # ------------------------------------------------------------------ pools
    def _alloc_arrays(self, n: int) -> None:
        self.parent = np.full(n, NONE, np.uint32)
        self.first_child = np.full(n, NONE, np.uint32)
        self.depth = np.full(n, FREE, np.uint8)
        self.rgb = np.zeros((n, 3), np.uint8)
        self.sigma = np.zeros(n, np.float32)
        self.origin = np.full((n, 3), NONE, np.uint32)

    POOL_NAMES = ("parent", "first_child", "depth", "rgb", "sigma", "origin")

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

    def allocate_unit(self) -> int:
        """Lowest-index free unit, else a new unit at the end (spec 2.3)."""
        while self._free_heap:
            u = heapq.heappop(self._free_heap)
            if u in self._free_set:
                self._free_set.discard(u)
                return u
        if self.n_used + UNIT > self.capacity:
            raise CapacityError(f"cell budget of {self.capacity} cells is exhausted")
        u = self.n_used
        self._grow_to(u + UNIT)
        self.n_used += UNIT
        return u

    def free_unit(self, u: int) -> None:
        s = slice(u, u + UNIT)
        self.parent[s] = NONE
        self.first_child[s] = NONE
        self.depth[s] = FREE
        self.rgb[s] = 0
        self.sigma[s] = 0
        self.origin[s] = NONE
        self._free_set.add(u)
        heapq.heappush(self._free_heap, u)
        # Trailing free units are given back: the used length stays minimal.
        while self.n_used > self.n_padded and (self.n_used - UNIT) in self._free_set:
            self.n_used -= UNIT
            self._free_set.discard(self.n_used)

    def rebuild_index(self) -> None:
        """Recompute the allocator state and key dictionary from the pools
        (after undo/redo swapped pool contents)."""
        n = self.n_used
        free_units = [u for u in range(self.n_padded, n, UNIT) if self.depth[u] == FREE]
        self._free_set = set(free_units)
        self._free_heap = list(free_units)
        heapq.heapify(self._free_heap)
        live = np.nonzero(self.depth[:n] != FREE)[0]
        d = self.depth[live].astype(object)
        o = self.origin[live].astype(object)
        self.keys = {
            (((int(dd) << 32 | int(ox)) << 32 | int(oy)) << 32) | int(oz): int(i)
            for i, dd, ox, oy, oz in zip(live, d, o[:, 0], o[:, 1], o[:, 2])
        }

    # -------------------------------------------------------------- geometry
    def cell_size_lattice(self, d):
        return np.left_shift(np.int64(1), self.max_depth - np.asarray(d, np.int64))

    def centres(self, cells: np.ndarray) -> np.ndarray:
        """Cell centres in canvas units, f64 [n, 3] (spec 1.3: exact lattice
        origin plus half a cell, times the lattice unit)."""
        cells = np.asarray(cells, np.int64)
        half = self.cell_size_lattice(self.depth[cells]).astype(np.float64) * 0.5
        return (self.origin[cells].astype(np.float64) + half[:, None]) * self.lattice_unit

    def sizes(self, cells: np.ndarray) -> np.ndarray:
        """Cell edge lengths in canvas units, f64 [n]."""
        return self.cell_size_lattice(self.depth[np.asarray(cells, np.int64)]).astype(np.float64) * self.lattice_unit

    def root_at(self, x: int, y: int, z: int) -> int:
        return x + self.roots[0] * (y + self.roots[1] * z)

    def is_leaf(self, c: int) -> bool:
        return self.first_child[c] == NONE

    def lookup(self, depth: int, x: int, y: int, z: int):
        return self.keys.get(_key(depth, x, y, z))

    def coarser_face_neighbour(self, c: int, axis: int, sign: int):
        """The leaf coarser than c that covers the cell-sized region across
        face (axis, sign) of c, or None (canvas boundary, or a cell of c's
        depth exists there)."""
        d = int(self.depth[c])
        size = 1 << (self.max_depth - d)
        o = [int(v) for v in self.origin[c]]
        o[axis] += sign * size
        if o[axis] < 0 or o[axis] >= self.roots[axis] << self.max_depth:
            return None
        if self.lookup(d, o[0], o[1], o[2]) is not None:
            return None
        for dd in range(d - 1, -1, -1):
            s = 1 << (self.max_depth - dd)
            n = self.lookup(dd, o[0] // s * s, o[1] // s * s, o[2] // s * s)
            if n is not None:
                return n
        raise AssertionError("no root covers an in-canvas point")

    # ------------------------------------------------------------- topology
    def refine(self, c: int, created: list[int]) -> None:
        """Refine leaf c (spec 4.2): first every coarser face-neighbour leaf,
        faces in the normative order, recursively; then c itself. New units
        are appended to `created`. Raises CapacityError if the budget is
        exhausted (units allocated before that stay valid: the tree is
        balanced after every single refinement)."""
        for axis, sign in FACES:
            n = self.coarser_face_neighbour(c, axis, sign)
            if n is not None:
                self.refine(n, created)
        if not self.is_leaf(c):  # refined as a side effect of a neighbour's balance
            return
        u = self.allocate_unit()
        self._make_children(c, u)
        created.append(u)

    def _make_children(self, c: int, u: int) -> None:
        d = int(self.depth[c]) + 1
        half = 1 << (self.max_depth - d)
        s = slice(u, u + UNIT)
        self.parent[s] = c
        self.first_child[s] = NONE
        self.depth[s] = d
        self.rgb[s] = self.rgb[c]
        self.sigma[s] = self.sigma[c]
        o = self.origin[c].astype(np.int64)
        k = np.arange(UNIT)
        self.origin[s, 0] = o[0] + (k & 1) * half
        self.origin[s, 1] = o[1] + ((k >> 1) & 1) * half
        self.origin[s, 2] = o[2] + ((k >> 2) & 1) * half
        self.first_child[c] = u
        for i in range(UNIT):
            ox, oy, oz = (int(v) for v in self.origin[u + i])
            self.keys[_key(d, ox, oy, oz)] = u + i
        self._mark_topology_change(c)

    def coarsen(self, c: int) -> None:
        """Collapse the 8 leaf children of c into c (the caller has checked
        that they are leaves and that balance allows it). c takes child
        octant 0's values."""
        u = int(self.first_child[c])
        self._mark_topology_change(c)
        self.rgb[c] = self.rgb[u]
        self.sigma[c] = self.sigma[u]
        d = int(self.depth[u])
        for i in range(UNIT):
            ox, oy, oz = (int(v) for v in self.origin[u + i])
            del self.keys[_key(d, ox, oy, oz)]
        self.first_child[c] = NONE
        self.free_unit(u)

    def can_coarsen(self, c: int) -> bool:
        """The children of c are all leaves and collapsing them keeps the tree
        2:1 balanced: no same-depth face neighbour of c has children that are
        not leaves on the shared face."""
        u = self.first_child[c]
        if u == NONE or np.any(self.first_child[u : u + UNIT] != NONE):
            return False
        for axis, sign in FACES:
            n = self._same_depth_neighbour(c, axis, sign)
            if n is None or self.first_child[n] == NONE:
                continue
            fc = int(self.first_child[n])
            side = 0 if sign > 0 else 1  # n's octants facing c
            for k in range(UNIT):
                if (k >> axis) & 1 == side and self.first_child[fc + k] != NONE:
                    return False
        return True

    def _same_depth_neighbour(self, c: int, axis: int, sign: int):
        d = int(self.depth[c])
        size = 1 << (self.max_depth - d)
        o = [int(v) for v in self.origin[c]]
        o[axis] += sign * size
        if o[axis] < 0 or o[axis] >= self.roots[axis] << self.max_depth:
            return None
        return self.lookup(d, o[0], o[1], o[2])

    def _mark_topology_change(self, c: int) -> None:
        """Cells whose g3 changes when c gains or loses its children (spec
        3.4): the 8 children, and the 4 children facing c of every internal
        same-depth face neighbour of c."""
        u = int(self.first_child[c])
        self.dirty.update(range(u, u + UNIT))
        for axis, sign in FACES:
            n = self._same_depth_neighbour(c, axis, sign)
            if n is None or self.first_child[n] == NONE:
                continue
            fc = int(self.first_child[n])
            side = 0 if sign > 0 else 1
            self.dirty.update(fc + k for k in range(UNIT) if (k >> axis) & 1 == side)

    def take_dirty(self) -> np.ndarray:
        """The cells whose g3 must be recomputed since the last call, sorted."""
        cells = np.array(sorted(self.dirty), dtype=np.int64)
        self.dirty = set()
        return cells

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
        """The leaf containing a canvas point, or None outside the canvas."""
        lat = []
        for a in range(3):
            x = float(p_canvas[a]) / self.lattice_unit
            if not 0.0 <= x < float(self.roots[a] << self.max_depth):
                return None
            lat.append(int(np.floor(x)))
        s = 1 << self.max_depth
        c = self.root_at(lat[0] // s, lat[1] // s, lat[2] // s)
        while self.first_child[c] != NONE:
            d = int(self.depth[c]) + 1
            half = 1 << (self.max_depth - d)
            o = self.origin[c]
            k = sum((1 << a) for a in range(3) if lat[a] - int(o[a]) >= half)
            c = int(self.first_child[c]) + k
        return c

    def leaves(self) -> np.ndarray:
        n = self.n_used
        return np.nonzero((self.depth[:n] != FREE) & (self.first_child[:n] == NONE))[0]

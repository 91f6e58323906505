"""G3: the one stored neighbour per axis of every non-root cell (spec 3.3).

Computed from parent/first_child alone, as the GPU pass (shaders/g3.wgsl) and
the painter's CPU port (painter/octree/src/g3.rs) do; plus a brute-force version
from lattice geometry that `check` and the tests compare against.
"""

from __future__ import annotations

import numpy as np

NONE = 0xFFFF_FFFF
FREE = 255
FACES = ((0, -1), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1))


def _root_neighbours(roots, n_roots: int) -> np.ndarray:
    rx, ry, rz = roots
    r = np.arange(n_roots, dtype=np.int64)
    xyz = np.stack([r % rx, (r // rx) % ry, r // (rx * ry)], axis=1)
    nb = np.full((n_roots, 6), NONE, np.int64)
    for f, (a, s) in enumerate(FACES):
        q = xyz.copy()
        q[:, a] += s
        ok = (q[:, a] >= 0) & (q[:, a] < roots[a])
        nb[ok, f] = q[ok, 0] + rx * (q[ok, 1] + ry * q[ok, 2])
    return nb


def neighbours(parent, first_child, depth, roots) -> np.ndarray:
    """Same-depth-or-coarser face neighbour of every cell, int64 [N, 6] in
    FACES order, NONE at the canvas boundary and for free cells."""
    n = len(parent)
    parent = parent.astype(np.int64)
    first_child = first_child.astype(np.int64)
    depth = depth.astype(np.int64)
    n_roots = roots[0] * roots[1] * roots[2]
    nb = np.full((n, 6), NONE, np.int64)
    nb[:n_roots] = _root_neighbours(roots, n_roots)
    live = depth != FREE
    max_d = int(depth[live].max()) if live.any() else 0
    for d in range(1, max_d + 1):
        cells = np.nonzero(live & (depth == d))[0]
        if len(cells) == 0:
            continue
        p = parent[cells]
        k = cells & 7
        for f, (a, s) in enumerate(FACES):
            bit = (k >> a) & 1
            inward = (bit == 0) if s > 0 else (bit == 1)
            out = np.full(len(cells), NONE, np.int64)
            out[inward] = cells[inward] ^ (1 << a)
            q = nb[p, f]
            cross = ~inward & (q != NONE)
            qc = q[cross]
            qc_fc = first_child[qc]
            descend = (qc_fc != NONE) & (depth[qc] == depth[p[cross]])
            res = qc.copy()
            res[descend] = qc_fc[descend] + (k[cross][descend] ^ (1 << a))
            out[cross] = res
            nb[cells, f] = out
    return nb


def g3_from_links(parent, first_child, depth, roots) -> np.ndarray:
    """g3 u32 [N, 3]: the outward-face neighbour per axis; NONE for roots,
    free cells and the canvas boundary."""
    nb = neighbours(parent, first_child, depth, roots)
    n = len(parent)
    n_roots = roots[0] * roots[1] * roots[2]
    g3 = np.full((n, 3), NONE, np.int64)
    cells = np.arange(n, dtype=np.int64)
    live = (depth != FREE) & (cells >= n_roots)
    for a in range(3):
        bit = (cells >> a) & 1
        f = 2 * a + bit  # bit 1: the +a face (FACES index 2a+1); bit 0: -a
        g3[live, a] = nb[cells[live], f[live]]
    return g3.astype(np.uint32)


def g3_brute_force(parent, first_child, depth, origin, roots, max_depth) -> np.ndarray:
    """g3 from lattice geometry: for each outward face, descend from the root
    that contains a point just across the face, down to the cell's depth."""
    n = len(parent)
    n_roots = roots[0] * roots[1] * roots[2]
    first_child = first_child.astype(np.int64)
    depth_i = depth.astype(np.int64)
    g3 = np.full((n, 3), NONE, np.int64)
    cells = np.nonzero((depth != FREE) & (np.arange(n) >= n_roots))[0]
    if len(cells) == 0:
        return g3.astype(np.uint32)
    o = origin[cells].astype(np.int64)
    d = depth_i[cells]
    size = np.left_shift(np.int64(1), max_depth - d)
    extent = np.array(roots, np.int64) << max_depth
    for a in range(3):
        bit = (cells >> a) & 1
        q = o.copy()
        q[:, a] += np.where(bit == 1, size, -size)
        inside = (q[:, a] >= 0) & (q[:, a] < extent[a])
        qi = q[inside]
        root_size = np.int64(1) << max_depth
        r = qi // root_size
        c = r[:, 0] + roots[0] * (r[:, 1] + roots[1] * r[:, 2])
        target = d[inside]
        while True:
            go = (first_child[c] != NONE) & (depth_i[c] < target)
            if not go.any():
                break
            cg = c[go]
            half = np.left_shift(np.int64(1), max_depth - depth_i[cg] - 1)
            rel = qi[go] - origin[cg].astype(np.int64)
            k = (rel[:, 0] >= half).astype(np.int64) | ((rel[:, 1] >= half) << 1) | ((rel[:, 2] >= half) << 2)
            c[go] = first_child[cg] + k
        out = np.full(len(cells), NONE, np.int64)
        out[inside] = c
        g3[cells, a] = out
    return g3.astype(np.uint32)

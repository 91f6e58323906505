"""Validation of a tree dump: structure, 2:1 balance, g3 (spec 11.2).

`check_arrays` returns a list of problems, each naming the first offending
cells; an empty list means the dump is valid. Used by `octopaint-ref check`,
by the tests after every segment, and by the conformance driver.
"""

from __future__ import annotations

import numpy as np

from .g3 import FREE, NONE, g3_brute_force, g3_from_links, neighbours
from .prefilter import stale_cells

MAX_LISTED = 5


def _cells(mask) -> str:
    idx = np.nonzero(mask)[0]
    more = f" and {len(idx) - MAX_LISTED} more" if len(idx) > MAX_LISTED else ""
    return ", ".join(str(int(i)) for i in idx[:MAX_LISTED]) + more


def check_arrays(a: dict) -> list[str]:
    problems: list[str] = []
    roots = tuple(int(r) for r in np.asarray(a["roots"]).reshape(-1))
    max_depth = int(a["max_depth"])
    root_size = float(a["root_size"])
    if len(roots) != 3 or min(roots) < 1:
        return [f"roots {roots} is not three positive counts"]
    if not 0 <= max_depth <= 28:
        return [f"max_depth {max_depth} is outside [0, 28]"]
    if not np.isfinite(root_size) or root_size <= 0:
        problems.append(f"root_size {root_size} is not a positive finite number")
    parent = a["parent"].astype(np.int64)
    first_child = a["first_child"].astype(np.int64)
    depth = a["depth"].astype(np.int64)
    n = len(parent)
    n_roots = roots[0] * roots[1] * roots[2]
    n_padded = (n_roots + 7) // 8 * 8
    shapes = {"first_child": (n,), "depth": (n,), "rgb": (n, 3), "sigma": (n,), "g3": (n, 3), "origin": (n, 3)}
    for k, shp in shapes.items():
        if a[k].shape != shp:
            problems.append(f"{k} has shape {a[k].shape}, expected {shp}")
    if problems:
        return problems
    if n % 8 or n < n_padded:
        return [f"used length {n} is not a multiple of 8 at least {n_padded} (the roots)"]
    idx = np.arange(n, dtype=np.int64)
    origin = a["origin"].astype(np.int64)
    free = depth == FREE
    live = ~free
    # Roots and padding.
    r = idx[:n_roots]
    size0 = 1 << max_depth
    root_origin = np.stack([(r % roots[0]), (r // roots[0]) % roots[1], r // (roots[0] * roots[1])], 1) * size0
    bad = (depth[:n_roots] != 0) | (parent[:n_roots] != NONE) | np.any(origin[:n_roots] != root_origin, axis=1)
    if bad.any():
        problems.append(f"roots with wrong depth, parent or origin: cells {_cells(bad)}")
    if np.any(live[n_roots:n_padded]):
        problems.append(f"padding cells after the roots are not free: {_cells(np.r_[np.zeros(n_roots, bool), live[n_roots:n_padded]])}")
    # Free cells.
    g3 = a["g3"].astype(np.int64)
    bad = free & ((parent != NONE) | (first_child != NONE) | np.any(origin != NONE, axis=1) | np.any(g3 != NONE, axis=1))
    if bad.any():
        problems.append(f"free cells whose parent, first_child, origin or g3 is not NONE: {_cells(bad)}")
    bad = free & (np.any(a["rgb"] != 0, axis=1) | (a["sigma"] != 0))
    if bad.any():
        problems.append(f"free cells whose rgb or sigma is not 0: {_cells(bad)}")
    units = free[n_padded:].reshape(-1, 8) if n > n_padded else np.zeros((0, 8), bool)
    mixed = units.any(axis=1) & ~units.all(axis=1)
    if mixed.any():
        problems.append(f"units partly free: first cells {_cells(np.repeat(mixed, 8) & (idx[n_padded:] % 8 == 0))}")
    if n > n_padded and units[-1].all():
        problems.append(f"the last unit ({n - 8}) is free: the used length is not trimmed")
    # Parent / child links.
    nonroot = live & (idx >= n_roots)
    p = parent[nonroot]
    okp = (p >= 0) & (p < n)
    if not okp.all():
        mask = np.zeros(n, bool)
        mask[idx[nonroot][~okp]] = True
        problems.append(f"parent out of range: cells {_cells(mask)}")
        return problems
    c_idx = idx[nonroot]
    bad = (first_child[p] != (c_idx & ~7)) | (depth[p] != depth[c_idx] - 1) | (depth[p] == FREE)
    if bad.any():
        mask = np.zeros(n, bool)
        mask[c_idx[bad]] = True
        problems.append(f"children whose parent does not point back, or with a wrong depth: cells {_cells(mask)}")
    if np.any(depth[live] > max_depth):
        problems.append(f"cells deeper than max_depth: {_cells(live & (depth > max_depth))}")
    inner = live & (first_child != NONE)
    fc = first_child[inner]
    okc = (fc % 8 == 0) & (fc >= n_padded) & (fc + 8 <= n)
    if not okc.all():
        mask = np.zeros(n, bool)
        mask[idx[inner][~okc]] = True
        problems.append(f"first_child not the start of a unit in range: cells {_cells(mask)}")
        return problems
    kids = fc[:, None] + np.arange(8)[None, :]
    bad = np.any(parent[kids] != idx[inner][:, None], axis=1)
    if bad.any():
        mask = np.zeros(n, bool)
        mask[idx[inner][bad]] = True
        problems.append(f"cells whose children do not point back: {_cells(mask)}")
    # Origins from the parent.
    k = c_idx & 7
    half = np.left_shift(np.int64(1), max_depth - depth[c_idx]) if len(c_idx) else np.zeros(0, np.int64)
    expect = origin[p] + np.stack([(k & 1), (k >> 1) & 1, (k >> 2) & 1], 1) * half[:, None]
    bad = np.any(origin[c_idx] != expect, axis=1)
    if bad.any():
        mask = np.zeros(n, bool)
        mask[c_idx[bad]] = True
        problems.append(f"origins that do not follow from the parent: cells {_cells(mask)}")
    # Values.
    sigma = a["sigma"]
    bad = ~np.isfinite(sigma) | (sigma < 0)
    if bad.any():
        problems.append(f"sigma not finite and >= 0: cells {_cells(bad)}")
    if problems:
        return problems
    # Balance: every leaf's same-depth-or-coarser neighbours are at most one level coarser.
    nb = neighbours(a["parent"], a["first_child"], a["depth"], roots)
    leaf = live & (first_child == NONE)
    lc = idx[leaf]
    nbl = nb[lc]
    has = nbl != NONE
    nd = np.where(has, depth[np.where(has, nbl, 0)], 0)
    bad_rows = np.any(has & (nd < depth[lc][:, None] - 1), axis=1)
    if bad_rows.any():
        mask = np.zeros(n, bool)
        mask[lc[bad_rows]] = True
        problems.append(f"2:1 face balance violated next to leaves {_cells(mask)}")
    # g3.
    from_links = g3_from_links(a["parent"], a["first_child"], a["depth"], roots).astype(np.int64)
    bad = np.any(g3 != from_links, axis=1)
    if bad.any():
        problems.append(f"g3 differs from the one computed from parent/first_child: cells {_cells(bad)}")
    brute = g3_brute_force(a["parent"], a["first_child"], a["depth"], a["origin"], roots, max_depth).astype(np.int64)
    bad = np.any(from_links != brute, axis=1)
    if bad.any():
        problems.append(f"g3 from links differs from brute force over the lattice: cells {_cells(bad)}")
    # Interior values: the prefilter of the children (spec 4.4).
    bad = stale_cells(a["first_child"], a["depth"], a["rgb"], sigma)
    if bad.any():
        problems.append(f"cells with children whose value is not their children's prefilter (spec 4.4): {_cells(bad)}")
    return problems

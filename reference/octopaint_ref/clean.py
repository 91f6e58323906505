"""Topology cleaning at stroke end (spec 9).

Collapse every 8 leaf siblings that are all empty (sigma == 0) or all
identical (equal rgb bytes and equal f32 sigma), when 2:1 balance allows,
until nothing more collapses. The result is the unique fixpoint over the whole
tree; because the tree is at that fixpoint before every stroke, only the
parents of cells the stroke touched can start a collapse, and a collapse of P
can only unblock the parent of P and that parent's same-depth face
neighbours, so a work list finds the same fixpoint. Painter twin:
painter/tree/src/clean.rs.
"""

from __future__ import annotations

import numpy as np

from .tree import FACES, NONE, UNIT


def children_mergeable(tree, c: int) -> bool:
    u = int(tree.first_child[c])
    if u == NONE_INT:
        return False
    s = slice(u, u + UNIT)
    if np.any(tree.first_child[s] != NONE):
        return False
    sigma = tree.sigma[s]
    if np.all(sigma == 0):
        return True
    rgb = tree.rgb[s]
    return bool(np.all(sigma == sigma[0]) and np.all(rgb == rgb[0]))


NONE_INT = 0xFFFF_FFFF


def clean(tree, touched: np.ndarray) -> int:
    """Collapse to the fixpoint, starting from the parents of `touched`.
    Returns the number of collapses."""
    work = set()
    for c in np.unique(tree.parent[touched]) if len(touched) else ():
        if c != NONE:
            work.add(int(c))
    collapses = 0
    while work:
        nxt = set()
        for c in sorted(work, key=lambda c: (-int(tree.depth[c]), c)):
            if tree.depth[c] == 255 or tree.first_child[c] == NONE:
                continue
            if not children_mergeable(tree, c) or not tree.can_coarsen(c):
                continue
            tree.coarsen(c)
            collapses += 1
            p = int(tree.parent[c])
            if p != NONE_INT:
                nxt.add(p)
                for axis, sign in FACES:
                    n = tree._same_depth_neighbour(p, axis, sign)
                    if n is not None and tree.first_child[n] != NONE:
                        nxt.add(n)
        work = nxt
    return collapses


def collapsible_anywhere(tree) -> list[int]:
    """Every cell that could still collapse (for tests: empty at a fixpoint)."""
    n = tree.n_used
    out = []
    for c in np.nonzero((tree.depth[:n] != 255) & (tree.first_child[:n] != NONE))[0]:
        c = int(c)
        if children_mergeable(tree, c) and tree.can_coarsen(c):
            out.append(c)
    return out

"""Topology cleaning at stroke end (spec 9).

Collapse every 8 leaf siblings that are all empty (sigma == 0) or all
identical (equal rgb bytes and equal f32 sigma), when 2:1 balance allows,
until nothing more collapses. Collapsing only ever relaxes the balance
constraints of other cells, so the result is the unique fixpoint over the
whole tree. Because the tree is at that fixpoint before every stroke, only
the parents of cells the stroke touched can start a collapse, and a collapse
of P can only unblock the parent of P and that parent's same-depth face
neighbours: a work list finds the same fixpoint. Each pass collapses a
batch; collapses in one batch never invalidate each other. Painter twin:
painter/octree/src/clean.rs.
"""

from __future__ import annotations

import numpy as np

from .tree import FREE, NONE, Tree


def clean(tree: Tree, touched: np.ndarray) -> int:
    """Collapse to the fixpoint, starting from the parents of `touched`.
    Returns the number of collapses."""
    touched = np.asarray(touched, np.int64)
    touched = touched[tree.depth[touched] != FREE]
    work = tree.parent[touched]
    work = np.unique(work[work != NONE]).astype(np.int64)
    collapses = 0
    while len(work):
        work = work[(tree.depth[work] != FREE) & (tree.first_child[work] != NONE)]
        done = work[tree.collapsible(work)]
        if not len(done):
            break
        tree.coarsen(done)
        collapses += len(done)
        parents = tree.parent[done]
        parents = np.unique(parents[parents != NONE]).astype(np.int64)
        nb = tree.same_depth_neighbours(parents)
        nb = nb[nb >= 0]
        nb = nb[tree.first_child[nb] != NONE]
        work = np.unique(np.concatenate([parents, nb]))
    return collapses


def collapsible_anywhere(tree: Tree) -> np.ndarray:
    """Every cell that could still collapse (tests: empty at a fixpoint)."""
    n = tree.n_used
    inner = np.nonzero((tree.depth[:n] != FREE) & (tree.first_child[:n] != NONE))[0]
    return inner[tree.collapsible(inner)]

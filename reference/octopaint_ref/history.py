"""Undo and redo of whole strokes (spec 10).

At stroke begin the used part of every pool is copied; at commit (after
topology cleaning) the cells that differ are kept as an undo record with
their old and new values. Undo writes the old values back, so the tree is
byte-identical to the one before the stroke, indices included; redo writes
the new ones. Painter twin: painter/octree/src/history/.
"""

from __future__ import annotations

import numpy as np

from .g3 import g3_from_links
from .tree import FREE, NONE

POOLS = ("parent", "first_child", "depth", "rgb", "sigma", "origin")
FREE_VALUE = {"parent": NONE, "first_child": NONE, "depth": FREE, "rgb": 0, "sigma": 0, "origin": NONE}


class History:
    def __init__(self, tree):
        self.tree = tree
        self.done: list[tuple] = []
        self.undone: list[tuple] = []
        self._before = None

    def _snapshot(self, n: int) -> dict:
        t = self.tree
        return {k: getattr(t, k)[:n].copy() for k in POOLS}

    def begin(self) -> None:
        self._before = (self.tree.n_used, self._snapshot(self.tree.n_used))

    def commit(self) -> None:
        t = self.tree
        old_n, old = self._before
        self._before = None
        new_n = t.n_used
        n = max(old_n, new_n)
        t._grow_to(n)
        changed = np.zeros(n, bool)
        new = {}
        for k in POOLS:
            a = old[k]
            if len(a) < n:
                pad = np.empty((n,) + a.shape[1:], a.dtype)
                pad[: len(a)] = a
                pad[len(a) :] = FREE_VALUE[k]
                old[k] = a = pad
            b = getattr(t, k)[:n]
            diff = a != b
            changed |= diff.reshape(n, -1).any(axis=1)
            new[k] = b
        idx = np.nonzero(changed)[0]
        record = (old_n, new_n, idx, {k: old[k][idx] for k in POOLS}, {k: new[k][idx].copy() for k in POOLS})
        self.done.append(record)
        self.undone.clear()

    def undo(self) -> None:
        rec = self.done.pop()
        self._write(rec[0], rec[2], rec[3])
        self.undone.append(rec)

    def redo(self) -> None:
        rec = self.undone.pop()
        self._write(rec[1], rec[2], rec[4])
        self.done.append(rec)

    def _write(self, n_used: int, idx: np.ndarray, vals: dict) -> None:
        t = self.tree
        g3_before = g3_from_links(t.parent[: t.n_used], t.first_child[: t.n_used], t.depth[: t.n_used], t.roots)
        t._grow_to(int(idx.max()) + 1 if len(idx) else 0)
        for k in POOLS:
            getattr(t, k)[idx] = vals[k]
        t.n_used = n_used
        t.rebuild_free_units()
        # The cells whose g3 changed (exact, by comparison) plus the rewritten ones.
        g3_after = g3_from_links(t.parent[:n_used], t.first_child[:n_used], t.depth[:n_used], t.roots)
        m = min(len(g3_before), len(g3_after))
        diff = np.nonzero((g3_before[:m] != g3_after[:m]).any(axis=1))[0]
        t.dirty.update(diff.tolist())
        t.dirty.update(idx.tolist())

"""Layers (spec 14): a document of up to 16 trees under one cell budget, one
history for strokes and layer operations, merge down, and the dump of a
document. The trace reader follows the same operations through a model of
the names, locks and selection (`check_op`, `model_apply`), so both use the
rules written once. Painter twin: painter/tree/src/layers/ (the rules:
painter/model/src/layer_rules.rs).
"""

from __future__ import annotations

import copy

import numpy as np

from .clean import clean
from .dump import LAYER_ARRAYS, tree_arrays
from .layer_rules import FIRST_NAME, NAME_BYTES, LayerOp, _placed, check_op
from .paint import Painting
from .tree import FREE, NONE

F32_MAX = 3.4028234663852886e38

class Layer:
    def __init__(self, name: str, painting: Painting):
        self.name = name
        self.visible = True
        self.opacity = 1.0
        self.locked = False
        self.painting = painting

    @property
    def tree(self):
        return self.painting.tree


class Document:
    """The layers of a version 2 trace and their one history (spec 14)."""

    def __init__(self, canvas, warn=None):
        self.canvas = canvas
        self.warn = warn or (lambda msg: None)
        self.layers = [self._new_layer(FIRST_NAME)]
        self.selected = 0
        self.done: list = []  # ("stroke", layer) or ("layers", before, after)
        self.undone: list = []
        self._painting_on = None  # the layer of the open stroke

    def _new_layer(self, name: str) -> Layer:
        return Layer(name, Painting(self.canvas, warn=self.warn))

    # ---------------------------------------------------------- budget
    def used(self, but=None) -> int:
        return sum(int(la.tree.n_used) for la in self.layers if la is not but)

    def share(self, layer: Layer) -> int:
        """What `layer` may grow to (spec 14.1)."""
        return self.canvas.capacity - self.used(but=layer)

    # ---------------------------------------------------------- strokes
    @property
    def current(self) -> Layer:
        return self.layers[self.selected]

    def begin_stroke(self, brush, line: int) -> bool:
        la = self._ready_to_paint(line, "stroke")
        if la is None:
            return False
        la.painting.begin_stroke(brush, line)
        self._painting_on = la
        return True

    def _ready_to_paint(self, line: int, what: str):
        """The selected layer made ready for a stroke or an import: None,
        with a warning, when it is locked (spec 14.2); else its redo history
        dropped and its budget set to its share (14.1)."""
        la = self.current
        if la.locked:
            self.warn(f'line {line}: layer "{la.name}" is locked; this {what} is skipped')
            return None
        self._drop_redo()
        la.tree.capacity = self.share(la)
        return la

    def add_sample(self, sample, line: int) -> None:
        if self._painting_on is not None:
            self._painting_on.painting.add_sample(sample, line)

    def end_stroke(self) -> None:
        la = self._painting_on
        if la is None:
            return
        self._painting_on = None
        la.painting.end_stroke()
        self.done.append(("stroke", la))

    def import_voxels(self, imp, line: int) -> bool:
        """An `import` event (spec 15.3) on the selected layer, one step of
        the history; skipped with a warning when the layer is locked (the
        reader's model was put out of step by a skipped layer operation)."""
        la = self._ready_to_paint(line, "import")
        if la is None:
            return False
        la.painting.import_voxels(imp.voxels, line)
        self.done.append(("stroke", la))
        return True

    def _drop_redo(self) -> None:
        self.undone.clear()
        for la in self.layers:
            la.painting.history.undone.clear()

    # ------------------------------------------------------------ undo
    def _settings(self) -> tuple:
        return ([(la, la.name, la.visible, la.opacity, la.locked) for la in self.layers], self.selected)

    def _restore(self, saved: tuple) -> None:
        rows, sel = saved
        self.layers = []
        for la, name, visible, opacity, locked in rows:
            la.name, la.visible, la.opacity, la.locked = name, visible, opacity, locked
            self.layers.append(la)
        self.selected = sel

    def undo(self) -> None:
        if not self.done:
            return
        step = self.done.pop()
        if step[0] == "stroke":
            step[1].painting.undo()
        else:
            self._restore(step[1])
        self.undone.append(step)

    def redo(self) -> None:
        if not self.undone:
            return
        step = self.undone.pop()
        if step[0] == "stroke":
            step[1].painting.redo()
        else:
            self._restore(step[2])
        self.done.append(step)

    # ------------------------------------------------------ operations
    def apply(self, op: LayerOp, line: int) -> bool:
        """Run one `layer` event; False (with a warning) when the document
        cannot take it now (spec 14.2: refused by the budget, or out of step
        with the reader's model after such a refusal)."""
        names = [la.name for la in self.layers]
        why = check_op(names, [la.locked for la in self.layers], op)
        if why is not None:
            self.warn(f"line {line}: {why}; it is skipped")
            return False
        i = names.index(op.layer) if op.layer is not None else None
        if op.op == "select":
            self.selected = i
            return True
        made = None
        if op.op == "add":
            made = self._new_layer(op.name)
            need = made.tree.n_used
        elif op.op == "duplicate":
            src = self.layers[i]
            made = Layer(op.name, Painting(self.canvas, warn=self.warn))
            made.painting.tree = copy.deepcopy(src.tree)
            made.painting.history.tree = made.painting.tree
            made.visible, made.opacity = src.visible, src.opacity
            need = made.tree.n_used
        elif op.op == "merge_down":
            lower, upper = self.layers[i - 1], self.layers[i]
            limit = self.canvas.capacity - sum(int(la.tree.n_used) for la in self.layers if la is not lower and la is not upper)
            tree = merge_trees(lower, upper, limit)
            if tree is None:
                need = None
            else:
                made = Layer(lower.name, Painting(self.canvas, warn=self.warn))
                made.painting.tree = tree
                made.painting.history.tree = tree
                tree.capacity = self.canvas.capacity
                need = 0  # counted in `limit` already
        else:
            need = 0
        if op.op in ("add", "duplicate") and need > self.canvas.capacity - self.used():
            need = None
        if need is None:
            self.warn(f"line {line}: the cell budget cannot hold this layer operation; it is skipped")
            return False
        self._drop_redo()
        before = self._settings()
        order, sel = _placed(len(self.layers), self.selected, op, i)
        old = self.layers
        self.layers = [made if j is None else old[j] for j in order]
        if op.op == "merge_down":
            self.layers[i - 1] = made
        elif op.op == "rename":
            old[i].name = op.name
        elif op.op == "set":
            la = old[i]
            if op.visible is not None:
                la.visible = op.visible
            if op.opacity is not None:
                la.opacity = op.opacity
            if op.locked is not None:
                la.locked = op.locked
        self.selected = sel
        self.done.append(("layers", before, self._settings()))
        return True


def merge_trees(lower: Layer, upper: Layer, limit: int):
    """The tree of `upper` merged down into `lower` (spec 14.4), or None when
    it would need more than `limit` cells."""
    A, B = lower.tree, upper.tree
    M = copy.deepcopy(A)
    M.capacity = limit
    if M.n_used > limit:
        return None
    for d in range(M.max_depth):
        n = M.n_used
        leaves = np.nonzero((M.depth[:n] == d) & (M.first_child[:n] == NONE))[0]
        if not len(leaves):
            continue
        b = B.cell_at(M.origin[leaves].astype(np.int64), np.full(len(leaves), d, np.int64))
        cand = leaves[(B.depth[b] == d) & (B.first_child[b] != NONE)]
        if not len(cand):
            continue
        if len(cand) > M.available_units():
            return None
        _, refused = M.refine_round(cand)
        assert not refused
    n = M.n_used
    leaves = np.nonzero((M.depth[:n] != FREE) & (M.first_child[:n] == NONE))[0]
    b = B.cell_at(M.origin[leaves].astype(np.int64), M.depth[leaves].astype(np.int64))
    oA = float(lower.opacity) if lower.visible else 0.0
    oB = float(upper.opacity) if upper.visible else 0.0
    wA = oA * M.sigma[leaves].astype(np.float64)
    wB = oB * B.sigma[b].astype(np.float64)
    w = wA + wB
    M.sigma[leaves] = np.minimum(w, F32_MAX).astype(np.float32)
    lit = w > 0
    mixed = np.floor((wA[lit, None] * M.rgb[leaves[lit]].astype(np.float64) + wB[lit, None] * B.rgb[b[lit]].astype(np.float64)) / w[lit, None] + 0.5)
    M.rgb[leaves[lit]] = np.clip(mixed, 0, 255).astype(np.uint8)
    clean(M, leaves[M.depth[leaves] > 0])
    return M


def document_arrays(doc: Document) -> dict:
    """The arrays of a document's dump (spec 14.5), in the order written."""
    t0 = doc.layers[0].tree
    out = {
        "roots": np.array(t0.roots, np.uint32),
        "max_depth": np.array(t0.max_depth, np.uint32),
        "root_size": np.array(t0.root_size, np.float64),
        "layer_count": np.array(len(doc.layers), np.uint32),
        "selected": np.array(doc.selected, np.uint32),
    }
    names = np.zeros((len(doc.layers), NAME_BYTES), np.uint8)
    for k, la in enumerate(doc.layers):
        b = la.name.encode("utf-8")
        names[k, : len(b)] = np.frombuffer(b, np.uint8)
    out["layer_names"] = names
    out["layer_visible"] = np.array([la.visible for la in doc.layers], np.uint8)
    out["layer_locked"] = np.array([la.locked for la in doc.layers], np.uint8)
    out["layer_opacity"] = np.array([la.opacity for la in doc.layers], np.float32)
    for k, la in enumerate(doc.layers):
        arrays = tree_arrays(la.tree)
        for name, _ in LAYER_ARRAYS:
            out[f"{k}/{name}"] = arrays[name]
    return out

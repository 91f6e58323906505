"""The rules of layer events (spec 14.2), shared by the trace reader's model
and the replay's document (layers.py): what an operation needs, where the
layers go, and what the reader's model of names, locks and selection becomes.
Painter twin: painter/model/src/layer_rules.rs.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

MAX_LAYERS = 16
MAX_NAME_CHARS = 64
NAME_BYTES = 256  # a name's UTF-8 bytes in a dump (64 code points need at most 256)
FIRST_NAME = "Layer 1"
OPS = ("add", "delete", "select", "rename", "move", "set", "duplicate", "merge_down")


@dataclass(frozen=True)
class LayerOp:
    """One `layer` event (spec 14.2), as read: the fields its `op` uses."""

    op: str
    layer: str | None = None
    name: str | None = None
    to: int | None = None
    visible: bool | None = None
    opacity: float | None = None  # rounded to f32 when read
    locked: bool | None = None


def to_f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def name_problem(name: str) -> str | None:
    """Why `name` is not a layer name (spec 14.1), or None."""
    if not 1 <= len(name) <= MAX_NAME_CHARS:
        return f"a layer name has 1 to {MAX_NAME_CHARS} characters, this one {len(name)}"
    for ch in name:
        o = ord(ch)
        if o <= 0x1F or 0x7F <= o <= 0x9F:
            return f"a layer name has no control characters (U+{o:04X})"
    return None


def check_op(names: list, locked: list, op: LayerOp) -> str | None:
    """Why the document with these layer `names` and `locked` flags (bottom
    first) cannot take `op`, or None: the rules of spec 14.2 after the
    fields were read, in the order written there."""
    if op.layer is not None and op.layer not in names:
        return f'layer: there is no layer named "{op.layer}"'
    i = names.index(op.layer) if op.layer is not None else None
    if op.name is not None and op.name in names and not (op.op == "rename" and names[i] == op.name):
        return f'name: a layer named "{op.name}" exists already'
    if op.op in ("add", "duplicate") and len(names) >= MAX_LAYERS:
        return f"op: a document holds at most {MAX_LAYERS} layers"
    if op.op == "delete" and len(names) == 1:
        return "op: the only layer cannot be deleted"
    if op.op == "move" and op.to >= len(names):
        return f"to: {op.to} is not a layer position (0 to {len(names) - 1})"
    if op.op == "merge_down":
        if i == 0:
            return f'op: "{op.layer}" is the bottom layer: there is nothing below it to merge into'
        if locked[i] or locked[i - 1]:
            return f'op: "{op.layer}" or the layer below it is locked'
    return None


def _placed(n: int, sel: int, op: LayerOp, i: int | None) -> tuple[list, int]:
    """Where the layers go for `op` on a document of `n` layers: the new order
    as a list of old indices (None for a new layer) and the new selection."""
    order = list(range(n))
    if op.op == "add":
        order.insert(sel + 1, None)
        return order, sel + 1
    if op.op == "delete":
        order.pop(i)
        if sel == i:
            sel = max(i - 1, 0)
        elif sel > i:
            sel -= 1
        return order, sel
    if op.op == "select":
        return order, i
    if op.op == "move":
        order.insert(op.to, order.pop(i))
        return order, order.index(sel)
    if op.op == "duplicate":
        order.insert(i + 1, None)
        return order, i + 1
    if op.op == "merge_down":
        order.pop(i)  # the merged layer takes the place of i - 1
        return order, i - 1
    return order, sel  # rename, set


def model_apply(state: tuple, op: LayerOp) -> tuple:
    """The reader's model (names, locks, selection) after `op`, which
    check_op accepted."""
    names, locked, sel = list(state[0]), list(state[1]), state[2]
    i = names.index(op.layer) if op.layer is not None else None
    order, new_sel = _placed(len(names), sel, op, i)
    out_n, out_l = [], []
    for j in order:
        if j is None:
            out_n.append(op.name)
            out_l.append(False)
        else:
            out_n.append(names[j])
            out_l.append(locked[j])
    if op.op == "rename":
        out_n[i] = op.name
    elif op.op == "set" and op.locked is not None:
        out_l[i] = op.locked
    elif op.op == "merge_down":
        out_l[i - 1] = False
    return tuple(out_n), tuple(out_l), new_sel


MODEL_START = ((FIRST_NAME,), (False,), 0)

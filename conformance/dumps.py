"""Comparing two tree dumps (docs/spec.md sections 11 and 13).

Tolerances are data: TOLERANCES says, per array, how close the painter's
values must be to the reference's. Every entry is exact today: both sides
compute the stored values with IEEE f64 arithmetic in the spec's order
(spec 13 says why), so any difference is a bug to find, not noise to allow.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# array -> how it is compared
TOLERANCES = {
    "roots": "equal",
    "max_depth": "equal",
    "root_size": "equal",
    "parent": "equal",
    "first_child": "equal",
    "depth": "equal",
    "origin": "equal",
    "g3": "equal",
    "rgb": "equal",  # steps per channel: 0
    "sigma": "bits",  # f32 bit patterns
}
ARRAY_ORDER = ("roots", "max_depth", "root_size", "parent", "first_child", "depth", "origin", "g3", "rgb", "sigma")


@dataclass
class Difference:
    array: str
    count: int  # cells that differ (1 for scalars and shapes)
    first_cell: int | None  # None for scalars and shape mismatches
    detail: str


def load(path: str) -> dict:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _rows_differ(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """bool [N]: cell i differs (any component)."""
    d = a != b
    return d.reshape(len(d), -1).any(axis=1) if d.ndim > 1 else d


def compare(ref: dict, painter: dict) -> list[Difference]:
    """Every array that differs beyond its tolerance, in ARRAY_ORDER, then
    any array only one side holds. Equal dumps hold the same arrays, each
    with the same dtype, shape and values (spec 11.1); their files' bytes
    are not compared."""
    out = []
    for name in ARRAY_ORDER:
        if name not in ref or name not in painter:
            side = "reference" if name not in ref else "painter"
            out.append(Difference(name, 1, None, f"missing from the {side}'s dump"))
            continue
        a, b = ref[name], painter[name]
        if a.dtype != b.dtype or a.shape != b.shape:
            out.append(Difference(name, 1, None, f"reference {a.dtype}{list(a.shape)}, painter {b.dtype}{list(b.shape)}"))
            continue
        if a.ndim == 0 or name == "roots":
            if not np.array_equal(a, b):
                out.append(Difference(name, 1, None, f"reference {a.tolist()}, painter {b.tolist()}"))
            continue
        if TOLERANCES[name] == "bits":
            bad = a.view(np.uint32) != b.view(np.uint32)
        else:
            bad = _rows_differ(a, b)
        if bad.any():
            cells = np.nonzero(bad)[0]
            i = int(cells[0])
            out.append(
                Difference(
                    name,
                    len(cells),
                    i,
                    f"{len(cells)} cells differ; first cell {i}: reference {a[i].tolist()}, painter {b[i].tolist()}",
                )
            )
    for name in sorted((set(ref) ^ set(painter)) - set(ARRAY_ORDER)):
        side = "reference" if name in ref else "painter"
        out.append(Difference(name, 1, None, f"an array only the {side}'s dump holds"))
    return out


DOCUMENT_ARRAYS = ("layer_count", "selected", "layer_names", "layer_visible", "layer_locked", "layer_opacity")
LAYER_ARRAYS = ("parent", "first_child", "depth", "rgb", "sigma", "g3", "origin")


def layers_of(d: dict) -> list:
    """A document's dump (spec 14.5) as one tree dump per layer, bottom
    first; a tree's dump as itself."""
    if "layer_count" not in d:
        return [d]
    shared = {k: d[k] for k in ("roots", "max_depth", "root_size") if k in d}
    n = int(d["layer_count"])
    return [{**shared, **{a: d[f"{k}/{a}"] for a in LAYER_ARRAYS if f"{k}/{a}" in d}} for k in range(n)]


def compare_document(ref: dict, painter: dict) -> list[Difference]:
    """compare() for dumps of documents too: the layer settings exactly
    (opacity bit for bit), then every layer's tree as compare() does, its
    arrays named `k/...`."""
    if "layer_count" not in ref and "layer_count" not in painter:
        return compare(ref, painter)
    out = []
    for name in DOCUMENT_ARRAYS:
        if name not in ref or name not in painter:
            side = "reference" if name not in ref else "painter"
            out.append(Difference(name, 1, None, f"missing from the {side}'s dump"))
            continue
        a, b = ref[name], painter[name]
        same = a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
        if not same:
            out.append(Difference(name, 1, None, f"reference {a.dtype}{list(a.shape)} {a.tolist()!r:.200}, painter {b.dtype}{list(b.shape)} {b.tolist()!r:.200}"))
    if out:
        return out
    for k, (la, lb) in enumerate(zip(layers_of(ref), layers_of(painter))):
        for d in compare(la, lb):
            out.append(Difference(f"{k}/{d.array}", d.count, None, d.detail))
    known = set(DOCUMENT_ARRAYS) | {"roots", "max_depth", "root_size"} | {f"{k}/{a}" for k in range(int(ref["layer_count"])) for a in LAYER_ARRAYS}
    for name in sorted((set(ref) | set(painter)) - known):
        side = "reference" if name in ref else "painter"
        out.append(Difference(name, 1, None, f"an array only the {side}'s dump holds"))
    return out


def record(d: dict, cell: int) -> str:
    """One cell's stored fields, for the report."""
    if cell >= len(d["parent"]):
        return f"cell {cell} is past the used length {len(d['parent'])}"
    return (
        f"parent {int(d['parent'][cell])} first_child {int(d['first_child'][cell])} depth {int(d['depth'][cell])} "
        f"rgb {d['rgb'][cell].tolist()} sigma {float(d['sigma'][cell])!r} origin {d['origin'][cell].tolist()} "
        f"g3 {d['g3'][cell].tolist()}"
    )

"""Tree dumps (.npz, spec 11): the arrays both implementations write at a
trace's `snapshot` events and the conformance driver compares.

The file is a zip (zipfile) of .npy entries (numpy's format.write_array),
stored without compression, entries in the order of DUMP_ARRAYS, every
timestamp 1980-01-01 00:00:00, so the same tree gives the same bytes here.
The painter's dumps (painter/octree/src/dump.rs, other zip and npy libraries)
hold the same arrays in other bytes: dumps are compared by content.
"""

from __future__ import annotations

import io
import os
import tempfile
import zipfile

import numpy as np

from .g3 import g3_from_links
from .prefilter import prefiltered

DUMP_ARRAYS = (
    ("parent", "<u4"),
    ("first_child", "<u4"),
    ("depth", "|u1"),
    ("rgb", "|u1"),
    ("sigma", "<f4"),
    ("g3", "<u4"),
    ("origin", "<u4"),
    ("roots", "<u4"),
    ("max_depth", "<u4"),
    ("root_size", "<f8"),
)


# The per-layer arrays of a document's dump (spec 14.5), under "k/".
LAYER_ARRAYS = DUMP_ARRAYS[:7]
DOCUMENT_ARRAYS = (
    ("roots", "<u4"),
    ("max_depth", "<u4"),
    ("root_size", "<f8"),
    ("layer_count", "<u4"),
    ("selected", "<u4"),
    ("layer_names", "|u1"),
    ("layer_visible", "|u1"),
    ("layer_locked", "|u1"),
    ("layer_opacity", "<f4"),
)


def entries(arrays: dict) -> list:
    """(name, dtype) of every entry of a dump, in file order: 11.1 for a
    tree, 14.5 for a document (it holds `layer_count`)."""
    if "layer_count" not in arrays:
        return list(DUMP_ARRAYS)
    out = list(DOCUMENT_ARRAYS)
    for k in range(int(arrays["layer_count"])):
        out.extend((f"{k}/{name}", dtype) for name, dtype in LAYER_ARRAYS)
    return out


def tree_arrays(tree) -> dict:
    n = tree.n_used
    parent = tree.parent[:n].copy()
    first_child = tree.first_child[:n].copy()
    depth = tree.depth[:n].copy()
    # Interior cells hold their children's prefilter (spec 4.4), computed
    # here: nothing else in the reference reads them.
    rgb, sigma = prefiltered(first_child, depth, tree.rgb[:n], tree.sigma[:n])
    return {
        "parent": parent,
        "first_child": first_child,
        "depth": depth,
        "rgb": rgb,
        "sigma": sigma,
        "g3": g3_from_links(parent, first_child, depth, tree.roots),
        "origin": tree.origin[:n].copy(),
        "roots": np.array(tree.roots, np.uint32),
        "max_depth": np.array(tree.max_depth, np.uint32),
        "root_size": np.array(tree.root_size, np.float64),
    }


def npy_bytes(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.require(a, requirements="C"), version=(1, 0), allow_pickle=False)
    return buf.getvalue()


def dump_bytes(arrays: dict) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as z:
        for name, dtype in entries(arrays):
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_STORED
            info.external_attr = 0o644 << 16
            z.writestr(info, npy_bytes(np.asarray(arrays[name]).astype(dtype, copy=False)))
    return buf.getvalue()


def write_atomic(path: str, data: bytes) -> None:
    """Write, fsync, rename: a reader never sees a half-written file. The
    file is made readable by all (0644), not mkstemp's owner-only 0600."""
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=d, prefix=".tmp-", suffix=os.path.basename(path))
    try:
        os.fchmod(fd, 0o644)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


class DumpError(ValueError):
    pass


def load_dump(path) -> dict:
    """Read a dump, checking names and dtypes. Raises DumpError."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as e:
        raise DumpError(f"{path}: not a readable .npz dump: {e}") from None
    if "layer_count" in arrays and arrays["layer_count"].shape != ():
        raise DumpError(f"{path}: array 'layer_count' is not a scalar")
    for name, dtype in entries(arrays):
        if name not in arrays:
            raise DumpError(f"{path}: array {name!r} is missing")
        if arrays[name].dtype != np.dtype(dtype):
            raise DumpError(f"{path}: array {name!r} has dtype {arrays[name].dtype}, expected {np.dtype(dtype)}")
    return arrays


def layer_trees(arrays: dict) -> list:
    """The tree arrays (11.1) of every layer of a dump, bottom first: the
    dump itself for a tree, one dict per layer for a document (14.5)."""
    if "layer_count" not in arrays:
        return [arrays]
    shared = {k: arrays[k] for k in ("roots", "max_depth", "root_size")}
    return [{**shared, **{name: arrays[f"{k}/{name}"] for name, _ in LAYER_ARRAYS}} for k in range(int(arrays["layer_count"]))]

"""The painting resampled at one export depth E, as *regions*: the
reference's independent twin of the painter's voxel export
(painter/export/src/values.rs and voxels.rs, docs/export.md), written as a
plain .npz so that a test can compare it with the painter's OpenVDB file as
OpenVDB itself reads it.

A region is a cell where a depth-first walk from the roots (roots in index
order, children k = 0..7) stops: a leaf of depth d <= E, or a cell with
children of depth E. It covers the cube of 2^(E-d) voxels on a side at voxel
origin `origin >> (D - E)`. Its value is the leaf's own, or for a cell with
children the aggregate of its leaves: volume-weighted mean extinction, and
colour weighted by extinction times volume (a plain volume-weighted mean
where every leaf is empty). Only regions whose extinction rounded to f32 is
> 0 are written, in walk order.

The .npz holds:

    origin       int32 (N, 3)  voxel origin of each region
    log2_edge    uint8 (N,)    log2 of its edge in voxels (E - d)
    density      f32   (N,)    extinction per canvas unit
    color        f32   (N, 3)  colour, linear or sRGB-encoded
    depth        uint32 ()     E
    voxel_size   f64   ()      root_size * 2^-E, canvas units
    colour_space unicode ()    "linear" or "srgb"

Everything is whole-array numpy: the walk keeps the sequence of cells where
it currently stops, in walk order, and replaces every cell it descends into
by its eight children, one depth at a time; the aggregates are sums grouped
by the region a leaf falls in, taken in the order the painter's stack visits
the leaves (children 7..0), so that the f64 sums are the painter's, bit for
bit.
"""

from __future__ import annotations

import io
import time
import zipfile

import numpy as np

from .dump import DumpError, load_dump, npy_bytes, tree_arrays, write_atomic

NONE = 0xFFFF_FFFF
FREE = 255
COLOUR_SPACES = ("linear", "srgb")
# The arrays the export reads from a dump, with their shapes (n = cells).
_SHAPES = {
    "first_child": ("n",),
    "depth": ("n",),
    "rgb": ("n", 3),
    "sigma": ("n",),
    "origin": ("n", 3),
    "roots": (3,),
    "max_depth": (),
    "root_size": (),
}


class ExportError(ValueError):
    """The input cannot be exported (malformed tree, depth out of range)."""


# ------------------------------------------------------------------ input
def check_tree(arrays: dict) -> None:
    """Shapes and lattice parameters the export relies on; raises
    ExportError. (The walk itself checks every link it follows.)"""
    for k in _SHAPES:
        if k not in arrays:
            raise ExportError(f"array {k!r} is missing")
    n = len(arrays["depth"]) if np.ndim(arrays["depth"]) == 1 else -1
    for k, shape in _SHAPES.items():
        want = tuple(n if s == "n" else s for s in shape)
        if np.shape(arrays[k]) != want:
            raise ExportError(f"array {k!r} has shape {np.shape(arrays[k])}, expected {want}")
    roots = [int(r) for r in arrays["roots"]]
    d = int(arrays["max_depth"])
    if min(roots) < 1 or d > 32 or any(r << d > 1 << 32 for r in roots):
        raise ExportError(f"roots {tuple(roots)} of depth {d} do not fit the u32 lattice")
    if roots[0] * roots[1] * roots[2] > n:
        raise ExportError(f"{roots[0] * roots[1] * roots[2]} roots but only {n} cells")
    size = float(arrays["root_size"])
    if not (np.isfinite(size) and size > 0):
        raise ExportError(f"root_size {size!r} is not a positive number")


def load_input(path: str, warn=None, depth: int | None = None) -> tuple[dict, float]:
    """The tree arrays of a dump (.npz) or of a trace's final tree (.jsonl,
    replayed in memory, nothing written). Returns (arrays, replay seconds).
    Raises ExportError (bad dump or tree, or `depth` out of the canvas's
    range, checked before a trace is replayed) or TraceError (bad trace)."""
    if _is_dump(path):
        try:
            arrays = load_dump(path)
        except DumpError as e:
            raise ExportError(str(e).removeprefix(f"{path}: ")) from None
        check_tree(arrays)
        if depth is not None:
            check_depth(depth, deepest_export(arrays))
        return arrays, 0.0
    from .replay import replay
    from .trace import read_trace

    trace = read_trace(path)
    if depth is not None:
        c = trace.canvas
        check_depth(depth, min(c.max_depth, deepest_addressable(c.roots, c.max_depth)))
    t0 = time.perf_counter()
    stats = replay(trace, None, warn=warn, renders=False)
    arrays = tree_arrays(stats.painting.tree)
    return arrays, time.perf_counter() - t0


def _is_dump(path: str) -> bool:
    low = path.lower()
    if low.endswith(".npz"):
        return True
    if low.endswith(".jsonl"):
        return False
    try:
        with open(path, "rb") as f:
            return f.read(4) == b"PK\x03\x04"
    except OSError:
        return False  # read_trace reports it


# ------------------------------------------------------------------ depths
def deepest_addressable(roots, max_depth: int) -> int:
    """The greatest E <= D whose voxel indices fit OpenVDB's i32
    coordinates: max(R) * 2^E <= 2^31."""
    r = max(int(x) for x in roots)
    e = int(max_depth)
    while e > 0 and r << e > 1 << 31:
        e -= 1
    return e


def deepest_export(arrays: dict) -> int:
    """The finest depth an export may ask for."""
    d = int(arrays["max_depth"])
    return min(d, deepest_addressable(arrays["roots"], d))


def deepest_painted(arrays: dict) -> int:
    """The deepest depth of a leaf with extinction > 0 (0 when empty)."""
    depth = arrays["depth"]
    painted = (depth != FREE) & (arrays["first_child"] == NONE) & (arrays["sigma"] > 0)
    return int(depth[painted].max()) if painted.any() else 0


def default_depth(arrays: dict) -> int:
    return min(deepest_painted(arrays), deepest_export(arrays))


def check_depth(e: int, deepest: int) -> None:
    if not 0 <= e <= deepest:
        raise ExportError(f"export depth {e} is out of range: this canvas goes from depth 0 to {deepest}")


# ------------------------------------------------------------------ the walk
def _expand(seq, go, fc, depth, origin, max_depth, reverse: bool, extra=None):
    """Replace every seq[i] with go[i] by its eight children (k = 0..7, or
    7..0 when reverse), keeping the order; `extra` (an array parallel to
    seq) is repeated alongside. Checks each link followed."""
    n = len(depth)
    parents = seq[go]
    pfc = fc[parents]
    if len(parents) and int(pfc.max()) > n - 8:
        bad = parents[np.argmax(pfc > n - 8)]
        raise ExportError(f"cell {bad}: first_child {fc[bad]} is past the {n} cells")
    counts = np.where(go, 8, 1)
    rep = np.repeat(seq, counts)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    k = np.arange(len(rep), dtype=np.int64) - start
    child = np.repeat(go, counts)
    if reverse:
        k = 7 - k
    out = np.where(child, fc[rep].astype(np.int64) + k, rep)
    # Every child one depth deeper, at its octant of the parent's cube.
    p, c, kk = rep[child], out[child], k[child]
    pd = depth[p].astype(np.int64)
    bad = (depth[c].astype(np.int64) != pd + 1) | (pd >= max_depth)
    if bad.any():
        i = int(np.argmax(bad))
        raise ExportError(
            f"cell {c[i]}: depth {depth[c[i]]} under cell {p[i]} of depth {depth[p[i]]} (max_depth {max_depth})"
        )
    half = np.left_shift(np.int64(1), max_depth - pd - 1)
    bits = (kk[:, None] >> np.arange(3)) & 1
    want = origin[p].astype(np.int64) + bits * half[:, None]
    bad = np.any(origin[c].astype(np.int64) != want, axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise ExportError(f"cell {c[i]}: origin {origin[c[i]].tolist()}, expected {want[i].tolist()} (octant {kk[i]} of cell {p[i]})")
    return out, (None if extra is None else np.repeat(extra, counts))


def region_cells(arrays: dict, e: int) -> np.ndarray:
    """The cells where the export walk at depth e stops, in walk order
    (int64): leaves of depth <= e and cells with children of depth e."""
    fc, depth, origin = arrays["first_child"], arrays["depth"], arrays["origin"]
    d_max = int(arrays["max_depth"])
    rx, ry, rz = (int(r) for r in arrays["roots"])
    seq = np.arange(rx * ry * rz, dtype=np.int64)
    xyz = np.stack([seq % rx, (seq // rx) % ry, seq // (rx * ry)], axis=1) << d_max
    if np.any(depth[seq] != 0) or np.any(origin[seq].astype(np.int64) != xyz):
        r = int(np.argmax((depth[seq] != 0) | np.any(origin[seq].astype(np.int64) != xyz, axis=1)))
        raise ExportError(f"root {r}: depth {depth[r]} and origin {origin[r].tolist()}, expected 0 and {xyz[r].tolist()}")
    while True:
        go = (fc[seq] != NONE) & (depth[seq] < e)
        if not go.any():
            return seq
        seq, _ = _expand(seq, go, fc, depth, origin, d_max, reverse=False)


def region_values(arrays: dict, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sigma f64 [n], sRGB colour f64 [n, 3]) of each cell seen at its own
    depth (values.rs, cell_value)."""
    fc, depth, origin = arrays["first_child"], arrays["depth"], arrays["origin"]
    sigma = arrays["sigma"][cells].astype(np.float64)
    rgb = arrays["rgb"][cells].astype(np.float64) / 255.0
    agg = np.nonzero(fc[cells] != NONE)[0]
    if not len(agg):
        return sigma, rgb
    # Descendant leaves of each aggregated cell, in the painter's stack
    # order (pre-order, children 7..0), grouped by the cell they fall in.
    seq, grp = cells[agg], np.arange(len(agg), dtype=np.int64)
    while True:
        go = fc[seq] != NONE
        if not go.any():
            break
        seq, grp = _expand(seq, go, fc, depth, origin, int(arrays["max_depth"]), reverse=True, extra=grp)
    d0 = depth[cells[agg]].astype(np.int64)
    w = np.ldexp(1.0, -3 * (depth[seq].astype(np.int64) - d0[grp]))  # 8^-(d - d0): exact
    s = arrays["sigma"][seq].astype(np.float64)
    c = arrays["rgb"][seq].astype(np.float64) / 255.0
    m = len(agg)
    sw = np.bincount(grp, weights=s * w, minlength=m)  # sequential sums, in seq order
    dense = np.stack([np.bincount(grp, weights=c[:, a] * s * w, minlength=m) for a in range(3)], axis=1)
    plain = np.stack([np.bincount(grp, weights=c[:, a] * w, minlength=m) for a in range(3)], axis=1)
    pos = sw > 0
    col = plain.copy()
    col[pos] = np.clip(dense[pos] / sw[pos, None], 0.0, 1.0)
    sigma[agg] = sw
    rgb[agg] = col
    return sigma, rgb


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """The sRGB transfer function inverted (IEC 61966-2-1), f64."""
    v = np.asarray(v, np.float64)
    with np.errstate(invalid="ignore"):
        return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def export_regions(arrays: dict, e: int | None = None, colour: str = "linear") -> dict:
    """The export of the tree `arrays` at depth e (default: the deepest
    painted depth, capped at the deepest exportable): the .npz arrays."""
    if colour not in COLOUR_SPACES:
        raise ValueError(f"colour space {colour!r}: expected one of {COLOUR_SPACES}")
    if e is None:
        e = default_depth(arrays)
    check_depth(e, deepest_export(arrays))
    cells = region_cells(arrays, e)
    sigma, rgb = region_values(arrays, cells)
    with np.errstate(over="ignore"):
        density = sigma.astype(np.float32)
    keep = density > 0
    cells, density, rgb = cells[keep], density[keep], rgb[keep]
    shift = int(arrays["max_depth"]) - e
    col = rgb if colour == "srgb" else srgb_to_linear(rgb)
    return {
        "origin": (arrays["origin"][cells].astype(np.int64) >> shift).astype(np.int32).reshape(-1, 3),
        "log2_edge": (e - arrays["depth"][cells].astype(np.int64)).astype(np.uint8),
        "density": density,
        "color": col.astype(np.float32).reshape(-1, 3),
        "depth": np.array(e, np.uint32),
        "voxel_size": np.array(np.ldexp(float(arrays["root_size"]), -e), np.float64),
        "colour_space": np.array(colour, np.str_),
    }


def active_voxels(log2_edge: np.ndarray) -> int:
    """Σ 8^k over the regions, exact (a Python int)."""
    counts = np.bincount(np.asarray(log2_edge, np.int64), minlength=1)
    return sum(int(n) << (3 * k) for k, n in enumerate(counts.tolist()))


# ------------------------------------------------------------------ output
EXPORT_ARRAYS = ("origin", "log2_edge", "density", "color", "depth", "voxel_size", "colour_space")


def export_bytes(out: dict) -> bytes:
    """An .npz of the export arrays, stored uncompressed with fixed
    timestamps (the same export always gives the same bytes)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as z:
        for name in EXPORT_ARRAYS:
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_STORED
            info.external_attr = 0o644 << 16
            z.writestr(info, npy_bytes(np.asarray(out[name])))
    return buf.getvalue()


def write_export(path: str, out: dict) -> None:
    """Atomically (temporary file in the same folder, then rename), 0644."""
    write_atomic(path, export_bytes(out))


def load_export(path: str) -> dict:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def summary(out: dict, seconds: float, replay_seconds: float = 0.0) -> str:
    n = len(out["density"])
    line = (
        f"exported {n} region{'s' if n != 1 else ''} ({active_voxels(out['log2_edge'])} active voxels) "
        f"at depth {int(out['depth'])}, voxel size {float(out['voxel_size'])!r}, "
        f"{out['colour_space']} colour, in {seconds:.2f} s"
    )
    if replay_seconds:
        line += f" (after replaying the trace in {replay_seconds:.2f} s)"
    return line


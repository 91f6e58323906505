"""Voxel sets: what an `import` event paints (spec 15).

A voxel set is an `.npz` of `depth`, `ijk`, `rgb` and `sigma` (15.1). This
module reads and checks one against a canvas, writes one (the trace
generator and the tests make them), and indexes one for the import's
decisions: which cells it reaches, the value at a cell's centre, and
whether a leaf is settled (15.3). Painter twins: painter/trace/src/voxels.rs
(the file) and painter/paint/src/voxels.rs (painting it).
"""

from __future__ import annotations

import hashlib
import io
import struct
import zipfile
from dataclasses import dataclass

import numpy as np

from .dump import npy_bytes

MAX_VOXELS = 1 << 26
ENTRIES = (("depth", "<u4", 0), ("ijk", "<u4", 2), ("rgb", "|u1", 2), ("sigma", "<f4", 1))


@dataclass(frozen=True, eq=False)
class VoxelSet:
    depth: int
    ijk: np.ndarray  # (n, 3) uint32
    rgb: np.ndarray  # (n, 3) uint8
    sigma: np.ndarray  # (n,) float32

    def __len__(self) -> int:
        return len(self.sigma)


@dataclass(frozen=True, eq=False)
class Import:
    """The value of an `import` event: the file as the trace names it, its
    digest, the optional label and the voxel set read from it."""

    file: str
    sha256: str
    name: str | None
    voxels: VoxelSet


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def write_bytes(depth: int, ijk, rgb, sigma) -> bytes:
    """A voxel set's file: stored entries in the order of 15.1, fixed
    timestamps (the same bytes for the same set)."""
    arrays = {
        "depth": np.asarray(depth, "<u4"),
        "ijk": np.asarray(ijk, "<u4").reshape(-1, 3),
        "rgb": np.asarray(rgb, "|u1").reshape(-1, 3),
        "sigma": np.asarray(sigma, "<f4").reshape(-1),
    }
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as z:
        for name, _, _ in ENTRIES:
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_STORED
            info.external_attr = 0o644 << 16
            z.writestr(info, npy_bytes(arrays[name]))
    return buf.getvalue()


def _array(z: zipfile.ZipFile, name: str, dtype: str, ndim: int) -> np.ndarray:
    try:
        info = z.getinfo(f"{name}.npy")
    except KeyError:
        raise ValueError(f"the entry {name}.npy is missing") from None
    if info.compress_type != zipfile.ZIP_STORED:
        raise ValueError(f"{name}.npy is compressed (write voxel sets with numpy's savez, not savez_compressed)")
    if info.compress_size != info.file_size:
        # A stored entry's bytes are its contents: sizes that differ are a
        # damaged zip (Python's reader would go by one and ignore the other).
        raise ValueError(f"damaged .npz: {name}.npy is stored in {info.compress_size} bytes but holds {info.file_size}")
    with z.open(info) as f:
        try:
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                shape, fortran, dt = np.lib.format.read_array_header_1_0(f)
            elif version == (2, 0):
                shape, fortran, dt = np.lib.format.read_array_header_2_0(f)
            else:
                raise ValueError(f"npy format version {version} is not supported")
        except ValueError as e:
            raise ValueError(f"{name}.npy: {e}") from None
        if dt.str != dtype:
            raise ValueError(f"{name}.npy has dtype {dt.str}, expected {dtype}")
        if len(shape) != ndim or (ndim == 2 and shape[1] != 3):
            want = {0: "[]", 1: "[n]", 2: "[n, 3]"}[ndim]
            raise ValueError(f"{name}.npy has shape {list(shape)}, expected {want}")
        if fortran and ndim == 2:
            raise ValueError(f"{name}.npy is Fortran-ordered (C order is required)")
        if ndim and shape[0] > MAX_VOXELS:
            raise ValueError(f"{name}.npy holds {shape[0]} voxels, more than {MAX_VOXELS}")
        count = int(np.prod(shape, dtype=np.int64)) if ndim else 1
        data = f.read(count * dt.itemsize + 1)
        if len(data) != count * dt.itemsize:
            raise ValueError(f"{name}.npy holds {len(data)} bytes of data, its header says {count * dt.itemsize}")
        return np.frombuffer(data, dtype=dt).reshape(shape)


def _check_end_record(data: bytes) -> int:
    """The archive's end-of-central-directory record as 15.1 requires it
    (and as painter/trace/src/voxels.rs checks it): the last `PK\\5\\6` in
    the file's final 65,557 bytes, one disk, its two entry counts equal,
    its central directory ending where it begins (nothing between them,
    nothing before the archive), its comment within the file. zip readers
    differ on each (Python's takes a comment cut short and ignores disk
    numbers), so the rule is the spec's; so are the central directory's
    entries filling it exactly. Returns the entry count."""
    start = max(0, len(data) - (22 + 0xFFFF))
    tail = data[start:]
    at = tail.rfind(b"PK\x05\x06")
    if at < 0:
        raise ValueError("not an .npz (zip) file: no end of central directory record")
    if at + 22 > len(tail):
        raise ValueError("not an .npz (zip) file: its end record is cut short")
    _, disk, disk_cd, here, total, size_cd, offset_cd, comment = struct.unpack("<4s4H2LH", tail[at : at + 22])
    if disk or disk_cd:
        raise ValueError("not an .npz (zip) file: it spans several disks")
    if here != total:
        raise ValueError("not an .npz (zip) file: its end record counts its entries two ways")
    if offset_cd + size_cd != start + at:
        raise ValueError("not an .npz (zip) file: its central directory does not end where its end record begins")
    if at + 22 + comment > len(tail):
        raise ValueError("not an .npz (zip) file: its end record's comment runs past the end of the file")
    # Its central directory's entries fill it exactly (zipfile would read a
    # name running past its end cut short), each needing zip 6.3 at most.
    p, end = offset_cd, start + at
    for _ in range(total):
        e = data[p : p + 46]
        if len(e) < 46:
            raise ValueError("not an .npz (zip) file: its central directory is cut short")
        if e[:4] != b"PK\x01\x02":
            raise ValueError("not an .npz (zip) file: its central directory is damaged")
        if e[6] > 63:
            raise ValueError(f"not an .npz (zip) file: an entry needs zip version {e[6] // 10}.{e[6] % 10} to be read")
        n, x, c = struct.unpack("<3H", e[28:34])
        p += 46 + n + x + c
        if p > end:
            raise ValueError("not an .npz (zip) file: an entry of its central directory runs past its end")
    if p != end:
        raise ValueError("not an .npz (zip) file: its central directory holds more than its entries")
    return total


def parse(data: bytes, canvas) -> VoxelSet:
    """Check `data` as a voxel set for `canvas` (15.1); ValueError says what
    is wrong."""
    entries = _check_end_record(data)
    try:
        z = zipfile.ZipFile(io.BytesIO(data))
    # NotImplementedError: an entry that needs a zip version above 6.3.
    except (zipfile.BadZipFile, ValueError, OSError, NotImplementedError) as e:
        raise ValueError(f"not an .npz (zip) file: {e}") from None
    if len(z.infolist()) != entries:
        raise ValueError(f"not an .npz (zip) file: its end record counts {entries} entries, its central directory holds {len(z.infolist())}")
    try:
        with z:
            arrays = {name: _array(z, name, dtype, ndim) for name, dtype, ndim in ENTRIES}
    # RuntimeError: an entry flagged as encrypted (zipfile asks for a password).
    except (zipfile.BadZipFile, OSError, EOFError, zipfile.LargeZipFile, NotImplementedError, RuntimeError) as e:
        raise ValueError(f"damaged .npz: {e}") from None
    depth = int(arrays["depth"])
    ijk, rgb, sigma = arrays["ijk"], arrays["rgb"], arrays["sigma"]
    n = len(ijk)
    if len(rgb) != n or len(sigma) != n:
        raise ValueError(f"ijk, rgb and sigma hold {n}, {len(rgb)} and {len(sigma)} voxels")
    if depth > canvas.max_depth:
        raise ValueError(f"depth {depth} is deeper than the canvas's max_depth {canvas.max_depth}")
    extent = np.array(canvas.roots, np.uint64) << np.uint64(depth)
    bad = np.nonzero(np.any(ijk.astype(np.uint64) >= extent, axis=1))[0]
    if len(bad):
        i = int(bad[0])
        raise ValueError(f"voxel {i} at {ijk[i].tolist()} is outside the canvas ({extent.tolist()} voxels at depth {depth})")
    bits = sigma.view(np.uint32)
    bad = np.nonzero(~np.isfinite(sigma) | (bits >> 31 != 0))[0]
    if len(bad):
        i = int(bad[0])
        raise ValueError(f"voxel {i} has sigma {float(sigma[i])!r} (finite, >= 0 and not -0 required)")
    if n:
        keys = _keys(ijk)
        order = np.argsort(keys, kind="stable")
        same = np.nonzero(keys[order][1:] == keys[order][:-1])[0]
        if len(same):
            i, j = sorted((int(order[same[0]]), int(order[same[0] + 1])))
            raise ValueError(f"voxels {i} and {j} are both at {ijk[i].tolist()}")
    return VoxelSet(depth, ijk.copy(), rgb.copy(), sigma.copy())


def _keys(ijk: np.ndarray) -> np.ndarray:
    """One sortable key per row of (n, 3) coordinates below 2^32: the bytes
    of (z, y, x) big-endian, so that byte order is numeric order."""
    k = np.ascontiguousarray(np.asarray(ijk, np.uint64)[:, ::-1].astype(">u4"))
    return k.view("V12").ravel()


def packed(rgb: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """A stored value as one integer: rgb bytes and the f32 bits of sigma."""
    rgb = np.asarray(rgb, np.uint64).reshape(-1, 3)
    s = np.asarray(sigma, np.float32).reshape(-1).view(np.uint32).astype(np.uint64)
    return rgb[:, 0] | (rgb[:, 1] << np.uint64(8)) | (rgb[:, 2] << np.uint64(16)) | (s << np.uint64(24))


class VoxelIndex:
    """Per depth e <= d, the blocks of the voxel set (15.3): for each cell
    position at depth e that holds a voxel, how many it holds and the
    smallest and largest packed value among them."""

    def __init__(self, vs: VoxelSet, max_depth: int):
        self.d = vs.depth
        self.D = max_depth
        self.rgb, self.sigma = vs.rgb, vs.sigma
        keys = _keys(vs.ijk)
        order = np.argsort(keys, kind="stable")
        ijk = vs.ijk[order].astype(np.uint64)
        val = packed(vs.rgb[order], vs.sigma[order])
        # Level d: the voxels themselves (order maps back to the set's rows).
        self.levels = {self.d: (keys[order], np.ones(len(val), np.uint64), val, val, order)}
        for e in range(self.d - 1, -1, -1):
            ijk = ijk >> np.uint64(1)
            k = _keys(ijk)
            o = np.argsort(k, kind="stable")
            k, ijk_s = k[o], ijk[o]
            _, cnt_prev, lo_prev, hi_prev, _ = self.levels[e + 1]
            cnt_s, lo_s, hi_s = cnt_prev[o], lo_prev[o], hi_prev[o]
            start = np.nonzero(np.concatenate(([True], k[1:] != k[:-1])))[0] if len(k) else np.zeros(0, np.int64)
            if len(k):
                cnt = np.add.reduceat(cnt_s, start)
                lo = np.minimum.reduceat(lo_s, start)
                hi = np.maximum.reduceat(hi_s, start)
            else:
                cnt = lo = hi = np.zeros(0, np.uint64)
            ijk = ijk_s[start]
            self.levels[e] = (k[start], cnt, lo, hi, None)

    def _find(self, e: int, q: np.ndarray) -> np.ndarray:
        """Row of each coordinate (m, 3) in level e, -1 where absent."""
        keys = self.levels[e][0]
        if len(q) == 0 or len(keys) == 0:
            return np.full(len(q), -1, np.int64)
        k = _keys(q)
        i = np.searchsorted(keys, k)
        i = np.minimum(i, len(keys) - 1)
        return np.where(keys[i] == k, i, -1).astype(np.int64)

    def reached(self, tree, cells: np.ndarray) -> np.ndarray:
        """bool: the cells whose block holds a voxel."""
        depth = tree.depth[cells].astype(np.int64)
        o = tree.origin[cells].astype(np.uint64)
        out = np.zeros(len(cells), bool)
        for e in np.unique(depth).tolist():
            sel = depth == e
            lv = min(e, self.d)
            out[sel] = self._find(lv, o[sel] >> np.uint64(self.D - lv)) >= 0
        return out

    def centre_values(self, tree, cells: np.ndarray):
        """The voxel at each cell's centre (15.3): (found, rgb, sigma)."""
        depth = tree.depth[cells].astype(np.int64)
        o = tree.origin[cells].astype(np.uint64)
        shift = np.where(depth < self.d, self.D - depth - 1, 0)
        half = np.where(depth < self.d, np.uint64(1) << shift.astype(np.uint64), np.uint64(0))
        q = (o + half[:, None]) >> np.uint64(self.D - self.d)
        row = self._find(self.d, q)
        found = row >= 0
        src = self.levels[self.d][4][row[found]]
        rgb = np.zeros((len(cells), 3), np.uint8)
        sigma = np.zeros(len(cells), np.float32)
        rgb[found] = self.rgb[src]
        sigma[found] = self.sigma[src]
        return found, rgb, sigma

    def settled(self, tree, cells: np.ndarray, before_rgb, before_sigma) -> np.ndarray:
        """bool: leaves of depth < d whose block and before-value hold one
        stored value (15.3). Cells of depth >= d are never candidates."""
        depth = tree.depth[cells].astype(np.int64)
        o = tree.origin[cells].astype(np.uint64)
        b = packed(before_rgb, before_sigma)
        out = np.zeros(len(cells), bool)
        for e in np.unique(depth).tolist():
            if e >= self.d:
                continue
            sel = np.nonzero(depth == e)[0]
            row = self._find(e, o[sel] >> np.uint64(self.D - e))
            ok = row >= 0
            _, cnt, lo, hi, _ = self.levels[e]
            r = row[ok]
            # 8^(d-e) voxels: more than a set can hold once 3(d-e) > 26.
            whole = cnt[r] == np.uint64(1 << (3 * (self.d - e))) if 3 * (self.d - e) <= 26 else np.zeros(len(r), bool)
            one = (lo[r] == hi[r]) & (whole | (lo[r] == b[sel][ok]))
            out[sel[ok]] = one
        return out

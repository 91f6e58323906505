"""Voxel set files (spec 15.1) written with the standard library alone: the
import traces' voxel sets (traces/imports/) and the malformed ones
(traces/malformed/imports/). Used by generate.py."""

from __future__ import annotations

import io
import struct
import zipfile


def npy(descr: str, shape: tuple, fmt: str, values) -> bytes:
    """One .npy (format 1.0) without numpy: the header dict padded so the data
    starts at a multiple of 64 bytes, then the values little-endian."""
    shp = "(" + "".join(f"{n}, " for n in shape)[:-2] + ("," if len(shape) == 1 else "") + ")" if shape else "()"
    head = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {shp}, }}"
    pad = 64 - (10 + len(head) + 1) % 64
    head = head + " " * (pad % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(head)) + head.encode() + struct.pack("<" + fmt * len(values), *values)


def voxel_set(depth: int, voxels, compress=False, ijk_descr="<u4") -> bytes:
    """A voxel set file (spec 15.1): voxels are (i, j, k, r, g, b, sigma)."""
    ijk = [c for v in voxels for c in v[:3]]
    entries = [
        ("depth", npy("<u4", (), "I", [depth])),
        ("ijk", npy(ijk_descr, (len(voxels), 3), "I" if ijk_descr == "<u4" else "q", ijk)),
        ("rgb", npy("|u1", (len(voxels), 3), "B", [c for v in voxels for c in v[3:6]])),
        ("sigma", npy("<f4", (len(voxels),), "f", [v[6] for v in voxels])),
    ]
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, data in entries:
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
            info.external_attr = 0o644 << 16
            z.writestr(info, data)
    return buf.getvalue()


def ball_voxels(depth: int, centre, radius: float, root_size: float, colour):
    """The voxels at `depth` whose centres lie in a ball, coloured by
    colour(i, j, k); sigma per voxel from colour too."""
    h = root_size / (1 << depth)
    lo = [max(0, int((c - radius) / h) - 1) for c in centre]
    hi = [int((c + radius) / h) + 1 for c in centre]
    out = []
    for k in range(lo[2], hi[2] + 1):
        for j in range(lo[1], hi[1] + 1):
            for i in range(lo[0], hi[0] + 1):
                x = [(q + 0.5) * h for q in (i, j, k)]
                if sum((a - b) ** 2 for a, b in zip(x, centre)) <= radius * radius:
                    out.append((i, j, k) + colour(i, j, k))
    return out

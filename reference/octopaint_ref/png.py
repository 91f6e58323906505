"""8-bit RGB PNG encoding (the images written at `render` events, spec 6).

One IDAT, filter 0 on every row, zlib level 6, no ancillary chunks: the same
pixels always give the same bytes, whichever library reads them. Written
atomically with dump.write_atomic.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _chunk(kind: bytes, data: bytes) -> bytes:
    crc = zlib.crc32(kind + data) & 0xFFFFFFFF
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)


def png_bytes(rgb: np.ndarray) -> bytes:
    """rgb: uint8 [h, w, 3], row 0 at the top."""
    rgb = np.ascontiguousarray(rgb, np.uint8)
    h, w, c = rgb.shape
    if c != 3:
        raise ValueError(f"expected [h, w, 3] pixels, got shape {rgb.shape}")
    raw = np.zeros((h, 1 + 3 * w), np.uint8)  # filter byte 0, then the row
    raw[:, 1:] = rgb.reshape(h, 3 * w)
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8-bit, truecolour
    return SIGNATURE + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + _chunk(b"IEND", b"")


def read_png(data: bytes) -> np.ndarray:
    """Decode what png_bytes writes (8-bit RGB, filter 0): uint8 [h, w, 3]."""
    if data[:8] != SIGNATURE:
        raise ValueError("not a PNG")
    pos, idat, w, h = 8, b"", 0, 0
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            w, h, bits, colour = struct.unpack(">IIBB", body[:10])
            if (bits, colour) != (8, 2):
                raise ValueError("only 8-bit RGB is read")
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + 3 * w)
    if np.any(raw[:, 0] != 0):
        raise ValueError("only filter 0 is read")
    return raw[:, 1:].reshape(h, w, 3).copy()

"""PNG files of rendered images (spec 6), through Pillow.

Images are compared by their decoded pixels (conformance/images.py), so the
encoder is Pillow's; the same pixels still give the same bytes with one
Pillow version. Written atomically with dump.write_atomic.
"""

from __future__ import annotations

import io

import numpy as np
from PIL import Image


def png_bytes(rgb: np.ndarray) -> bytes:
    """rgb: uint8 [h, w, 3], row 0 at the top."""
    rgb = np.ascontiguousarray(rgb, np.uint8)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected [h, w, 3] pixels, got shape {rgb.shape}")
    buf = io.BytesIO()
    Image.fromarray(rgb, "RGB").save(buf, format="PNG")
    return buf.getvalue()


def read_png(data: bytes) -> np.ndarray:
    """Decode a PNG to uint8 [h, w, 3] (any mode Pillow reads is converted)."""
    with Image.open(io.BytesIO(data)) as im:
        return np.asarray(im.convert("RGB"), np.uint8).copy()

"""Comparing two images (docs/spec.md section 13).

Images keep a tolerance, as data, per precision of the GPU ray caster: it
traces in f32 (or f16) and composites in f32 with the device's exp, the
reference in f64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from PIL import Image

# Per ray-caster precision (spec 13). f32: lavapipe gives at most 1 step
# and 84.8-94.6 dB on every trace; the margin is for GPUs whose exp differs.
IMAGE_TOLERANCES = {
    "f32": {
        "max_steps": 1,  # a pixel is off when a channel differs by more than this
        "min_fraction_within": 0.999,  # of pixels
        "min_psnr_db": 60.0,
    },
    "f16": {
        "max_steps": 2,
        "min_fraction_within": 0.999,
        "min_psnr_db": 45.0,
    },
}
IMAGE_TOLERANCE = IMAGE_TOLERANCES["f32"]


@dataclass
class ImageResult:
    ok: bool
    fraction_within: float
    psnr_db: float
    max_steps: int
    detail: str


def read_rgb(path: str) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), np.uint8)


def compare(ref_path: str, painter_path: str, diff_path: str | None = None, tol: dict = IMAGE_TOLERANCE) -> ImageResult:
    a, b = read_rgb(ref_path), read_rgb(painter_path)
    if a.shape != b.shape:
        return ImageResult(False, 0.0, 0.0, 255, f"sizes differ: reference {a.shape}, painter {b.shape}")
    d = np.abs(a.astype(np.int32) - b.astype(np.int32))
    per_pixel = d.max(axis=2)
    within = float((per_pixel <= tol["max_steps"]).mean())
    mse = float((d.astype(np.float64) ** 2).mean())
    psnr = math.inf if mse == 0 else 10 * math.log10(255.0**2 / mse)
    ok = within >= tol["min_fraction_within"] and psnr >= tol["min_psnr_db"]
    if diff_path is not None and d.any():
        # Differences amplified 16x; pixels beyond tolerance in pure red.
        vis = np.clip(d * 16, 0, 255).astype(np.uint8)
        vis[per_pixel > tol["max_steps"]] = (255, 0, 0)
        Image.fromarray(vis).save(diff_path)
    detail = f"{100 * within:.3f}% of pixels within {tol['max_steps']} steps, PSNR {psnr:.1f} dB, largest difference {int(d.max())}"
    return ImageResult(ok, within, psnr, int(d.max()), detail)

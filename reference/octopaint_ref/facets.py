"""What interpolating the stored shading vectors across a leaf does (spec
6.1, docs/render.md "Lighting"): every lit render event of a one-tree trace
cast by the reference's f64 ray caster twice, with each leaf shaded by its
own vector alone (flat, one shade a cell) and as the spec says
(interpolated at each segment's midpoint). The figure is the root mean
square step between neighbouring pixels where both rays met paint, in
8-bit steps: a cell's flat face against its neighbour's shows as one step
at every cell edge, which interpolation spreads over the cell; and how
many pixels differ. --pair writes both side by side per render.

    python -m octopaint_ref.facets traces/lit.jsonl --pair docs/render
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace

import numpy as np

from .dump import tree_arrays
from .jax_setup import configure
from .lod_study import each_render, pair_strip, scaled
from .png import png_bytes
from .raycast import render


def neighbour_steps(image: np.ndarray, painted: np.ndarray) -> float:
    """The root mean square of the differences (8-bit steps, channels
    averaged) between horizontally or vertically adjacent pixels both
    painted. Spreading a change over several pixels leaves the mean step as
    it was and lowers this: it is what a flat face's edge raises."""
    x = image.astype(np.float64)
    dx = np.abs(x[:, 1:] - x[:, :-1]).mean(axis=-1)[painted[:, 1:] & painted[:, :-1]]
    dy = np.abs(x[1:] - x[:-1]).mean(axis=-1)[painted[1:] & painted[:-1]]
    both = np.concatenate([dx, dy])
    return float(np.sqrt((both * both).mean())) if both.size else 0.0


def study(trace_path: str, div: int = 1, pair=None, grow: int = 1, crop=None) -> list:
    """One row per lit render event of a one-tree trace, cameras at
    grow/div of their size (the field of view kept). crop: (x0, y0, x1,
    y1), fractions of the image the pair shows."""
    rows = []

    def after(name, painting, camera, light):
        if light is None or not light.on:
            return
        camera = scaled(camera, div)
        camera = replace(camera, size=(camera.size[0] * grow, camera.size[1] * grow))
        arrays = tree_arrays(painting.tree)
        flat = render(arrays, camera, light=light, flat=True)
        smooth = render(arrays, camera, light=light)
        # Painted: the ray's transmittance fell (it composited something).
        painted = np.any(smooth.colour.reshape(flat.image.shape) != np.asarray(camera.background), axis=-1)
        rows.append(
            {
                "render": name,
                "size": list(camera.size),
                "flat": neighbour_steps(flat.image, painted),
                "interpolated": neighbour_steps(smooth.image, painted),
                "differ": float(np.any(flat.image != smooth.image, axis=-1).mean()),
            }
        )
        if pair is not None:
            os.makedirs(pair, exist_ok=True)
            zoom = max(1, 320 // camera.size[0])
            out = f"{name}_facets.png" if grow == 1 else f"{name}_facets_x{grow}.png"
            shown = [flat.image, smooth.image]
            if crop is not None:
                h, w = flat.image.shape[:2]
                x0, y0, x1, y1 = int(crop[0] * w), int(crop[1] * h), int(crop[2] * w), int(crop[3] * h)
                shown = [im[y0:y1, x0:x1] for im in shown]
                zoom = max(1, 320 // max(1, x1 - x0))
            with open(os.path.join(pair, out), "wb") as f:
                f.write(png_bytes(pair_strip(shown, zoom)))

    each_render(trace_path, after)
    return rows


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(prog="python -m octopaint_ref.facets", description=__doc__.split("\n\n")[0])
    ap.add_argument("traces", nargs="+")
    ap.add_argument("--scale", type=int, default=1, help="divide every camera's size by this (fov kept; default 1)")
    ap.add_argument("--grow", type=int, default=1, help="multiply every camera's size by this (fov kept; default 1): cells cover more pixels")
    ap.add_argument("--crop", help="x0,y0,x1,y1: the part of each image the pair shows, as fractions (default all)")
    ap.add_argument("--pair", help="folder for each lit render's flat and interpolated images side by side")
    a = ap.parse_args(argv)
    if a.scale < 1 or a.grow < 1:
        ap.error("--scale and --grow must be at least 1")
    crop = None
    if a.crop is not None:
        crop = [float(x) for x in a.crop.split(",")]
        if len(crop) != 4 or not (0 <= crop[0] < crop[2] <= 1 and 0 <= crop[1] < crop[3] <= 1):
            ap.error("--crop takes x0,y0,x1,y1 with 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1")
    print("| trace | render | size | rms neighbour step, flat | interpolated | pixels that differ |")
    print("| --- | --- | --- | ---: | ---: | ---: |")
    for t in a.traces:
        for r in study(t, a.scale, a.pair, a.grow, crop):
            w, h = r["size"]
            print(f"| {t} | {r['render']} | {w}×{h} | {r['flat']:.3f} | {r['interpolated']:.3f} | {100 * r['differ']:.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The level of detail's quality and cost (spec 7, docs/benchmarks.md "Level
of detail"), measured with the reference's f64 ray caster: for every render
event of the given traces, the truth is the full-depth image cast at
`ss` x `ss` samples per pixel and box-filtered to the display size; the
figures are the PSNR of the full-depth image and of the image at each level
of detail against it, the cells stepped per ray (mean, p99), and a flicker
figure: the mean frame-to-frame difference of a slow pan (the camera
turned about the canvas y axis, `_turned`) or with `--orbit` of a slow
turntable (the camera carried about a vertical axis in front of it), with
and without.

    python -m octopaint_ref.lod_study traces/scene.jsonl traces/lit.jsonl --json out/lod.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import replace

import numpy as np

from .dump import tree_arrays
from .jax_setup import configure
from .lod import check_k, view_axis
from .png import png_bytes
from .precision import psnr
from .raycast import render
from .replay import replay
from .trace import read_trace


def _render(painting, camera, light, k=0.0):
    return render(tree_arrays(painting.tree), camera, light=light, lod=k)


def truth(painting, camera, light, ss: int) -> np.ndarray:
    """The full-depth image at ss x ss samples per pixel, box-filtered, as
    8-bit (the mean of the samples' f64 colours, rounded as spec 6)."""
    w, h = camera.size
    big = replace(camera, size=(w * ss, h * ss))
    c = _render(painting, big, light).colour.reshape(h, ss, w, ss, 3).mean(axis=(1, 3))
    return np.clip(np.floor(c * 255.0 + 0.5), 0, 255).astype(np.uint8)


def _turned(camera, degrees: float):
    """camera turned by `degrees` about the canvas y axis (a slow pan)."""
    a = math.radians(degrees) / 2
    qx, qy, qz, qw = camera.q
    s, c = math.sin(a), math.cos(a)
    # r * q with r = (0, s, 0, c)
    q = (c * qx + s * qz, c * qy + s * qw, c * qz - s * qx, c * qw - s * qy)
    return replace(camera, q=q)


def _orbited(camera, degrees: float, pivot):
    """camera carried `degrees` about the vertical (canvas y) axis through
    `pivot`, turning with it (a turntable seen from a fixed camera)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    v = np.asarray(camera.eye, np.float64) - pivot
    eye = pivot + np.array([c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]])
    return replace(_turned(camera, degrees), eye=tuple(float(x) for x in eye))


def orbit_pivot(painting, camera) -> np.ndarray:
    """The point of the view axis nearest the canvas's centre (at least one
    root edge in front of the eye): what a turntable turns about."""
    t = painting.tree
    centre = np.array(t.roots, np.float64) * t.root_size / 2.0
    eye, f = np.asarray(camera.eye, np.float64), view_axis(camera)
    return eye + f * max(float(np.dot(centre - eye, f)), t.root_size)


def flicker(painting, camera, light, k: float, frames: int, step_deg: float, orbit: bool = False) -> float:
    """Mean absolute frame-to-frame difference (8-bit steps per channel) of
    `frames` frames panning by `step_deg` each, or with `orbit` turning by
    as much about orbit_pivot (a slow turntable)."""
    pivot = orbit_pivot(painting, camera) if orbit else None
    prev, diffs = None, []
    for i in range(frames):
        view = _orbited(camera, i * step_deg, pivot) if orbit else _turned(camera, i * step_deg)
        img = _render(painting, view, light, k).image.astype(np.int64)
        if prev is not None:
            diffs.append(float(np.abs(img - prev).mean()))
        prev = img
    return float(np.mean(diffs))


def pair_strip(images: list, zoom: int) -> np.ndarray:
    """Images side by side, each enlarged `zoom` times (nearest pixel), with
    a 2-pixel white gap: the docs' before/after pictures."""
    big = [np.repeat(np.repeat(im, zoom, axis=0), zoom, axis=1) for im in images]
    gap = np.full((big[0].shape[0], 2, 3), 255, np.uint8)
    parts = []
    for b in big:
        parts += [b, gap]
    return np.concatenate(parts[:-1], axis=1)


def scaled(camera, div: int):
    """`camera` with its size divided by `div` (at least 1 pixel a side),
    the field of view kept: every cell covers 1/div as many pixels."""
    w, h = camera.size
    return replace(camera, size=(max(1, w // div), max(1, h // div)))


def each_render(trace_path: str, on_render) -> None:
    """Replay a one-tree trace (version 1), calling on_render(name,
    painting, camera, light) at every render event with the view the trace
    has set by then (light None before any light event)."""
    trace = read_trace(trace_path)
    if trace.version != 1:
        raise ValueError(f"{trace_path}: the study reads one-tree traces (version 1)")
    view = {"camera": None, "light": None}

    def after(ev, painting):
        if ev.kind in ("camera", "light"):
            view[ev.kind] = ev.value
        if ev.kind == "render":
            on_render(ev.value, painting, view["camera"], view["light"])

    replay(trace, None, renders=False, after_event=after)


def study(trace_path: str, lods: list, ss: int, frames: int, step_deg: float, div: int = 1, pair=None, orbit: bool = False) -> list:
    """One row per render event of a one-tree trace (version 1); cameras at
    1/div of their size. pair: a folder to write, per render, the images at
    the first and last k and the truth side by side (`RENDER_lod.png`)."""
    rows = []

    def after(name, painting, camera, light):
        camera = scaled(camera, div)
        t0 = time.perf_counter()
        ref = truth(painting, camera, light, ss)
        row = {"trace": trace_path, "render": name, "size": list(camera.size), "samples_per_pixel": ss * ss, "levels": []}
        images = []
        for k in lods:
            r = _render(painting, camera, light, k)
            images.append(r.image)
            steps = r.steps.ravel()
            row["levels"].append(
                {
                    "k": k,
                    "psnr_db": psnr(r.image, ref),
                    "steps_mean": float(steps.mean()),
                    "steps_p99": float(np.percentile(steps, 99)),
                    "flicker": flicker(painting, camera, light, k, frames, step_deg, orbit) if frames > 1 else None,
                }
            )
        row["seconds"] = time.perf_counter() - t0
        rows.append(row)
        if pair is not None:
            os.makedirs(pair, exist_ok=True)
            zoom = max(1, 320 // camera.size[0])
            with open(os.path.join(pair, f"{name}_lod.png"), "wb") as f:
                f.write(png_bytes(pair_strip([images[0], images[-1], ref], zoom)))

    each_render(trace_path, after)
    return rows


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(prog="python -m octopaint_ref.lod_study", description=__doc__.split("\n\n")[0])
    ap.add_argument("traces", nargs="+")
    ap.add_argument("--lod", default="0,1", help="levels of detail to compare (default 0,1)")
    ap.add_argument("--ss", type=int, default=4, help="samples per pixel and axis of the truth (default 4)")
    ap.add_argument("--frames", type=int, default=6, help="frames of the flicker pan (default 6; 1: none)")
    ap.add_argument("--step", type=float, default=0.25, help="degrees the pan turns per frame (default 0.25)")
    ap.add_argument("--json", help="write the rows here")
    ap.add_argument("--scale", type=int, default=1, help="divide every camera's size by this (fov kept; default 1)")
    ap.add_argument("--pair", help="folder for each render's images at the first and last k and the truth, side by side")
    ap.add_argument("--orbit", action="store_true", help="flicker over a turntable orbit (about the view axis's point nearest the canvas centre) instead of a pan")
    a = ap.parse_args(argv)
    if a.scale < 1:
        ap.error("--scale must be at least 1")
    lods = [check_k(float(x)) for x in a.lod.split(",")]
    rows = []
    print("| trace | render | size | k | PSNR against the truth (dB) | cells per ray, mean | p99 | flicker (steps) |")
    print("| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |")
    for t in a.traces:
        for row in study(t, lods, a.ss, a.frames, a.step, a.scale, a.pair, a.orbit):
            rows.append(row)
            for lv in row["levels"]:
                fl = f"{lv['flicker']:.3f}" if lv["flicker"] is not None else ""
                print(
                    f"| {t.split('/')[-1]} | {row['render']} | {row['size'][0]}×{row['size'][1]} | {lv['k']:g} | {lv['psnr_db']:.2f} | "
                    f"{lv['steps_mean']:.1f} | {lv['steps_p99']:.0f} | {fl} |",
                    flush=True,
                )
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump({"ss": a.ss, "frames": a.frames, "step_deg": a.step, "scale": a.scale, "orbit": a.orbit, "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The precision study of docs/precision.md: the paper's section 6 analysis
(Fig. 11, Fig. 12) on our own depth-24 scene, and its section 9 question,
whether half precision suffices for local-coordinate ray casting.

    python -m octopaint_ref.precision --out docs/precision

regenerates every figure (PNG) and writes the tables (results.md, and
results.json with the raw numbers) into --out. `--quick` runs a smaller
version (a minute) for checking that the command works.

Pseudo-random rays come from hashing an index (lowbias32, as
traces/generate.py), so every language can rebuild them.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np

from . import ray_error as RE
from .arith import FORMATS
from .camera import look_at, split_eye
from .dump import tree_arrays
from .jax_setup import configure
from .oracle import exact_path
from .paint import Painting
from .raycast import OVERFLOW, Ray, cast, device_tree, render, start_points
from .trace import Brush, Camera, Canvas, Sample

PRECISIONS = ("f16", "f32", "f64")
FRAMES = ("local", "world")
# The scene: the paper's canvas (4^3 roots, depth 24) with one root 1 unit wide.
CANVAS = Canvas(roots=(4, 4, 4), max_depth=24, root_size=1.0, capacity=1 << 24)
FOCUS = (1.6307371234567891, 2.2741693456789123, 1.9137571928374651)  # canvas units, not dyadic
# Paper figures (section 6.3), for the side-by-side table.
PAPER_MAX_ANGLE_DEG = 7.5e-9
PAPER_POSITION_ERROR = 2.5e-7
NEAR_CELLS = 64  # the depth sweep looks at the first cells of each ray,
FAR_EDGES = 16.0  # from this many edges of the eye's leaf on


# ------------------------------------------------------------- hashing
def hash32(x: np.ndarray) -> np.ndarray:
    """lowbias32 on uint32 arrays (traces/generate.py hash32)."""
    x = np.asarray(x, np.uint64) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(0x7FEB352D)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(0x846CA68B)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    return x


def uniform(stream: int, i) -> np.ndarray:
    """Uniform in [0, 1) from (stream, index), as traces/generate.py rnd."""
    i = np.asarray(i, np.uint64)
    return hash32(hash32(np.uint64(stream)) ^ ((i * np.uint64(0x9E3779B9)) & np.uint64(0xFFFFFFFF))).astype(np.float64) / 4294967296.0


def sphere_directions(n: int, stream: int = 11, first: int = 0) -> np.ndarray:
    """n unit vectors, uniform on the sphere, f64 [n, 3]: those of indices
    first .. first + n - 1, each from its index alone."""
    i = np.arange(first, first + n, dtype=np.uint64)
    z = 2.0 * uniform(stream, i) - 1.0
    phi = 2.0 * math.pi * uniform(stream + 1, i)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


# --------------------------------------------------------------- scene
def refine_towards(tree, point, depth: int) -> None:
    """Refine the leaf containing `point` until it has `depth` (2:1 balance
    grades the tree around it)."""
    while True:
        c = tree.leaf_at(point)
        if tree.depth[c] >= depth:
            return
        tree.refine_round(np.array([c], np.int64))


def sphere_layout(k: int):
    """Centre and radius of painted sphere k (k = 0 smallest): each 6 deg
    in angular radius seen from FOCUS, on a ring 17 deg off the -z axis."""
    r = 8e-7 * 10.0**k
    ang = 2 * math.pi * k / 6 + 0.3
    off = math.radians(17.0)
    u = np.array([math.sin(off) * math.cos(ang), math.sin(off) * math.sin(ang), -math.cos(off)])
    return np.asarray(FOCUS) + u * (r / math.sin(math.radians(6.0))), r


def build_scene(paint: bool = True, depth: int = 24) -> dict:
    """The test scene as dump arrays: six painted spheres whose radii span
    five decades (target depths 24 down to about 8), seen from FOCUS, and
    the tree refined to `depth` around FOCUS (the eye sits in a leaf of that
    depth). paint=False gives the graded tree alone with hashed leaf values
    (fast: the tests use it)."""
    painting = Painting(CANVAS)
    tree = painting.tree
    if paint:
        for k in range(6):
            c, r = sphere_layout(k)
            colour = (0.25 + 0.7 * uniform(21, 3 * k), 0.25 + 0.7 * uniform(21, 3 * k + 1), 0.25 + 0.7 * uniform(21, 3 * k + 2))
            painting.begin_stroke(Brush("sphere", "paint", float(r), tuple(float(v) for v in colour), 0.95, 0.3))
            painting.add_sample(Sample(tuple(float(v) for v in c)))
            painting.end_stroke()
    refine_towards(tree, FOCUS, depth)
    arrays = tree_arrays(tree)
    if not paint:
        n = len(arrays["parent"])
        i = np.arange(n)
        arrays["rgb"] = (uniform(31, i)[:, None] * np.array([255, 200, 150])).astype(np.uint8)
        arrays["sigma"] = np.where(uniform(32, i) < 0.5, 0.0, uniform(33, i) * 1e3).astype(np.float32)
        arrays["sigma"][arrays["depth"] == 255] = 0
    return arrays


def eye_split():
    return split_eye(FOCUS, CANVAS.root_size * 2.0**-CANVAS.max_depth)


def rays_from(eye_lattice, frac, dirs) -> Ray:
    n = len(dirs)
    return Ray(np.broadcast_to(eye_lattice, (n, 3)).copy(), np.broadcast_to(frac, (n, 3)).copy(), np.asarray(dirs, np.float64))


def near_camera(size=(256, 256), fov_deg=60.0) -> Camera:
    """From FOCUS (a depth-24 leaf) towards the ring of spheres."""
    h = math.radians(fov_deg) / 2
    return Camera(FOCUS, (0.0, 0.0, 0.0, 1.0), (-h, h, h, -h), size, (0.05, 0.05, 0.08))


def far_camera(size=(256, 256), fov_deg=8.0) -> Camera:
    """From outside the canvas, 6 units away: long rays, clipped at entry."""
    eye = np.asarray(FOCUS) + np.array([0.4, 0.3, 6.5])
    target = sphere_layout(5)[0]
    h = math.radians(fov_deg) / 2
    return Camera(tuple(eye), look_at(eye, target), (-h, h, h, -h), size, (0.05, 0.05, 0.08))


# --------------------------------------------------------- measurement
def offsets(frame: str, canvas, origin, depth, p, eye_lattice, frac):
    """Computed points (a cell's origin and depth and the local point p, or
    the world point p) minus the exact eye, (hi, lo) lattice units."""
    D = canvas.max_depth
    if frame == "local":
        return RE.offsets_local(origin, depth, p, eye_lattice, frac, D)
    return RE.offsets_world(p, eye_lattice, frac, canvas.root_size * 2.0**-D)


def start_error(tree, canvas, rays: Ray, precision: str, frame: str):
    """Each ray's computed start point against the exact eye: (w0 (hi, lo),
    e0 = |w0| in lattice units, the start cell's depth)."""
    _, _, d0, o0, p0 = start_points(tree, canvas, rays, precision, frame)
    w0 = offsets(frame, canvas, o0, d0, p0, rays.eye_lattice, rays.frac)
    return w0, np.sqrt(((w0[0] + w0[1]) ** 2).sum(axis=1)), d0


def measure(arrays, rays: Ray, precision: str, frame: str, capacity=512, tile=512, device=None, opaque=True):
    """Trace `rays` (eyes inside the canvas) and measure every exit point up
    to where the ray ends: where it becomes opaque (T < 1/256) or leaves the
    canvas; opaque=False ignores density (sigma 0: every ray runs to the
    canvas boundary). `device` must match `opaque`. Returns a dict of numpy
    arrays:
    per ray `final_angle`, `length` (lattice units), `e0` (lattice units),
    `e0_cells` (e0 in edges of the start cell), `steps`, `overflow`; per step
    (flattened) `angle`, `step_length`, `step_index`, `ray`; and the
    recorded cell sequences `cells` [R, K]."""
    if device is None:
        device = device_tree(arrays if opaque else {**arrays, "sigma": np.zeros_like(arrays["sigma"])})
    tree, canvas = device
    fmt = FORMATS[precision]
    s, rec = cast(tree, canvas, rays, precision, frame, max_steps=capacity, record=capacity, tile=tile)
    steps = s.steps
    D = canvas.max_depth
    n, K = rec.cell.shape
    valid = np.arange(K)[None, :] < steps[:, None]
    ray_idx = np.broadcast_to(np.arange(n)[:, None], (n, K))[valid]
    eye_l = rays.eye_lattice[ray_idx]
    frac = rays.frac[ray_idx]
    dirs = np.asarray(rays.dir_canvas)
    d_fmt = dirs.astype(fmt.numpy_dtype).astype(np.float64)
    w = offsets(frame, canvas, rec.origin[valid], rec.depth[valid], rec.p_exit[valid], eye_l, frac)
    ang, length = RE.angles(w, d_fmt[ray_idx])
    # The final point of each ray is its last recorded exit.
    last = np.cumsum(steps) - 1
    w0, e0, d0 = start_error(tree, canvas, rays, precision, frame)
    return {
        "final_angle": ang[last],
        "length": length[last],
        "e0": e0,
        "e0_cells": e0 / np.exp2(D - d0.astype(np.float64)),
        "start_depth": d0,
        "steps": steps,
        "overflow": s.status == OVERFLOW,
        "angle": ang,
        "step_length": length,
        "step_index": np.nonzero(valid)[1] + 1,
        "ray": ray_idx,
        "w": w,  # (hi, lo) [steps, 3]: exit points minus the eye, lattice units
        "w0": w0,  # (hi, lo) [rays, 3]: computed start points minus the eye
        "edge": np.exp2(D - rec.depth[valid].astype(np.float64)),  # edge of the cell exited
        "cells": np.where(valid, rec.cell.astype(np.int64), -1),
        "eps": fmt.eps,
    }


def fig11_choices(arrays, rays: Ray, m: dict) -> list[dict]:
    """The paper's Fig. 11 figure (7.5e-9 degrees, f32, local, depth 24)
    under several measurement choices, on the f32 local measurement `m` of
    `rays`: which point of a ray counts, what the angle is measured from
    and against, which statistic over the rays, and in which unit. Each row:
    `key`, `choice` (in words), `rad` (the statistic in radians; NaN where
    no point qualifies)."""
    dirs = np.asarray(rays.dir_canvas, np.float64)
    d_fmt = dirs.astype(np.float32).astype(np.float64)
    last = np.cumsum(m["steps"]) - 1
    w_last = (m["w"][0][last], m["w"][1][last])
    final = m["final_angle"]
    exact_dir, _ = RE.angles(w_last, dirs)
    rel = [RE.dd_sum([w_last[0][:, a], -m["w0"][0][:, a], w_last[1][:, a], -m["w0"][1][:, a]]) for a in range(3)]
    from_start, _ = RE.angles((np.stack([r[0] for r in rel], 1), np.stack([r[1] for r in rel], 1)), d_fmt)
    # The exit point of the first painted cell each ray crosses: where it
    # meets the paint, in cells from depth 24 up (one sphere per scale).
    cells = m["cells"][m["cells"] >= 0]
    painted = np.nonzero(arrays["sigma"][cells] > 0)[0]
    _, first = np.unique(m["ray"][painted], return_index=True)
    at_paint = m["angle"][painted[first]]
    fine = m["angle"][m["edge"] / m["step_length"] <= 1.0 / 64]
    top = lambda x: float(x.max()) if x.size else float("nan")
    return [
        {"key": "ours", "choice": "ours: max over rays of the final exit point, from the exact eye, against the f32 direction", "rad": float(final.max())},
        {"key": "exact_direction", "choice": "the same against the exact (unrounded) pixel direction", "rad": float(exact_dir.max())},
        {"key": "from_start", "choice": "the same from the computed start point (without e0)", "rad": float(from_start.max())},
        {"key": "at_paint", "choice": f"max at the point where each ray meets paint ({len(first)} rays)", "rad": top(at_paint)},
        {"key": "fine_cells", "choice": f"max over exit points in cells at least 64 times smaller than their distance ({fine.size} points)", "rad": top(fine)},
        {"key": "median", "choice": "median over rays of the final exit point", "rad": float(np.median(final))},
        {"key": "mean", "choice": "mean over rays of the final exit point", "rad": float(final.mean())},
    ]


def within_bound(m: dict) -> np.ndarray:
    """Per ray: the final angle error is within asin(e0/L + 5 eps)."""
    return m["final_angle"] <= RE.bound(m["e0"], m["length"], m["eps"])


def exact_offsets(points, eye_lattice, frac):
    """Exact points (mpf triples, lattice coordinates) minus the exact eye
    (eye_lattice + frac), as (hi, lo) f64 [n, 3] for ray_error."""
    import mpmath

    with mpmath.workdps(60):
        eye = [mpmath.mpf(int(eye_lattice[a])) + mpmath.mpf(float(frac[a])) for a in range(3)]
        rel = [[x[a] - eye[a] for a in range(3)] for x in points]
        hi = np.array([[float(v) for v in r] for r in rel]).reshape(-1, 3)
        lo = np.array([[float(v - mpmath.mpf(float(v))) for v in r] for r in rel]).reshape(-1, 3)
    return hi, lo


def compare_exact(arrays, rays: Ray, m: dict, precision: str, which) -> dict:
    """Against the mpmath ray, over the ray indices `which`: how many rays
    cross a different cell sequence, and for the others the largest
    distance between a computed exit point and the exact one, in edges of
    the cell exited (the local-frame position error). Exact paths run to
    the same length as the measured ones."""
    fmt = FORMATS[precision]
    first = np.concatenate([[0], np.cumsum(m["steps"])[:-1]])
    bad, worst = 0, 0.0
    for i in which:
        d = np.asarray(rays.dir_canvas[i]).astype(fmt.numpy_dtype).astype(np.float64)
        k = int(m["steps"][i])
        ex = exact_path(arrays, rays.eye_lattice[i], rays.frac[i], d, max_steps=k)
        got = [int(c) for c in m["cells"][i][:k]]
        if got != ex.cells:
            bad += 1
            continue
        hi, lo = exact_offsets(ex.exit, rays.eye_lattice[i], rays.frac[i])
        sl = slice(first[i], first[i] + k)
        err = RE.position_error((m["w"][0][sl], m["w"][1][sl]), (hi, lo)) / m["edge"][sl]
        worst = max(worst, float(err.max()))
    return {"differs": bad, "compared": len(which), "max_position_error_edges": worst}


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10.0 * math.log10(255.0**2 / mse)


def image_difference(img: np.ndarray, ref: np.ndarray) -> dict:
    diff = np.abs(img.astype(np.int64) - ref.astype(np.int64)).max(axis=-1)
    return {
        "psnr_db": psnr(img, ref),
        "pct_over_2_steps": 100.0 * float((diff > 2).mean()),
        "pct_any": 100.0 * float((diff > 0).mean()),
        "max_steps_off": int(diff.max()),
    }


# --------------------------------------------------------------- study
def run_study(out: str, quick: bool = False) -> dict:
    from . import precision_plots as P

    t0 = time.perf_counter()
    os.makedirs(out, exist_ok=True)
    log = lambda *a: print(f"[{time.perf_counter() - t0:6.1f} s]", *a, file=sys.stderr, flush=True)
    arrays = build_scene(paint=True)
    log(f"scene: {int((arrays['depth'] != 255).sum())} cells, depth {int(arrays['depth'][arrays['depth'] != 255].max())}")
    results: dict = {"cells": int((arrays["depth"] != 255).sum())}
    E, phi = eye_split()

    # Fig. 11/12: per-pixel angle error from a camera in a depth-24 leaf.
    side = 64 if quick else 160
    cam = near_camera((side, side))
    from .camera import pixel_directions

    dirs = pixel_directions(cam).reshape(-1, 3)
    rays = rays_from(E, phi, dirs)
    dev = device_tree(arrays)
    per = {}
    for frame in FRAMES:
        for prec in PRECISIONS:
            m = measure(arrays, rays, prec, frame, device=dev)
            per[(prec, frame)] = m
            ok = within_bound(m)
            results[f"{prec}_{frame}"] = {
                "max_angle_rad": float(m["final_angle"].max()),
                "max_angle_deg": float(np.degrees(m["final_angle"].max())),
                "median_angle_rad": float(np.median(m["final_angle"])),
                "max_step_angle_rad": float(m["angle"].max()),
                "max_e0_cells": float(m["e0_cells"].max()),
                "rays_within_bound_pct": 100.0 * float(ok.mean()),
                "max_cells_crossed": int(m["steps"].max()),
                "rays_at_step_cap": int(m["overflow"].sum()),
            }
            log(prec, frame, results[f"{prec}_{frame}"])
    # The direction itself, rounded to the format, turns each ray by this
    # much before any traversal error (not part of the angle error above).
    for prec in PRECISIONS:
        d_fmt = dirs.astype(FORMATS[prec].numpy_dtype).astype(np.float64)
        w = (d_fmt, np.zeros_like(d_fmt))
        results[f"{prec}_local"]["direction_rounding_rad"] = float(RE.angles(w, dirs)[0].max())
    results["fig11_choices"] = fig11_choices(arrays, rays, per[("f32", "local")])
    P.angle_images(per, side, os.path.join(out, "fig11_angle_error_images.png"))
    P.error_vs_length(per, os.path.join(out, "fig11_error_vs_length.png"))
    P.error_vs_cells(per, os.path.join(out, "fig11_error_vs_cells.png"))

    # Exact cell sequences (mpmath) for a subset of the rays.
    n_exact = 40 if quick else 300
    which = np.unique(np.linspace(0, len(dirs) - 1, n_exact).astype(np.int64))
    for frame in FRAMES:
        for prec in PRECISIONS:
            c = compare_exact(arrays, rays, per[(prec, frame)], prec, which)
            results[f"{prec}_{frame}"]["sequence_differs_pct"] = 100.0 * c["differs"] / c["compared"]
            results[f"{prec}_{frame}"]["sequence_rays_compared"] = c["compared"]
            results[f"{prec}_{frame}"]["max_position_error_edges"] = c["max_position_error_edges"]
            log(prec, frame, c)

    # Where the frames break: the eye in a leaf of each depth, random
    # directions, the first NEAR_CELLS cells of every ray (where the paper's
    # e0/L term lives and where world coordinates fail first).
    depths = [4, 8, 12, 16, 20, 24] if not quick else [8, 16, 24]
    n_dirs = 128 if quick else 512
    sweep = {}
    rnd_dirs = sphere_directions(n_dirs)
    for depth in depths:
        tree_d = build_scene(paint=False, depth=depth)
        dev_d = device_tree({**tree_d, "sigma": np.zeros_like(tree_d["sigma"])})
        rays_d = rays_from(E, phi, rnd_dirs)
        ms = {(p, f): measure(tree_d, rays_d, p, f, device=dev_d, opaque=False) for f in FRAMES for p in PRECISIONS}
        ref_cells = ms[("f64", "local")]["cells"][:, :NEAR_CELLS]
        row = {}
        edge = 2.0 ** (CANVAS.max_depth - depth)
        for (prec, frame), m in ms.items():
            # Past FAR_EDGES edges of the eye's leaf the e0/L term is small.
            near = (m["step_index"] <= NEAR_CELLS) & (m["step_length"] >= FAR_EDGES * edge)
            row[f"{prec}_{frame}"] = {
                "max_angle_rad": float(m["angle"][near].max()),
                "max_final_angle_rad": float(m["final_angle"].max()),
                "sequence_differs_pct": 100.0 * float(np.any(m["cells"][:, :NEAR_CELLS] != ref_cells, axis=1).mean()),
                "within_bound_pct": 100.0 * float(within_bound(m).mean()),
            }
        sweep[depth] = row
        log("depth", depth, {k: f"{v['max_angle_rad']:.2e}" for k, v in row.items()})
    results["depth_sweep"] = sweep
    P.depth_sweep(sweep, os.path.join(out, "f16_depth_sweep.png"))

    # Section 9: half precision images against f64, near and far cameras.
    images = {}
    sizes = [(128, 128)] if quick else [(256, 256), (512, 512), (1024, 1024)]
    dev_img = device_tree(arrays)
    for name, make in (("near", near_camera), ("far", far_camera)):
        for size in sizes if name == "near" else sizes[:1]:
            camera = make(size)
            ref = render(arrays, camera, "f64", "local", device=dev_img)
            row = {}
            shots = {"f64_local": ref.image}
            for prec, frame in (("f32", "local"), ("f16", "local"), ("f64", "world"), ("f32", "world"), ("f16", "world")):
                r = render(arrays, camera, prec, frame, device=dev_img)
                row[f"{prec}_{frame}"] = image_difference(r.image, ref.image)
                shots[f"{prec}_{frame}"] = r.image
            key = f"{name}_{size[0]}"
            images[key] = row
            log("image", key, {k: (round(v["psnr_db"], 1), round(v["pct_over_2_steps"], 3)) for k, v in row.items()})
            if size == sizes[0]:
                P.image_grid(shots, os.path.join(out, f"images_{name}.png"))
    results["images"] = images

    # Compositing in low precision (composite_precision.py): the segments
    # the f64 caster composites for the near camera's rays, and adversarial
    # media, in f16, bf16 and f32 under each formulation, against mpmath.
    from . import composite_precision as CP

    side_c = 32 if quick else 64
    rays_c = rays_from(E, phi, pixel_directions(near_camera((side_c, side_c))).reshape(-1, 3))
    media = {"scene": CP.scene_segments(arrays, rays_c), **CP.adversarial_media()}
    comp = CP.study(media)
    results["compositing"] = {"|".join(k): v for k, v in comp.items()}
    P.compositing_errors(comp, os.path.join(out, "compositing_errors.png"))
    log("compositing", {k: round(v["max_colour_steps"], 3) for k, v in results["compositing"].items() if k.startswith("scene")})
    # At scale (precision_scale.py, in this process on its devices): many
    # more rays than the camera's, summarised exactly per shard.
    from . import precision_scale as PS

    n_scale = 16384 if quick else 262144
    scale = {}
    for prec in PRECISIONS:
        tracer = PS.Tracer(prec, "local", CANVAS.max_depth, 512)
        total = PS.empty_summary()
        for first in range(0, n_scale, 4096):
            total = PS.merge(total, tracer.shard(first, min(4096, n_scale - first)))
        scale[prec] = {**total, "eps": tracer.eps}
        log("at scale", prec, {k: total[k] for k in ("rays", "within", "max_angle", "argmax")})
    results["at_scale"] = scale
    P.angle_histograms(scale, PS.BIN_EDGES, os.path.join(out, "angle_histograms.png"))
    results["seconds"] = time.perf_counter() - t0
    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump(results, f, indent=1, sort_keys=True)
    with open(os.path.join(out, "results.md"), "w") as f:
        f.write(tables(results))
    log("done")
    return results


def tables(r: dict) -> str:
    """The Markdown tables docs/precision.md quotes."""
    lines = ["<!-- generated by python -m octopaint_ref.precision; do not edit -->", ""]
    lines += [
        "| frame | precision | eps | max angle error (rad) | max (deg) | median (rad) | max e0 (start-cell edges) | rays within bound | cell sequence differs | max exit point error (cell edges) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for frame in FRAMES:
        for prec in PRECISIONS:
            v = r[f"{prec}_{frame}"]
            lines.append(
                f"| {frame} | {prec} | {FORMATS[prec].eps:.3g} | {v['max_angle_rad']:.3g} | {v['max_angle_deg']:.3g} | "
                f"{v['median_angle_rad']:.3g} | {v['max_e0_cells']:.3g} | {v['rays_within_bound_pct']:.1f}% | "
                f"{v['sequence_differs_pct']:.1f}% of {v['sequence_rays_compared']} | "
                + (f"{v['max_position_error_edges']:.3g} |" if v["sequence_differs_pct"] < 100 else "- |")
            )
    lines += ["", "Rounding the unit direction to the format turns a ray by at most: "
              + ", ".join(f"{p} {r[f'{p}_local']['direction_rounding_rad']:.2g} rad" for p in PRECISIONS) + "."]
    lines += ["", "Paper (f32, local, depth 24): max angle error 7.5e-9 deg, position error 2.5e-7. "
              f"Ours (f32, local): max angle error {r['f32_local']['max_angle_deg']:.3g} deg, "
              f"max start error {r['f32_local']['max_e0_cells']:.3g} cell edges.", ""]
    lines += ["The paper's figure under other measurement choices (f32, local; the paper's 7.5e-9 is "
              f"{math.radians(PAPER_MAX_ANGLE_DEG):.2g} rad if degrees):", "",
              "| choice | rad | deg | rad / 7.5e-9 | deg / 7.5e-9 |", "| --- | --- | --- | --- | --- |"]
    for c in r["fig11_choices"]:
        rad, dg = c["rad"], math.degrees(c["rad"])
        lines.append(f"| {c['choice']} | {rad:.3g} | {dg:.3g} | {rad / PAPER_MAX_ANGLE_DEG:.2f} | {dg / PAPER_MAX_ANGLE_DEG:.0f} |")
    lines.append("")
    sweep = r["depth_sweep"]
    keys = [f"{p}_{f}" for f in FRAMES for p in PRECISIONS]
    lines += [f"By the depth of the eye's leaf, random directions, first {NEAR_CELLS} cells of each ray: max angle error (rad) at exit points at least {FAR_EDGES:g} eye-leaf edges from the eye / % rays whose first {NEAR_CELLS} cells differ from f64 local:", ""]
    lines += ["| eye depth | " + " | ".join(keys) + " |", "| --- |" + " --- |" * len(keys)]
    for depth, row in sweep.items():
        lines.append(f"| {depth} | " + " | ".join(f"{row[k]['max_angle_rad']:.2g} / {row[k]['sequence_differs_pct']:.0f}%" for k in keys) + " |")
    lines += ["", "Images against the f64 local render (PSNR dB / % pixels off by more than 2 steps):", ""]
    cols = ["f32_local", "f16_local", "f64_world", "f32_world", "f16_world"]
    lines += ["| camera | " + " | ".join(cols) + " |", "| --- |" + " --- |" * len(cols)]
    for key, row in r["images"].items():
        lines.append(f"| {key} | " + " | ".join(f"{row[c]['psnr_db']:.1f} / {row[c]['pct_over_2_steps']:.3f}%" for c in cols) + " |")
    if "at_scale" in r:
        lines += ["", "At scale (octopaint-ref precision's shards, local frame, eye in a depth-24 leaf, rays to the canvas boundary):", "",
                  "| precision | rays | within the bound | max angle error (rad) | its ray |", "| --- | --- | --- | --- | --- |"]
        for prec, v in r["at_scale"].items():
            lines.append(f"| {prec} | {v['rays']:,} | {100.0 * v['within'] / v['rays']:.4f}% | {v['max_angle']:.3g} | {v['argmax']} |")
    if "compositing" in r:
        from .composite_precision import table as composite_table

        comp = {tuple(k.split("|")): v for k, v in r["compositing"].items()}
        lines += ["", "Compositing in low precision against mpmath (max colour error in 8-bit steps / max transmittance "
                  "error / % rays within the transmittance bound):", "", composite_table(comp)]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(prog="python -m octopaint_ref.precision", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs/precision", help="folder for the figures and tables")
    ap.add_argument("--quick", action="store_true", help="a small run (about a minute)")
    args = ap.parse_args(argv)
    run_study(args.out, args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Differential fuzzing: random small traces replayed by both implementations.

The traces in traces/ are written by hand, each for a feature; the
combinations they leave out are where the two implementations can drift
apart unseen (a mirrored hard sphere once refined leaves the reference
settles, spec 8.7, and no trace had one). This script writes random valid
traces from a seed (every shape, mode and brush parameter, mirror copies,
pressure, samples close together and far apart, a small cell budget now and
then, undo and redo, layers in version-2 traces, voxel-set imports, deep
and shallow canvases, small images), replays each with the reference and
the painter through the driver's `check_trace`, and reports every seed
whose dumps, images or warnings differ, with its trace kept for replay:

    .venv/bin/python conformance/fuzz.py --painter painter/target/release/octopaint \\
        --seeds 200 --out /tmp/fuzz

Traces are small (a few thousand to about a million cells), so that the
reference replays most in one to three seconds. The same seed gives the same
trace on any machine: `random.Random(seed)` and nothing else.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import math
import os
import random
import shutil
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)

import driver  # noqa: E402

_spec = importlib.util.spec_from_file_location("trace_generate", os.path.join(REPO, "traces", "generate.py"))
gen = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gen)

SHAPES = ("sphere", "sphere", "sphere", "box", "cylinder", "cone", "noise")
MODES = ("paint", "paint", "erase", "recolor", "mix", "pickup")
HARDNESS = (0.0, 0.3, 0.55, 0.8, 1.0)


def _unit_quat(rng: random.Random) -> list[float]:
    axis = [rng.uniform(-1.0, 1.0) for _ in range(3)]
    if sum(a * a for a in axis) < 1e-6:
        axis = [0.0, 0.0, 1.0]
    return gen.axis_quat(axis, rng.uniform(0.0, 2.0 * math.pi))


def _brush(w, rng: random.Random, extent: float, cell: float) -> tuple[str, float]:
    shape = rng.choice(SHAPES)
    mode = rng.choice(MODES)
    # From two finest cells to 40% of the canvas: the target depth (cells
    # of r/10, spec 8.7) bounds the cells a sample makes either way.
    lo, hi = math.log2(2.0 * cell), math.log2(0.4 * extent)
    radius = 2.0 ** rng.uniform(lo, max(lo, hi))
    extra: dict = {}
    if shape != "sphere":
        extra["spacing"] = rng.choice((0.2, 0.35, 0.5, 1.0))
    if shape in ("box", "cylinder", "cone"):
        extra["aspect"] = [gen.r6(rng.uniform(0.4, 1.5)) for _ in range(3)]
    if shape == "noise":
        extra["noise"] = {"frequency": gen.r6(rng.uniform(0.5, 4.0)), "octaves": rng.randint(1, 4), "seed": rng.randint(0, 99), "gain": gen.r6(rng.uniform(0.2, 0.8))}
    if mode == "mix":
        extra["mix_ratio"] = gen.r6(rng.uniform(0.1, 1.0))
    if mode == "pickup":
        extra["pickup_rate"] = gen.r6(rng.uniform(0.05, 0.6))
    colour = [rng.random() for _ in range(3)]
    w.brush(shape, mode, radius, colour, opacity=rng.uniform(0.05, 1.0), hardness=rng.choice(HARDNESS), **extra)
    return shape, radius


def _stroke(w, rng: random.Random, shape: str, radius: float, size: list[float]) -> None:
    n = rng.randint(1, 9)
    step = radius * rng.choice((0.05, 0.25, 0.5, 1.0, 1.6))
    # Mostly inside the canvas; now and then starting near or past an edge.
    margin = 0.3 * radius if rng.random() < 0.8 else -0.5 * radius
    p = [rng.uniform(min(margin, size[k] / 2), max(size[k] - margin, size[k] / 2)) for k in range(3)]
    heading = [rng.uniform(-1.0, 1.0) for _ in range(3)]
    points = []
    for _ in range(n):
        points.append(list(p))
        heading = [h + rng.uniform(-0.5, 0.5) for h in heading]
        norm = math.sqrt(sum(h * h for h in heading)) or 1.0
        p = [p[k] + step * heading[k] / norm for k in range(3)]
    pressures = [rng.uniform(0.05, 1.0) for _ in range(n)] if rng.random() < 0.7 else None
    quats = [_unit_quat(rng) for _ in range(n)] if shape != "sphere" or rng.random() < 0.2 else None
    w.stroke(points, pressures, quats)


def random_trace(seed: int) -> str:
    """A valid trace (docs/TRACE-FORMAT.md) drawn from `seed` alone."""
    return random_trace_and_files(seed)[0]


def random_trace_and_files(seed: int) -> tuple[str, dict[str, bytes]]:
    """A valid trace drawn from `seed` alone, and the voxel sets its
    imports read (paths relative to the trace's folder)."""
    rng = random.Random(seed)
    files: dict[str, bytes] = {}
    version = 2 if rng.random() < 0.3 else 1
    shape = rng.random()
    if shape < 0.15:
        # Deep: finest cells from 2^-16 to 2^-28 of a root, and one axis
        # perhaps with the most roots it may have (R·2^D = 2^32, spec
        # 12.2's limit), so lattice coordinates reach 2^32.
        max_depth = rng.randint(16, 28)
        roots = [1, 1, 1]
        if rng.random() < 0.4:
            roots[rng.randrange(3)] = 1 << (32 - max_depth)
        root_size = rng.choice((1e4, 1e-3, 3.7, 1e9))
    elif shape < 0.25:
        # Shallow: a root that never refines (depth 0) up to depth 3.
        max_depth = rng.randint(0, 3)
        roots = [rng.randint(1, 4) for _ in range(3)]
        root_size = rng.choice((1.0, 0.25, 5.0))
    else:
        roots = [rng.choice((1, 1, 2)) for _ in range(3)]
        max_depth = rng.randint(4, 8)
        root_size = rng.choice((1.0, 0.5, 2.0, 0.3, 7.0))
    n_roots = roots[0] * roots[1] * roots[2]
    capacity = max(rng.choice((1 << 21, 1 << 21, 1 << 21, 20000, 4000)), 2 * n_roots)
    w = gen.Writer({"roots": roots, "max_depth": max_depth, "root_size": root_size, "capacity": capacity}, f"fuzz seed {seed}", version)
    size = [r * root_size for r in roots]
    extent = min(size)
    cell = root_size / 2**max_depth
    layers = ["Layer 1"]
    snapshots = 0
    for _ in range(rng.randint(1, 7)):
        if version == 2 and rng.random() < 0.35:
            _layer_op(w, rng, layers)
        if rng.random() < 0.12:
            _import(w, rng, files, f"fuzz_{seed}_{len(files)}.npz", roots, root_size, max_depth)
        if rng.random() < 0.25:
            dyadic = rng.random() < 0.5
            centre = [gen.r6(size[k] * (rng.randint(1, 3) / 4 if dyadic else rng.uniform(0.2, 0.8))) for k in range(3)]
            w.ev("mirror", 0.1, axes=[rng.random() < 0.5 for _ in range(3)], centre=centre)
        shape, radius = _brush(w, rng, extent, cell)
        for _ in range(rng.randint(1, 2)):
            _stroke(w, rng, shape, radius, size)
        if rng.random() < 0.15:
            w.ev("undo", 0.1)
            if rng.random() < 0.5:
                w.ev("redo", 0.1)
        if rng.random() < 0.15:
            snapshots += 1
            w.ev("snapshot", 0.1, name=f"fuzz_{seed}_{snapshots}")
    if rng.random() < 0.5:
        _renders(w, rng, seed, size)
    w.ev("snapshot", 0.1, name=f"fuzz_{seed}")
    return w.text(), files


def _renders(w, rng: random.Random, seed: int, size: list[float]) -> None:
    """Small images of the canvas (spec 6): from outside it or from inside,
    towards its middle or a random point, unlit and then perhaps lit."""
    mid = [s / 2 for s in size]
    if rng.random() < 0.25:
        eye = [rng.uniform(0.1, 0.9) * s for s in size]
    else:
        d = [rng.uniform(-1.0, 1.0) for _ in range(3)]
        n = math.sqrt(sum(v * v for v in d)) or 1.0
        reach = max(size) * rng.uniform(0.9, 2.0)
        eye = [mid[k] + reach * d[k] / n for k in range(3)]
    target = mid if rng.random() < 0.6 else [rng.uniform(0.0, 1.0) * s for s in size]
    if sum((eye[k] - target[k]) ** 2 for k in range(3)) < 1e-6:
        target = [target[0] + 0.1 * size[0], target[1], target[2]]
    w.camera(eye, target, size=(64, 48), fov_deg=rng.uniform(20.0, 80.0))
    w.ev("render", 0.1, name=f"fuzz_{seed}_unlit")
    if rng.random() < 0.5:
        light = [rng.uniform(-1.0, 1.0) for _ in range(3)]
        if max(abs(v) for v in light) < 0.05:
            light = [0.0, 1.0, 0.0]
        w.ev("light", 0.1, dir=[gen.r6(v) for v in light], intensity=gen.r6(rng.uniform(0.3, 1.5)),
             ambient=gen.r6(rng.uniform(0.0, 0.5)), shadows=rng.random() < 0.7)
        w.ev("render", 0.1, name=f"fuzz_{seed}_lit")


def _import(w, rng: random.Random, files: dict, name: str, roots: list, root_size: float, max_depth: int) -> None:
    """An import event (spec 15) of a ball of voxels inside the canvas at a
    random depth: one colour (blocks that settle), a gradient (refined to
    the set's depth) or sigma 0 (it erases)."""
    depth = rng.randint(max(0, max_depth - 4), max_depth)
    n = [r << depth for r in roots]  # voxels a side of the canvas
    h = root_size / (1 << depth)
    radius = h * rng.uniform(1.0, min(6.0, min(n) / 2))
    centre = [h * rng.uniform(radius / h, n[k] - radius / h) for k in range(3)]
    kind = rng.choice(("flat", "gradient", "gradient", "erase"))
    rgb = [rng.randrange(256) for _ in range(3)]
    sigma = gen.r6(rng.uniform(0.5, 60.0))

    def colour(i, j, k):
        if kind == "flat":
            return (*rgb, sigma)
        if kind == "erase":
            return (0, 0, 0, 0.0)
        return ((rgb[0] + 9 * i) % 256, (rgb[1] + 13 * j) % 256, (rgb[2] + 5 * k) % 256, float(1 + (i + j + k) % 7))

    voxels = [v for v in gen.ball_voxels(depth, centre, radius, root_size, colour) if all(v[a] < n[a] for a in range(3))]
    data = gen.voxel_set(depth, voxels)
    files[name] = data
    w.ev("import", 0.1, file=name, sha256=hashlib.sha256(data).hexdigest())


def _layer_op(w, rng: random.Random, layers: list[str]) -> None:
    """One valid layer event (spec 14): the names stay unique, a merge has
    a layer below it, the last layer is never deleted. No layer is locked,
    so painting and merging stay allowed."""
    op = rng.choice(("add", "add", "select", "set", "duplicate", "merge_down", "move", "delete"))
    name = f"L{len(layers) + 1}x{rng.randint(0, 999)}"
    while name in layers:
        name += "'"
    pick = rng.choice(layers)
    if op == "add" and len(layers) < 6:
        w.ev("layer", 0.1, op="add", name=name)
        layers.append(name)
    elif op == "duplicate" and len(layers) < 6:
        w.ev("layer", 0.1, op="duplicate", layer=pick, name=name)
        layers.insert(layers.index(pick) + 1, name)
    elif op == "merge_down" and layers.index(pick) > 0:
        w.ev("layer", 0.1, op="merge_down", layer=pick)
        layers.remove(pick)
    elif op == "move" and len(layers) > 1:
        to = rng.randrange(len(layers))
        w.ev("layer", 0.1, op="move", layer=pick, to=to)
        layers.remove(pick)
        layers.insert(to, pick)
    elif op == "delete" and len(layers) > 1:
        w.ev("layer", 0.1, op="delete", layer=pick)
        layers.remove(pick)
    elif op == "set":
        w.ev("layer", 0.1, op="set", layer=pick, opacity=gen.r6(rng.uniform(0.0, 1.0)), visible=rng.random() < 0.8)
    else:
        w.ev("layer", 0.1, op="select", layer=pick)


def fuzz(painter: str, seeds: range, out: str, budget_s: float | None = None, log=print) -> list[int]:
    """Replay the traces of `seeds` with both implementations; returns the
    seeds that differ (their traces and report paragraphs stay in `out`)."""
    work = os.path.join(out, "work")
    os.makedirs(work, exist_ok=True)
    bad = []
    t0 = time.perf_counter()
    for seed in seeds:
        if budget_s is not None and time.perf_counter() - t0 > budget_s:
            log(f"time budget of {budget_s:.0f} s spent after seed {seed - 1}")
            break
        trace = os.path.join(out, f"fuzz_{seed}.jsonl")
        text, files = random_trace_and_files(seed)
        with open(trace, "w") as f:
            f.write(text)
        for path, data in files.items():
            with open(os.path.join(out, path), "wb") as f:
                f.write(data)
        # Images on the painter's GPU renderer (the one that ships).
        r = driver.check_trace(trace, painter, work, out, require_images=True)
        shutil.rmtree(os.path.join(work, f"fuzz_{seed}"), ignore_errors=True)
        if r.problems:
            bad.append(seed)
            with open(os.path.join(out, f"fuzz_{seed}.md"), "w") as f:
                f.write("\n\n".join(r.problems) + "\n")
            log(f"seed {seed}: DIFFERS ({r.cells} cells; trace {trace})")
        else:
            os.remove(trace)
            for path in files:
                os.remove(os.path.join(out, path))
            log(f"seed {seed}: same ({r.dumps} dumps, {r.cells} cells, reference {r.ref_seconds:.1f} s, painter {r.painter_seconds:.1f} s)")
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--painter", required=True, help="the painter binary (octopaint)")
    ap.add_argument("--seeds", type=int, default=100, help="how many seeds")
    ap.add_argument("--first", type=int, default=0, help="the first seed")
    ap.add_argument("--out", required=True, help="folder for the differing traces and their reports")
    ap.add_argument("--budget", type=float, default=None, help="stop starting seeds after this many seconds")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    bad = fuzz(args.painter, range(args.first, args.first + args.seeds), args.out, args.budget)
    print(f"{len(bad)} seed(s) differ: {bad}" if bad else "every seed the same")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

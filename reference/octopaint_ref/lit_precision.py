"""Is f16 traversal still enough with lighting? (docs/precision.md, "With
lighting")

    python -m octopaint_ref.cli lit-precision --out docs/precision

Replays traces/lit.jsonl and traces/scene.jsonl and, at every render event
that is lit, draws the view with the traversal in f16, f32 and f64 (local
frame; compositing f64 as always) and the same view unlit, then compares
each with the f64 picture of its kind, at each level of detail `--lod`
(spec 7; every precision against f64 at the same k): PSNR and the share of
pixels off by more than 2 steps (spec 13's f16 tolerance is 99.9% within 2 steps and
45 dB). Lighting reads no position: a cell's normal comes from stored sigma
values, so the traversal's rounding reaches a lit picture through the same
segment lengths and cells as an unlit one, plus the shadow ray's start point
and path. The table says whether that shows. Results: lit_precision.md and
.json in --out.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

from .dump import tree_arrays
from .jax_setup import configure
from .lod import check_k
from .lod_study import each_render, scaled
from .precision import psnr
from .raycast import device_tree, render

TRACES = os.path.join(os.path.dirname(__file__), "..", "..", "traces")


def _stats(img: np.ndarray, ref: np.ndarray) -> dict:
    d = np.abs(img.astype(int) - ref.astype(int)).max(axis=-1)
    return {"psnr_db": psnr(img, ref), "over_2_steps_pct": float((d > 2).mean() * 100), "max_steps": int(d.max())}


def _view_rows(name, render_name, arrays, dev, cam, light, lods, precisions) -> list[dict]:
    """The rows of one lit render event seen by `cam`: per k and precision,
    the lit and the unlit view against f64 at the same k."""
    rows = []
    views = (("lit", light), ("unlit", None))
    for k in lods:
        ref = {kind: render(arrays, cam, "f64", device=dev, light=lt, lod=k).image for kind, lt in views}
        for prec in precisions:
            row = {"trace": name, "render": render_name, "size": list(cam.size), "shadows": light.shadows, "lod": k, "precision": prec}
            for kind, lt in views:
                row[kind] = _stats(render(arrays, cam, prec, device=dev, light=lt, lod=k).image, ref[kind])
            rows.append(row)
            print(json.dumps(row), file=sys.stderr)
    return rows


def study(traces=("lit.jsonl", "scene.jsonl"), precisions=("f16", "f32"), lods=(0.0,), divs=(1,)) -> list[dict]:
    """Rows of the study: per lit render event, camera size (1/div of the
    trace's, lod_study.scaled: with smaller pixels the cut engages), level
    of detail k (spec 7; each precision against f64 at the same k) and
    precision."""
    rows = []
    for name in traces:

        def after(render_name, painting, cam, light, name=name):
            if light is None or not light.on:
                return
            arrays = tree_arrays(painting.tree)
            dev = device_tree(arrays)
            for div in divs:
                rows.extend(_view_rows(name, render_name, arrays, dev, scaled(cam, div), light, lods, precisions))

        each_render(os.path.join(TRACES, name), after)
    return rows


def table(rows: list[dict]) -> str:
    def cell(s):
        db = "identical" if s["psnr_db"] == float("inf") else f"{s['psnr_db']:.1f} dB"
        return f"{db}, {s['over_2_steps_pct']:.3f}% > 2 steps (max {s['max_steps']})"

    out = ["| render | size | shadows | k | traversal | lit vs f64 lit | unlit vs f64 unlit |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        size = "×".join(str(v) for v in r["size"])
        out.append(
            f"| {r['trace']}: {r['render']} | {size} | {'yes' if r['shadows'] else 'no'} | {r['lod']:g} | {r['precision']} | {cell(r['lit'])} | {cell(r['unlit'])} |"
        )
    return "\n".join(out) + "\n"


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--out", required=True, help="folder for lit_precision.md and .json")
    ap.add_argument("--lod", default="0,1", help="levels of detail k, comma-separated (spec 7; 0: full depth)")
    ap.add_argument("--scale", default="1", help="divide every camera's size by each of these, comma-separated (fov kept; default 1)")


def command(a) -> int:
    try:
        lods = tuple(check_k(v) for v in a.lod.split(","))
    except ValueError as e:
        raise SystemExit(f"--lod: {e}") from None
    divs = tuple(int(v) for v in a.scale.split(","))
    if not all(d >= 1 for d in divs):
        raise SystemExit(f"--scale: every divisor must be at least 1, got {a.scale}")
    rows = study(lods=lods, divs=divs)
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "lit_precision.json"), "w") as f:
        json.dump(rows, f, indent=1, default=float)
    text = table(rows)
    with open(os.path.join(a.out, "lit_precision.md"), "w") as f:
        f.write(f"# Traversal precision with lighting\n\n`python -m octopaint_ref.cli lit-precision --out docs/precision --lod {a.lod} --scale {a.scale}` (docs/precision.md, \"With lighting\" and \"With prefiltered cells and a level of detail\"; make precision).\n\n" + text)
    print(text)
    return 0


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(prog="octopaint-ref lit-precision", description=__doc__.split("\n\n")[0])
    add_arguments(ap)
    return command(ap.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())

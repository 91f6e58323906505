"""Ray caster throughput on CPU: `python -m octopaint_ref.bench_raycast`.

Replays the scene trace (painting only), then renders every camera of the
trace at 256x256 in the local frame with f32 (the figure docs/benchmarks.md
quotes), f64 (the replay's oracle images) and f16, each twice: the first
call includes tracing and compiling, the second is the steady state the
rays/s column reports. f16 and f32 are emulated per operation in f64
(arith.py), so they cost more than native f64 here; on a GPU the ordering
reverses.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import numpy as np

from .dump import tree_arrays
from .jax_setup import configure
from .raycast import device_tree, render
from .replay import replay
from .trace import read_trace

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(prog="python -m octopaint_ref.bench_raycast", description=__doc__.split("\n\n")[0])
    ap.add_argument("--trace", default=os.path.join(REPO, "traces", "scene.jsonl"))
    ap.add_argument("--size", type=int, default=256, help="image width and height")
    ap.add_argument("--precisions", default="f32,f64,f16", help="any of f16, f32, f64 (emulated per operation; f64 native), f16-native, f32-native")
    ap.add_argument("--json", help="also write the rows (and JAX's devices) as JSON here")
    args = ap.parse_args(argv)
    trace = read_trace(args.trace)
    t0 = time.perf_counter()
    arrays = tree_arrays(replay(trace, None, renders=False).painting.tree)
    print(f"replayed {os.path.basename(args.trace)} in {time.perf_counter() - t0:.1f} s: {len(arrays['parent'])} cells", flush=True)
    dev = device_tree(arrays)
    cams = [(i, e.value) for i, e in enumerate(e for e in trace.events if e.kind == "camera")]
    import jax

    rows = []
    print(f"jax {jax.__version__} on {', '.join(str(d) for d in jax.devices())}", flush=True)
    print(f"{'camera':<8}{'precision':<11}{'first s':>9}{'second s':>10}{'rays/s':>12}{'cells/ray':>11}")
    for prec in args.precisions.split(","):
        for i, cam in cams:
            cam = dataclasses.replace(cam, size=(args.size, args.size))
            t = time.perf_counter()
            render(arrays, cam, prec, device=dev)
            first = time.perf_counter() - t
            t = time.perf_counter()
            r = render(arrays, cam, prec, device=dev)
            second = time.perf_counter() - t
            n = args.size * args.size
            print(f"{i:<8}{prec:<11}{first:>9.2f}{second:>10.2f}{n / second:>12.0f}{np.mean(r.steps):>11.1f}", flush=True)
            rows.append({"camera": i, "precision": prec, "size": args.size, "first_s": first, "second_s": second,
                         "rays_per_s": n / second, "cells_per_ray": float(np.mean(r.steps))})
    if args.json:
        import json

        with open(args.json, "w") as f:
            json.dump({"jax": jax.__version__, "devices": [str(d) for d in jax.devices()], "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

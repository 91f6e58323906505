"""Inverse painting: recover a stroke's colour, radius and sample positions
from renderings of a different stroke (differentiable stamping diffpaint.py
and ray casting diffrender.py, on a fixed topology).

    python reference/examples/inverse_paint.py [--iterations 150] [--out docs/examples]

The canvas is one root refined to depth 5 everywhere (32,768 leaves). The
target is a three-sample orange stroke; the fit starts from a thinner
blue stroke elsewhere and sees three 48x48 views. Prints the loss per
iteration and the recovered parameters, and writes
inverse_paint_{target,before,after}.png (the views side by side).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from octopaint_ref import raycast
from octopaint_ref.camera import orbit_camera
from octopaint_ref.diffpaint import stroke_values
from octopaint_ref.diffrender import composite, record_paths
from octopaint_ref.dump import tree_arrays, write_atomic
from octopaint_ref.jax_setup import configure
from octopaint_ref.optim import adam_init, adam_step
from octopaint_ref.png import png_bytes
from octopaint_ref.tree import Tree

CENTRE = (0.5, 0.5, 0.5)
VIEWS = ((0.0, 10.0), (90.0, 25.0), (200.0, -30.0))
BACKGROUND = (0.05, 0.05, 0.08)
HARDNESS = 0.3
OPACITY = 0.9
TARGET = {
    "colour": (0.95, 0.55, 0.1),
    "radius": 0.11,
    "points": ((0.28, 0.36, 0.5), (0.5, 0.58, 0.44), (0.72, 0.47, 0.56)),
}
START = {
    "colour": (0.2, 0.45, 0.85),
    "radius": 0.07,
    "points": ((0.33, 0.45, 0.45), (0.5, 0.5, 0.5), (0.66, 0.42, 0.5)),
}
LEARNING_RATE = {"colour": 0.03, "radius": 0.003, "points": 0.006}


def _stroke(spec):
    return {k: jnp.asarray(np.array(v, np.float64)) for k, v in spec.items()}


def save(path, colours, size):
    w, h = size
    row = np.concatenate([raycast.to_pixels(np.asarray(c).reshape(h, w, 3)) for c in colours], axis=1)
    write_atomic(path, png_bytes(row))


def run(iterations=150, out=None, size=(48, 48), log=print):
    """Returns (losses, fitted parameters as numpy)."""
    tree = Tree((1, 1, 1), 5, 1.0, 1 << 16)
    for _ in range(5):
        tree.refine_round(tree.leaves())
    leaves = tree.leaves()
    dev, canvas = raycast.device_tree(tree_arrays(tree))
    centres = jnp.asarray(tree.centres(leaves))
    idx = jnp.asarray(leaves)
    empty_rgb, empty_sigma = jnp.zeros((len(leaves), 3)), jnp.zeros(len(leaves))
    bg = jnp.asarray(BACKGROUND)
    vs = []
    for az, el in VIEWS:
        rays = raycast.camera_rays(orbit_camera(CENTRE, 2.2, az, el, size, 0.3, BACKGROUND), canvas)
        vs.append((rays, record_paths(dev, canvas, rays)))

    def render_all(stroke):
        rgb, sigma = stroke_values(centres, empty_rgb, empty_sigma, {**stroke, "opacity": jnp.asarray(OPACITY)}, HARDNESS)
        rgb_all, sigma_all = dev.rgb.at[idx].set(rgb), dev.sigma.at[idx].set(sigma)
        return [composite(rgb_all, sigma_all, p, jnp.asarray(p.p0), r.dir_canvas, canvas, bg) for r, p in vs]

    targets = render_all(_stroke(TARGET))

    def loss(stroke):
        return sum(jnp.mean((a - b) ** 2) for a, b in zip(render_all(stroke), targets)) / len(targets)

    params = _stroke(START)
    if out:
        os.makedirs(out, exist_ok=True)
        save(os.path.join(out, "inverse_paint_target.png"), targets, size)
        save(os.path.join(out, "inverse_paint_before.png"), render_all(params), size)
    value_and_grad = jax.jit(jax.value_and_grad(loss))
    state = adam_init(params)
    losses = []
    for it in range(iterations):
        value, grads = value_and_grad(params)
        losses.append(float(value))
        log(f"iteration {it:4d}  loss {float(value):.3e}  radius {float(params['radius']):.4f}")
        params, state = adam_step(params, grads, state, LEARNING_RATE)
        params["colour"] = jnp.clip(params["colour"], 0.0, 1.0)
        params["radius"] = jnp.maximum(params["radius"], 0.02)
    losses.append(float(jax.jit(loss)(params)))
    fitted = {k: np.asarray(v) for k, v in params.items()}
    log(f"final          loss {losses[-1]:.3e} ({losses[0] / max(losses[-1], 1e-300):.0f}x lower)")
    for k in ("colour", "radius", "points"):
        log(f"{k:>7}: fitted {np.round(fitted[k], 4).tolist()}  target {np.round(np.array(TARGET[k]), 4).tolist()}")
    if out:
        save(os.path.join(out, "inverse_paint_after.png"), render_all(params), size)
    return losses, fitted


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iterations", type=int, default=150)
    ap.add_argument("--out", default="docs/examples")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    run(args.iterations, args.out)
    print(f"{time.perf_counter() - t0:.1f} s; images in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

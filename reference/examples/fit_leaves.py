"""Fit the colours and densities of every leaf of a fixed tree to three
rendered views of a target (differentiable ray casting, diffrender.py).

    python reference/examples/fit_leaves.py [--iterations 300] [--out docs/examples]

The target is two strokes painted (diffpaint.py) on a root refined to depth
4 everywhere (4,096 leaves); the fit starts from grey haze and sees only
the three 48x48 images. Prints the loss per iteration and writes
fit_leaves_{target,before,after}.png (the three views side by side).
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
VIEWS = ((0.0, 15.0), (110.0, 30.0), (230.0, -20.0))  # azimuth, elevation (deg)
BACKGROUND = (0.05, 0.05, 0.08)


def target_values(tree: Tree, leaves):
    """Two strokes painted over empty leaves: (rgb [n, 3], sigma [n])."""
    c = jnp.asarray(tree.centres(leaves))
    rgb, sigma = jnp.zeros((len(leaves), 3)), jnp.zeros(len(leaves))
    for colour, pts in (
        ((0.9, 0.35, 0.15), [[0.25, 0.3, 0.45], [0.5, 0.55, 0.5], [0.75, 0.45, 0.55]]),
        ((0.2, 0.5, 0.95), [[0.45, 0.2, 0.3], [0.5, 0.5, 0.7], [0.55, 0.8, 0.4]]),
    ):
        st = {"colour": jnp.array(colour), "opacity": jnp.array(0.9), "radius": jnp.array(0.12), "points": jnp.array(pts)}
        rgb, sigma = stroke_values(c, rgb, sigma, st, 0.5)
    return rgb, sigma


def views(tree_dev, canvas, size):
    out = []
    for az, el in VIEWS:
        cam = orbit_camera(CENTRE, 2.2, az, el, size, 0.3, BACKGROUND)
        rays = raycast.camera_rays(cam, canvas)
        out.append((rays, record_paths(tree_dev, canvas, rays)))
    return out


def save(path, colours, size):
    w, h = size
    row = np.concatenate([raycast.to_pixels(np.asarray(c).reshape(h, w, 3)) for c in colours], axis=1)
    write_atomic(path, png_bytes(row))


def run(iterations=300, out=None, size=(48, 48), log=print):
    """Returns the loss per iteration (before each update, then the final)."""
    tree = Tree((1, 1, 1), 4, 1.0, 1 << 14)
    for _ in range(4):
        tree.refine_round(tree.leaves())
    leaves = tree.leaves()
    dev, canvas = raycast.device_tree(tree_arrays(tree))
    vs = views(dev, canvas, size)
    idx = jnp.asarray(leaves)
    t_rgb, t_sigma = target_values(tree, leaves)
    bg = jnp.asarray(BACKGROUND)

    def render_all(rgb_leaves, sigma_leaves):
        rgb = dev.rgb.at[idx].set(rgb_leaves)
        sigma = dev.sigma.at[idx].set(sigma_leaves)
        return [composite(rgb, sigma, paths, jnp.asarray(paths.p0), rays.dir_canvas, canvas, bg) for rays, paths in vs]

    targets = render_all(t_rgb, t_sigma)
    sigma_scale = 20.0

    def unpack(params):
        return jax.nn.sigmoid(params["rgb"]), jax.nn.softplus(params["sigma"]) * sigma_scale

    def loss(params):
        imgs = render_all(*unpack(params))
        return sum(jnp.mean((a - b) ** 2) for a, b in zip(imgs, targets)) / len(imgs)

    params = {"rgb": jnp.zeros((len(leaves), 3)), "sigma": jnp.full(len(leaves), -4.0)}
    value_and_grad = jax.jit(jax.value_and_grad(loss))
    if out:
        os.makedirs(out, exist_ok=True)
        save(os.path.join(out, "fit_leaves_target.png"), targets, size)
        save(os.path.join(out, "fit_leaves_before.png"), render_all(*unpack(params)), size)
    state = adam_init(params)
    losses = []
    for it in range(iterations):
        value, grads = value_and_grad(params)
        losses.append(float(value))
        log(f"iteration {it:4d}  loss {float(value):.3e}")
        params, state = adam_step(params, grads, state, 0.1)
    losses.append(float(jax.jit(loss)(params)))
    log(f"final          loss {losses[-1]:.3e} ({losses[0] / max(losses[-1], 1e-300):.0f}x lower)")
    if out:
        save(os.path.join(out, "fit_leaves_after.png"), render_all(*unpack(params)), size)
    return losses


def main(argv=None) -> int:
    configure()
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iterations", type=int, default=300)
    ap.add_argument("--out", default="docs/examples")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    run(args.iterations, args.out)
    print(f"{time.perf_counter() - t0:.1f} s; images in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

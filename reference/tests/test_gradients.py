"""Gradients of image losses against central finite differences (f64):
cell values and the eye through the ray caster, brush colour, opacity,
radius and sample positions through the stamping (fixed topology)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from octopaint_ref import raycast
from octopaint_ref.camera import pixel_directions, split_eye
from octopaint_ref.diffpaint import stroke_values
from octopaint_ref.diffrender import composite, record_paths, start_from_eye
from octopaint_ref.dump import tree_arrays
from octopaint_ref.precision import refine_towards, uniform
from octopaint_ref.trace import Camera
from octopaint_ref.tree import Tree

# Tolerances are data: |grad - fd| <= rtol * |fd| + atol, per dtype.
TOL = {"f64": {"rtol": 2e-5, "atol": 1e-9}}
H = {"value": 1e-6, "eye": 1e-7, "brush": 1e-6}


def _close(grad, fd, tol=TOL["f64"]):
    grad, fd = np.asarray(grad), np.asarray(fd)
    assert np.all(np.abs(grad - fd) <= tol["rtol"] * np.abs(fd) + tol["atol"]), (grad, fd)


@pytest.fixture(scope="module")
def scene():
    """One root, depth 3 everywhere and depth 6 around a point: steps to
    siblings, same-depth and coarser neighbours, and descents."""
    t = Tree((1, 1, 1), 6, 1.0, 1 << 16)
    for _ in range(3):
        t.refine_round(t.leaves())
    refine_towards(t, (0.43, 0.57, 0.51), 6)
    a = tree_arrays(t)
    n = len(a["parent"])
    i = np.arange(n)
    a["rgb"] = (np.stack([uniform(41, i), uniform(42, i), uniform(43, i)], 1) * 255).astype(np.uint8)
    a["sigma"] = (uniform(44, i) * 6.0).astype(np.float32)
    tree, canvas = raycast.device_tree(a)
    leaves = t.leaves()
    return a, tree, canvas, leaves, t.centres(leaves)


def _rays(canvas, eye, q, size, fov=0.35):
    cam = Camera(tuple(eye), q, (-fov, fov, fov, -fov), size)
    lu = canvas.root_size * 2.0**-canvas.max_depth
    e, f = split_eye(eye, lu)
    d = pixel_directions(cam).reshape(-1, 3)
    n = len(d)
    return raycast.Ray(np.broadcast_to(e, (n, 3)).copy(), np.broadcast_to(f, (n, 3)).copy(), d)


def _check_cells(cells, g_rgb, g_sigma, tree, loss_traced):
    """Each cell's d loss / d sigma and d loss / d green against central
    finite differences of loss_traced(rgb, sigma) (numpy pools)."""
    rgb0, sigma0 = np.asarray(tree.rgb), np.asarray(tree.sigma)
    h = H["value"]
    for c in cells:
        up, dn = sigma0.copy(), sigma0.copy()
        up[c] += h
        dn[c] -= h
        _close(g_sigma[c], (loss_traced(rgb0, up) - loss_traced(rgb0, dn)) / (2 * h))
        up, dn = rgb0.copy(), rgb0.copy()
        up[c, 1] += h
        dn[c, 1] -= h
        _close(g_rgb[c, 1], (loss_traced(up, sigma0) - loss_traced(dn, sigma0)) / (2 * h))


OUTSIDE = ((0.5, 0.45, 2.2), (0.0, 0.0, 0.0, 1.0))
TARGET = 0.3


def test_composite_replays_the_ray_caster(scene):
    _, tree, canvas, _, _ = scene
    rays = _rays(canvas, *OUTSIDE, (12, 12))
    paths = record_paths(tree, canvas, rays)
    s, _ = raycast.cast(tree, canvas, rays, "f64", "local")
    got = composite(tree.rgb, tree.sigma, paths, jnp.asarray(paths.p0), rays.dir_canvas, canvas, jnp.zeros(3))
    assert np.allclose(np.asarray(got), s.colour, rtol=0, atol=1e-12)
    assert s.colour.max() > 0.1


def test_gradient_of_cell_values(scene):
    """d loss / d (rgb, sigma) of chosen cells against finite differences of
    the ray caster itself (raycast.cast with the values perturbed)."""
    _, tree, canvas, _, _ = scene
    rays = _rays(canvas, *OUTSIDE, (10, 10))
    paths = record_paths(tree, canvas, rays)
    p0 = jnp.asarray(paths.p0)

    def loss(rgb, sigma):
        c = composite(rgb, sigma, paths, p0, rays.dir_canvas, canvas, jnp.zeros(3))
        return jnp.sum((c - TARGET) ** 2)

    g_rgb, g_sigma = jax.jit(jax.grad(loss, argnums=(0, 1)))(tree.rgb, tree.sigma)
    g_rgb, g_sigma = np.asarray(g_rgb), np.asarray(g_sigma)

    def loss_traced(rgb, sigma):
        s, _ = raycast.cast(tree._replace(rgb=jnp.asarray(rgb), sigma=jnp.asarray(sigma)), canvas, rays, "f64", "local")
        return float(np.sum((s.colour - TARGET) ** 2))

    cells = np.argsort(-np.abs(g_sigma))[:4].tolist() + np.argsort(-np.abs(g_rgb[:, 1]))[:3].tolist()
    _check_cells(cells, g_rgb, g_sigma, tree, loss_traced)
    assert np.abs(g_sigma[cells]).min() > 1e-6


def test_gradient_of_the_eye(scene):
    """d loss / d eye for an eye inside the canvas. The finite differences
    re-run the ray caster at eye +- h and check that the cell sequences did
    not change (the gradient is that of a fixed sequence)."""
    _, tree, canvas, _, _ = scene
    eye = np.array([0.4312, 0.5623, 0.5101])
    q = (0.1, 0.2, 0.05, 0.97)
    rays = _rays(canvas, eye, q, (8, 8), fov=0.6)
    paths = record_paths(tree, canvas, rays)

    def loss(e):
        p0 = start_from_eye(paths, e, canvas)
        c = composite(tree.rgb, tree.sigma, paths, p0, rays.dir_canvas, canvas, jnp.zeros(3))
        return jnp.sum((c - TARGET) ** 2)

    assert np.allclose(np.asarray(start_from_eye(paths, jnp.asarray(eye), canvas)), paths.p0, atol=1e-9)
    g = np.asarray(jax.grad(loss)(jnp.asarray(eye)))
    fd = []
    for a in range(3):
        vals = []
        for sgn in (1, -1):
            e = eye.copy()
            e[a] += sgn * H["eye"]
            r = _rays(canvas, e, q, (8, 8), fov=0.6)
            moved = record_paths(tree, canvas, r)
            assert np.array_equal(moved.cell, paths.cell)
            s, _ = raycast.cast(tree, canvas, r, "f64", "local")
            vals.append(np.sum((s.colour - TARGET) ** 2))
        fd.append((vals[0] - vals[1]) / (2 * H["eye"]))
    _close(g, np.array(fd), {"rtol": 1e-4, "atol": 1e-6})
    assert np.abs(g).max() > 1e-2


def test_gradient_of_the_brush(scene):
    """d loss / d (colour, opacity, radius, sample positions) of a stroke
    painted on the fixed leaves, rendered, against central differences."""
    a, tree, canvas, leaves, centres = scene
    rays = _rays(canvas, *OUTSIDE, (10, 10))
    paths = record_paths(tree, canvas, rays)
    p0 = jnp.asarray(paths.p0)
    leaves_j = jnp.asarray(leaves)
    before_rgb = tree.rgb[leaves_j]
    before_sigma = tree.sigma[leaves_j] * 0.1
    stroke = {
        "colour": jnp.array([0.9, 0.4, 0.2]),
        "opacity": jnp.array(0.8),
        "radius": jnp.array(0.17),
        "points": jnp.array([[0.35, 0.4, 0.5], [0.5, 0.47, 0.55], [0.63, 0.5, 0.45]]),
    }

    def loss(st):
        rgb, sigma = stroke_values(jnp.asarray(centres), before_rgb, before_sigma, st, 0.4)
        c = composite(tree.rgb.at[leaves_j].set(rgb), tree.sigma.at[leaves_j].set(sigma), paths, p0, rays.dir_canvas, canvas, jnp.zeros(3))
        return jnp.sum((c - TARGET) ** 2)

    f = jax.jit(loss)
    g = jax.jit(jax.grad(loss))(stroke)
    for name in ("colour", "opacity", "radius", "points"):
        x = np.asarray(stroke[name], np.float64)
        for idx in np.ndindex(x.shape):
            up, dn = x.copy(), x.copy()
            up[idx] += H["brush"]
            dn[idx] -= H["brush"]
            fd = (float(f({**stroke, name: jnp.asarray(up)})) - float(f({**stroke, name: jnp.asarray(dn)}))) / (2 * H["brush"])
            _close(np.asarray(g[name])[idx], fd, {"rtol": 1e-4, "atol": 1e-6})
    assert abs(float(g["radius"])) > 1e-3 and np.abs(np.asarray(g["points"])).max() > 1e-3


def _cut(canvas, k, size=(12, 12), fov=0.35):
    eye, q = OUTSIDE
    return raycast.camera_cut(Camera(tuple(eye), q, (-fov, fov, fov, -fov), size), k)


def test_composite_replays_the_ray_caster_with_a_level_of_detail(scene):
    """Spec 7's cut: the recorded sequence stops at small interior cells and
    the composite replays raycast.cast at that k (its frame maps include the
    cut's moves up and down)."""
    a, tree, canvas, _, _ = scene
    rays = _rays(canvas, *OUTSIDE, (12, 12))
    full = record_paths(tree, canvas, rays)
    lod = _cut(canvas, 4.0)
    paths = record_paths(tree, canvas, rays, lod=lod)
    # The cut engages: some rays step through interior cells, and fewer cells.
    walked = paths.cell[np.arange(paths.cell.shape[1])[None, :] < paths.steps[:, None]]
    assert np.any(np.asarray(a["first_child"])[walked] != 0xFFFF_FFFF)
    assert paths.steps.sum() < full.steps.sum()
    s, _ = raycast.cast(tree, canvas, rays, "f64", "local", lod=lod)
    got = composite(tree.rgb, tree.sigma, paths, jnp.asarray(paths.p0), rays.dir_canvas, canvas, jnp.zeros(3))
    assert np.allclose(np.asarray(got), s.colour, rtol=0, atol=1e-12)


def test_gradients_reach_the_leaves_under_a_cut_cell(scene):
    """With the cut, d loss / d leaf sigma and rgb go through the prefilter
    (diffrender.prefiltered) to leaves no ray visits, and match central
    finite differences of the ray caster on prefiltered values."""
    from octopaint_ref.diffrender import prefiltered

    a, tree, canvas, _, _ = scene
    rays = _rays(canvas, *OUTSIDE, (10, 10))
    lod = _cut(canvas, 4.0, (10, 10))
    paths = record_paths(tree, canvas, rays, lod=lod)
    p0 = jnp.asarray(paths.p0)
    fc, depth = np.asarray(a["first_child"]), np.asarray(a["depth"])

    def loss(rgb, sigma):
        rgb, sigma = prefiltered(fc, depth, rgb, sigma)
        c = composite(rgb, sigma, paths, p0, rays.dir_canvas, canvas, jnp.zeros(3))
        return jnp.sum((c - TARGET) ** 2)

    g_rgb, g_sigma = jax.grad(loss, argnums=(0, 1))(tree.rgb, tree.sigma)
    g_rgb, g_sigma = np.asarray(g_rgb), np.asarray(g_sigma)

    def loss_traced(rgb, sigma):
        rgb, sigma = prefiltered(fc, depth, rgb, sigma)
        s, _ = raycast.cast(tree._replace(rgb=rgb, sigma=sigma), canvas, rays, "f64", "local", lod=lod)
        return float(np.sum((s.colour - TARGET) ** 2))

    visited = np.zeros(len(fc), bool)
    visited[paths.cell[np.arange(paths.cell.shape[1])[None, :] < paths.steps[:, None]]] = True
    leaf = fc == 0xFFFF_FFFF  # the device tree pads its pools past the dump's cells
    hidden = np.nonzero(leaf & ~visited & (np.abs(g_sigma[: len(fc)]) > 1e-6))[0]
    assert len(hidden) > 0, "no gradient reaches a leaf under a cut cell"
    _check_cells(hidden[np.argsort(-np.abs(g_sigma[hidden]))[:3]].tolist(), g_rgb, g_sigma, tree, loss_traced)

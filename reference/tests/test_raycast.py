"""The ray caster (spec 6, 7) against the mpmath oracle, against numpy
scalar arithmetic in f16/f32, on broken links, on clipped eyes, and as
written by replay."""

import io
import os

import numpy as np
import pytest
from conftest import TRACES
from octopaint_ref import oracle, raycast
from octopaint_ref.arith import FORMATS
from octopaint_ref.dump import tree_arrays
from octopaint_ref.png import png_bytes, read_png
from octopaint_ref.precision import build_scene, eye_split, rays_from, sphere_directions
from octopaint_ref.trace import Camera, read_trace
from octopaint_ref.tree import Tree
from PIL import Image


@pytest.fixture(scope="module")
def graded():
    """Depth-24 graded tree with hashed leaf values, and its device copy."""
    arrays = build_scene(paint=False)
    return arrays, raycast.device_tree(arrays)


def test_png_files_hold_their_pixels():
    rgb = (np.arange(7 * 5 * 3).reshape(5, 7, 3) * 7 % 256).astype(np.uint8)
    data = png_bytes(rgb)
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(data)).convert("RGB")), rgb)
    assert np.array_equal(read_png(data), rgb)
    assert png_bytes(rgb) == data
    with pytest.raises(ValueError, match="expected"):
        png_bytes(rgb[..., :2])


def test_f64_local_matches_the_exact_ray(graded):
    """Cell sequence, termination and colour of f64 local rays equal the
    mpmath oracle's (which shares no code with the traversal)."""
    arrays, dev = graded
    tree, canvas = dev
    e, f = eye_split()
    rays = rays_from(e, f, sphere_directions(24, stream=5))
    s, rec = raycast.cast(tree, canvas, rays, "f64", "local", record=512)
    for i in range(24):
        ex = oracle.exact_path(arrays, e, f, rays.dir_canvas[i], max_steps=int(s.steps[i]))
        n = int(s.steps[i])
        assert [int(c) for c in rec.cell[i, :n]] == ex.cells[:n]
        assert ex.opaque_at == n or s.status[i] == raycast.LEFT
        colour = np.array([float(c) for c in ex.colour])
        assert np.allclose(s.colour[i], colour, rtol=0, atol=1e-12), (i, s.colour[i], colour)


def _replay_step_numpy(dt, p, d, axis_rec, p_exit_rec, cell, depth_now, depth_next):
    """One step of spec 7 in numpy scalars of dtype dt (numpy rounds once
    per operation): the exit distances, the exit point, the frame change.
    Returns (p_exit, p_next)."""
    half = dt(0.5)
    ts = []
    for a in range(3):
        if d[a] == 0:
            ts.append(np.inf)
        else:
            bound = half if d[a] > 0 else -half
            ts.append(max(dt((bound - p[a]) / d[a]), dt(0)))
    axis = int(np.argmin(ts))
    assert axis == axis_rec
    t = dt(ts[axis])
    p_exit = [dt(p[b] + dt(t * d[b])) for b in range(3)]
    s = 1 if d[axis] > 0 else -1
    p_exit[axis] = half if s > 0 else -half
    assert all(np.float64(p_exit[b]) == p_exit_rec[b] for b in range(3))
    p_next = list(p_exit)
    if depth_next == depth_now - 1:  # one level coarser
        bits = [(cell >> b) & 1 for b in range(3)]
        p_next = [dt(dt(p_exit[b] * dt(0.5)) + dt((bits[b] - 0.5) * 0.5)) for b in range(3)]
    p_next[axis] = dt(-0.5 * s)
    if depth_next == depth_now + 1:  # a descent (balanced tree: only after a same-depth step)
        p_next = [dt(dt(p_next[b] * dt(2)) + (dt(-0.5) if p_next[b] >= 0 else dt(0.5))) for b in range(3)]
    return p_exit, p_next


@pytest.mark.parametrize("name", ["f16", "f32", "f64"])
def test_traversal_rounds_like_numpy_scalars(graded, name):
    """Every exit point of every step equals a numpy-scalar replay of the
    same step in the same format, bit for bit (f16: IEEE half per op)."""
    arrays, dev = graded
    tree, canvas = dev
    dt = FORMATS[name].numpy_dtype
    e, f = eye_split()
    rays = rays_from(e, f, sphere_directions(12, stream=7))
    s, rec = raycast.cast(tree, canvas, rays, name, "local", record=512)
    starts = raycast.start_points(tree, canvas, rays, name, "local")
    checked = 0
    for i in range(12):
        d = [dt(v) for v in rays.dir_canvas[i]]
        p = [dt(v) for v in starts[4][i]]
        # the start: ((E - o) + phi)/S - 1/2, each operation rounded
        S = 2.0 ** (24 - int(starts[2][i]))
        rel = [dt((int(e[a]) - int(starts[3][i][a])) / S) for a in range(3)]
        frac = [dt(dt(f[a]) / dt(S)) if S < 2**14 else dt(np.float64(dt(f[a])) / S) for a in range(3)]
        assert p == [dt(dt(rel[a] + frac[a]) - dt(0.5)) for a in range(3)]
        n = int(s.steps[i])
        for k in range(n - 1):
            p_exit, p = _replay_step_numpy(
                dt, p, d, int(rec.axis[i, k]), rec.p_exit[i, k], int(rec.cell[i, k]), int(rec.depth[i, k]), int(rec.depth[i, k + 1])
            )
            checked += 1
    assert checked > 300


def _two_roots(values):
    """Roots (2, 1, 1), D = 3; root 0 refined once. values: {cell: (rgb, sigma)};
    a value for root 0 overrides its prefilter."""
    t = Tree((2, 1, 1), 3, 1.0, 1024)
    t.refine_round(np.array([0]))
    for c, (rgb, sigma) in values.items():
        t.rgb[c] = rgb
        t.sigma[c] = sigma
    arrays = tree_arrays(t)
    # tree_arrays stores root 0's prefilter (spec 4.4); a value given for it
    # here is put back, so a test can tell the parent's own colour from its
    # children's
    if 0 in values:
        arrays["rgb"][0] = values[0][0]
        arrays["sigma"][0] = values[0][1]
    return arrays


CAM = Camera((-0.5, 0.3, 0.3), (0.0, -0.7071067811865476, 0.0, 0.7071067811865476), (-0.2, 0.2, 0.2, -0.2), (16, 16))


def test_broken_descent_composites_the_parent():
    """Children whose parent link is broken are not entered: the parent is
    composited as a leaf (spec 7)."""
    vals = {0: ((200, 10, 10), 3.0), 1: ((9, 9, 9), 0.0), 8: ((10, 200, 10), 4.0), 9: ((10, 10, 200), 6.0)}
    broken = _two_roots(vals)
    broken["parent"][8:16] = 1  # the unit no longer points back at root 0
    leaf = _two_roots(vals)
    leaf["first_child"][0] = raycast.NONE  # what the ray caster must see
    a = raycast.render(broken, CAM)
    b = raycast.render(leaf, CAM)
    assert a.count(raycast.LEFT) == 256
    assert np.array_equal(a.image, b.image)
    assert a.image.max() > 100  # the parent's red is there


def test_broken_sibling_is_crossed_without_compositing():
    vals = {8 + k: ((30 * k, 100, 50), 2.0) for k in range(8)}
    broken = _two_roots(vals)
    broken["parent"][9] = 1  # child 9 alone loses its link
    cleared = _two_roots({**vals, 9: ((0, 0, 0), 0.0)})
    eye = (0.1, 0.2, 0.2)
    cam = Camera(eye, (0.0, -0.7071067811865476, 0.0, 0.7071067811865476), (-0.3, 0.3, 0.3, -0.3), (24, 24))
    a = raycast.render(broken, cam)
    b = raycast.render(cleared, cam)
    assert a.skipped > 0
    assert np.array_equal(a.image, b.image)
    assert not np.array_equal(a.image, raycast.render(_two_roots(vals), cam).image)


def test_clipped_eye_sees_what_an_inside_eye_sees(graded):
    """A ray from outside the canvas crosses the cells, and composites the
    colour, of the same ray started just inside the canvas box (spec 7)."""
    arrays, dev = graded
    tree, canvas = dev
    lu = canvas.root_size * 2.0**-canvas.max_depth
    dirs = sphere_directions(16, stream=9)
    target = np.array([1.6307371234567891, 2.2741693456789123, 1.9137571928374651])
    outside = target[None, :] - dirs * 7.0
    # the slab entry, then 1e-9 canvas units further (inside the box)
    t0, t1 = (0.0 - outside) / dirs, (4.0 - outside) / dirs
    t_in = np.minimum(t0, t1).max(axis=1)
    inside = outside + dirs * (t_in + 1e-9)[:, None]

    def rays(points):
        e = np.floor(points / lu)
        return raycast.Ray(e.astype(np.int64), points / lu - e, dirs)

    a, ra = raycast.cast(tree, canvas, rays(outside), "f64", "local", record=256)
    b, rb = raycast.cast(tree, canvas, rays(inside), "f64", "local", record=256)
    assert np.array_equal(a.steps, b.steps)
    assert np.array_equal(ra.cell, rb.cell)
    assert np.allclose(a.colour, b.colour, atol=1e-6)
    assert np.array_equal(a.status, b.status) and a.steps.sum() > len(dirs)


def test_frames_and_precisions_agree_on_a_shallow_tree():
    """single_stamp (depth 8): world and local frames, f32 and f64, give the
    same picture to within a step; f16 local to within a few."""
    trace = read_trace(os.path.join(TRACES, "single_stamp.jsonl"))
    from octopaint_ref.replay import replay

    images = {}
    replay(trace, None, on_render=lambda name, img: images.setdefault(name, img))
    arrays = tree_arrays(replay(trace, None, renders=False).painting.tree)
    cam = [e.value for e in trace.events if e.kind == "camera"][-1]
    ref = raycast.render(arrays, cam)
    assert np.array_equal(ref.image, images["single_stamp"].image)
    assert ref.image.max() > 100
    for prec, frame, steps in (("f64", "world", 1), ("f32", "local", 1), ("f32", "world", 1), ("f16", "local", 3)):
        img = raycast.render(arrays, cam, prec, frame).image
        assert np.abs(img.astype(int) - ref.image.astype(int)).max() <= steps, (prec, frame)


@pytest.mark.parametrize("precision,frame", [("f16", "local"), ("f64", "world")])
def test_traversal_traces_under_strict_dtype_promotion(precision, frame):
    """No implicit dtype promotion anywhere in the traversal (JAX 'strict')."""
    import jax

    arrays = build_scene(paint=False, depth=10)
    tree, canvas = raycast.device_tree(arrays)
    e, f = eye_split()
    rays = rays_from(e, f, sphere_directions(8))
    with jax.numpy_dtype_promotion("strict"):
        s, rec = raycast.cast(tree, canvas, rays, precision, frame, record=64)
    assert np.all(s.status == raycast.LEFT) or np.all(s.steps > 0)


def test_images_do_not_depend_on_batching():
    """The same render in tiles of 4096 rays and of 1000 gives the same
    colours bit for bit (every operation rounds once, whatever XLA fuses)."""
    from octopaint_ref.replay import replay

    trace = read_trace(os.path.join(TRACES, "single_stamp.jsonl"))
    arrays = tree_arrays(replay(trace, None, renders=False).painting.tree)
    cam = [e.value for e in trace.events if e.kind == "camera"][-1]
    a = raycast.render(arrays, cam)
    b = raycast.render(arrays, cam, tile=1000)
    assert np.array_equal(a.colour, b.colour)
    assert png_bytes(a.image) == png_bytes(b.image)

"""Level of detail (spec 7): the cut's definition against a brute-force
walker that finds the cut cell at every point by descent from its root,
k = 0 against the full walk, the monotone smallness the walk relies on, and
the --lod option of replay."""

import math
import os
import subprocess
import sys

import numpy as np
import pytest
from octopaint_ref import lod, raycast
from octopaint_ref.camera import pixel_directions, split_eye
from octopaint_ref.precision import CANVAS, build_scene, near_camera
from octopaint_ref.replay import parse_lods

NONE = 0xFFFF_FFFF


@pytest.fixture(scope="module")
def graded():
    """The depth-24 graded tree of the precision study, with hashed leaf
    values and its interior cells prefiltered (dump arrays)."""
    return build_scene(paint=False)


def _small_np(cut, max_depth, depth, origin):
    s = float(1 << (max_depth - depth))
    v = ((np.asarray(origin, np.int64) - cut.eye_lattice).astype(np.float64) + s * 0.5) - cut.frac
    z = (v[0] * cut.fwd[0] + v[1] * cut.fwd[1]) + v[2] * cut.fwd[2]
    return s <= cut.lam * z


def _cut_cell(arrays, cut, q):
    """The cut cell at lattice point q by descent from its root (spec 7's
    definition): (cell, depth, origin)."""
    D = int(arrays["max_depth"])
    rx, ry, _ = (int(r) for r in np.asarray(arrays["roots"]).reshape(-1))
    root = q >> D
    cell = int(root[0] + rx * (root[1] + ry * root[2]))
    depth, origin = 0, root << D
    fc_all, parent = arrays["first_child"], arrays["parent"]
    while fc_all[cell] != NONE and not _small_np(cut, D, depth, origin):
        half = 1 << (D - depth - 1)
        bits = (q - origin >= half).astype(np.int64)
        child = int(fc_all[cell]) + int(bits[0] | (bits[1] << 1) | (bits[2] << 2))
        assert parent[child] == cell
        cell, depth, origin = child, depth + 1, origin + bits * half
    return cell, depth, origin


def _brute_force(arrays, cut, eye, d, lu):
    """Composite along one ray by finding the cut cell at every point:
    world-frame slab exits in lattice units, a nudge past each exit."""
    D = int(arrays["max_depth"])
    extent = np.asarray(arrays["roots"]).reshape(-1).astype(np.int64) << D
    rgb = np.asarray(arrays["rgb"], np.float64) / 255.0
    sigma = np.asarray(arrays["sigma"], np.float32).astype(np.float64)
    colour, trans, t, cells = np.zeros(3), 1.0, 0.0, []
    while trans >= raycast.T_MIN:
        x = eye + t * d
        q = np.floor(x).astype(np.int64)
        if np.any(q < 0) or np.any(q >= extent):
            break
        cell, depth, origin = _cut_cell(arrays, cut, q)
        size = float(1 << (D - depth))
        bound = np.where(d > 0, origin + size, origin).astype(np.float64)
        t_axes = np.where(d != 0, (bound - eye) / np.where(d != 0, d, 1.0), np.inf)
        t_exit = float(t_axes.min())
        e = math.exp(-sigma[cell] * (t_exit - t) * lu)
        colour += trans * (1.0 - e) * rgb[cell]
        trans *= e
        cells.append(cell)
        t = t_exit + 1e-7 * size
    return colour, trans, cells


def test_the_walk_finds_the_cut_of_the_definition(graded):
    """Every ray of a small image at a coarse level, whose footprints are
    wider than most of the graded tree's cells, composites what the
    brute-force cut walker does."""
    camera = near_camera(size=(12, 9), fov_deg=60.0)
    k = 8.0  # lam = 0.77: the graded tree's cells are about as wide as their distance
    r = raycast.render(graded, camera, lod=k)
    full = raycast.render(graded, camera)
    lu = CANVAS.root_size * 2.0**-CANVAS.max_depth
    e, f = split_eye(camera.eye, lu)
    cut = lod.Cut(lod.lam_of(camera, k), lod.view_axis(camera), e, f)
    eye = e.astype(np.float64) + f
    dirs = pixel_directions(camera).reshape(-1, 3)
    agree = 0
    for i, d in enumerate(dirs):
        colour, trans, _ = _brute_force(graded, cut, eye, d, lu)
        colour = colour + trans * np.asarray(camera.background)
        agree += np.allclose(r.colour.reshape(-1, 3)[i], colour, rtol=0, atol=1e-6)
    assert agree >= len(dirs) - 2, f"{len(dirs) - agree} of {len(dirs)} rays differ"
    # The cut is coarser than the leaves: fewer cells, another picture.
    assert r.steps.sum() < 0.8 * full.steps.sum()
    assert not np.array_equal(r.image, full.image)


def test_a_level_that_cuts_nothing_is_the_full_walk(graded):
    """With lam > 0 but no cell small (the cut's code runs, nothing stops),
    the image, the colours and the steps are those of k = 0."""
    camera = near_camera(size=(16, 12), fov_deg=60.0)
    full = raycast.render(graded, camera)
    tiny = raycast.render(graded, camera, lod=1e-12)
    assert lod.lam_of(camera, 1e-12) > 0
    assert np.array_equal(full.image, tiny.image)
    assert np.array_equal(full.colour, tiny.colour)
    assert np.array_equal(full.steps, tiny.steps)


def test_smallness_is_monotone_down_the_tree(graded):
    """lam <= 1: a small cell's children are small (the walk's loops rely
    on it), for cameras looking every way from inside the graded tree."""
    D = int(graded["max_depth"])
    depth = np.asarray(graded["depth"]).astype(np.int64)
    origin = np.asarray(graded["origin"]).astype(np.int64)
    fc = np.asarray(graded["first_child"])
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(6):
        q = rng.normal(size=4)
        cam = near_camera(size=(64, 48), fov_deg=90.0)
        cam = type(cam)(cam.eye, tuple(q / np.linalg.norm(q)), cam.fov, cam.size)
        lu = CANVAS.root_size * 2.0**-CANVAS.max_depth
        e, f = split_eye(cam.eye, lu)
        cut = lod.Cut(1.0, lod.view_axis(cam), e, f)
        for c in np.nonzero((fc != NONE) & (depth != 255))[0]:
            if _small_np(cut, D, depth[c], origin[c]):
                for j in range(8):
                    ch = int(fc[c]) + j
                    assert _small_np(cut, D, depth[ch], origin[ch])
                    checked += 1
    assert checked > 0


def test_lod_values_are_checked():
    assert parse_lods("0,1,0.5") == [("0", 0.0), ("1", 1.0), ("0.5", 0.5)]
    for bad in ("", "abc", "-1", "1,1", "1,1.0", "65", "nan", "inf", "1e3", ".5", "1.", "0x1"):
        with pytest.raises(ValueError):
            parse_lods(bad)
    with pytest.raises(ValueError):
        lod.check_k(float("nan"))
    assert lod.lam_of(near_camera(size=(2, 2), fov_deg=170.0), 64.0) == 1.0


def test_replay_refuses_a_bad_lod_before_writing(tmp_path):
    from conftest import TRACES

    out = tmp_path / "out"
    res = subprocess.run(
        [sys.executable, "-m", "octopaint_ref.cli", "replay", os.path.join(TRACES, "single_stamp.jsonl"), "--out", str(out), "--lod", "0,-1"],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 2 and "--lod" in res.stderr
    assert not out.exists()


def test_the_study_measures_every_render_of_a_trace():
    """lod_study (docs/benchmarks.md): one row per render event, a PSNR
    against the supersampled truth and the cells per ray at each level."""
    from conftest import TRACES
    from octopaint_ref import lod_study

    rows = lod_study.study(os.path.join(TRACES, "single_stamp.jsonl"), [0.0, 4.0], ss=2, frames=2, step_deg=0.5)
    assert rows and all(len(r["levels"]) == 2 for r in rows)
    for r in rows:
        full, cut = r["levels"]
        assert full["psnr_db"] > 20 and cut["psnr_db"] > 10
        assert cut["steps_mean"] <= full["steps_mean"] and full["flicker"] >= 0


def test_the_study_scales_cameras_and_writes_the_pair(tmp_path):
    """--scale divides every camera's size (the field of view kept) and
    --pair writes the first and last k's images and the truth side by side,
    enlarged to about 320 pixels each."""
    from conftest import TRACES
    from octopaint_ref import lod_study
    from octopaint_ref.png import read_png

    path = os.path.join(TRACES, "single_stamp.jsonl")
    rows = lod_study.study(path, [0.0, 4.0], ss=2, frames=1, step_deg=0.5, div=4, pair=str(tmp_path))
    full = lod_study.study(path, [0.0], ss=1, frames=1, step_deg=0.5)
    for r, f in zip(rows, full):
        assert r["size"] == [f["size"][0] // 4, f["size"][1] // 4]
        img = read_png((tmp_path / f"{r['render']}_lod.png").read_bytes())
        w, h = r["size"]
        zoom = max(1, 320 // w)
        assert img.shape == (h * zoom, 3 * w * zoom + 4, 3)


def test_the_orbit_keeps_the_pivot_in_view_and_its_distance():
    """--orbit: the camera is carried about the vertical axis through the
    pivot, turning with it, so the pivot stays on the view axis at the same
    distance (a turntable)."""
    from conftest import TRACES
    from octopaint_ref import lod_study
    from octopaint_ref.lod import view_axis
    from octopaint_ref.replay import replay
    from octopaint_ref.trace import read_trace

    trace = read_trace(os.path.join(TRACES, "single_stamp.jsonl"))
    seen = {}

    def after(ev, painting):
        if ev.kind == "camera":
            seen["camera"] = ev.value
            seen["painting"] = painting

    replay(trace, None, renders=False, after_event=after)
    cam = seen["camera"]
    pivot = lod_study.orbit_pivot(seen["painting"], cam)
    for deg in (0.0, 3.0, 40.0, -90.0):
        moved = lod_study._orbited(cam, deg, pivot)
        to = pivot - np.asarray(moved.eye)
        assert abs(np.linalg.norm(to) - np.linalg.norm(pivot - np.asarray(cam.eye))) < 1e-12
        assert np.allclose(view_axis(moved), to / np.linalg.norm(to), atol=1e-12)
        assert abs(moved.eye[1] - cam.eye[1]) < 1e-12

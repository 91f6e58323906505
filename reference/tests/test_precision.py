"""The paper's error bound (section 6.3) on random rays at depth 24, and the
error metric it is measured with, against mpmath."""

import mpmath
import numpy as np
import pytest
from octopaint_ref import oracle
from octopaint_ref import ray_error as RE
from octopaint_ref.precision import build_scene, eye_split, fig11_choices, measure, rays_from, sphere_directions, within_bound
from octopaint_ref.raycast import cast, device_tree

N_RAYS = 300


@pytest.fixture(scope="module")
def blind_scene():
    """The depth-24 graded tree with density ignored: every ray runs from
    the eye (in a depth-24 leaf) to the canvas boundary."""
    arrays = build_scene(paint=False)
    dev = device_tree({**arrays, "sigma": np.zeros_like(arrays["sigma"])})
    e, f = eye_split()
    return arrays, dev, rays_from(e, f, sphere_directions(N_RAYS, stream=3))


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_every_ray_is_within_the_papers_bound(blind_scene, precision):
    """asin(e0/L + 5 eps) at each ray's last point, e0 measured per ray
    (the computed start against the exact eye), eps = 2^-23 or 2^-52."""
    arrays, dev, rays = blind_scene
    m = measure(arrays, rays, precision, "local", device=dev, opaque=False)
    assert not m["overflow"].any()
    assert m["start_depth"].min() == 24
    assert (m["length"] > 2**24).all()  # every ray reaches the canvas boundary
    ok = within_bound(m)
    assert ok.all(), (m["final_angle"][~ok], RE.bound(m["e0"], m["length"], m["eps"])[~ok])
    assert m["final_angle"].max() > 0  # measured, not vacuous


def test_fig11_choices_measure_what_they_say(blind_scene):
    """The measurement choices of the Fig. 11 comparison (docs/precision.md):
    against the unrounded direction the angle moves by at most the angle
    the rounding turned the direction (triangle inequality on the sphere);
    without e0 it moves by at most e0/L; the statistics are ordered."""
    arrays, dev, rays = blind_scene
    m = measure(arrays, rays, "f32", "local", device=dev, opaque=False)
    rows = {r["key"]: r["rad"] for r in fig11_choices(arrays, rays, m)}
    ours = rows["ours"]
    dirs = np.asarray(rays.dir_canvas)
    turn = RE.angles((dirs.astype(np.float32).astype(np.float64), np.zeros_like(dirs)), dirs)[0].max()
    assert abs(rows["exact_direction"] - ours) <= turn * (1 + 1e-9)
    assert abs(rows["from_start"] - ours) <= (m["e0"] / m["length"]).max() * (1 + 1e-6) + 1e-18
    assert 0 < rows["median"] <= rows["mean"] * 2 <= 2 * ours
    assert 0 < rows["at_paint"] <= m["angle"].max()
    # A graded tree seen from its finest leaf has no cell that small for its
    # distance: the row says so rather than inventing a value.
    assert np.isnan(rows["fine_cells"])


def test_world_coordinates_drift_at_depth_24(blind_scene):
    """The contrast the paper's Fig. 12 draws: f32 world positions cannot
    even hold the eye's depth-24 leaf, and the cells crossed differ."""
    arrays, dev, rays = blind_scene
    world = measure(arrays, rays, "f32", "world", device=dev, opaque=False)
    local = measure(arrays, rays, "f32", "local", device=dev, opaque=False)
    assert world["e0_cells"].max() > 0.5  # the eye moved by half a cell or more
    first = slice(0, 16)
    differs = np.any(world["cells"][:, first] != local["cells"][:, first], axis=1)
    assert differs.mean() > 0.5
    assert world["angle"].max() > 1e3 * local["angle"].max()


def test_angle_metric_matches_mpmath(blind_scene):
    """ray_error's double-double angles equal the mpmath angles to 1e-9
    relative, for f16, f32 and f64 exit points in local and world frames."""
    arrays, dev, rays = blind_scene
    tree, canvas = dev
    e, f = eye_split()
    sub = type(rays)(*(np.asarray(a)[:6] for a in rays))
    for precision in ("f16", "f32", "f64"):
        for frame in ("local", "world"):
            s, rec = cast(tree, canvas, sub, precision, frame, record=256)
            fmt_dirs = sub.dir_canvas.astype({"f16": np.float16, "f32": np.float32, "f64": np.float64}[precision]).astype(np.float64)
            for i in range(6):
                for k in (0, 3, int(s.steps[i]) // 2, int(s.steps[i]) - 1):
                    o, dep, p = rec.origin[i, k][None], rec.depth[i, k][None], rec.p_exit[i, k][None]
                    if frame == "local":
                        w = RE.offsets_local(o, dep, p, e[None], f[None], 24)
                        with mpmath.workdps(120):
                            size = mpmath.mpf(2) ** (24 - int(dep[0]))
                            point = [int(o[0][a]) + (mpmath.mpf(float(p[0][a])) + mpmath.mpf(0.5)) * size for a in range(3)]
                    else:
                        w = RE.offsets_world(p, e[None], f[None], 2.0**-24)
                        with mpmath.workdps(120):
                            point = [mpmath.mpf(float(p[0][a])) * mpmath.mpf(2) ** 24 for a in range(3)]
                    got, _ = RE.angles(w, fmt_dirs[i][None])
                    want = float(oracle.exact_angle(e, f, fmt_dirs[i], point))
                    assert abs(got[0] - want) <= 1e-9 * want + 1e-30, (precision, frame, i, k, got[0], want)

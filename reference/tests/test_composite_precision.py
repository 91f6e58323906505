"""Compositing in f16, bf16 and f32 (composite_precision.py): the stated
transmittance bound holds on every ray of every medium, under every
formulation; the mpmath oracle agrees with f64; and the finding of
docs/precision.md holds: only compensated sums keep f16 within a step in
a long haze."""

import numpy as np
import pytest
from octopaint_ref import composite_precision as CP
from octopaint_ref import precision as PR
from octopaint_ref.camera import pixel_directions


@pytest.fixture(scope="module")
def media():
    arrays = PR.build_scene(paint=True)
    e, f = PR.eye_split()
    rays = PR.rays_from(e, f, pixel_directions(PR.near_camera((16, 16))).reshape(-1, 3))
    return {"scene": CP.scene_segments(arrays, rays), **CP.adversarial_media()}


@pytest.mark.parametrize("fmt", ["f16", "bf16", "f32", "f64"])
@pytest.mark.parametrize("form", CP.FORMS)
def test_every_ray_is_within_the_transmittance_bound(media, fmt, form):
    for name, (x, c) in media.items():
        _, T, end = CP.composite(x, c, fmt, form)
        exact = CP.exact_transmittance(x, end)
        bound = CP.transmittance_bound(x, end, fmt, form)
        err = np.abs(T - exact)
        assert (err <= bound).all(), (name, fmt, form, err[err > bound], bound[err > bound])
        if fmt != "f64":
            assert err.max() > 0, (name, fmt, form)  # measured, not vacuous


def test_the_oracle_agrees_with_f64(media):
    x, c = media["scene"]
    assert (x > 0).sum(axis=1).max() > 5  # rays cross painted cells
    col, T, end = CP.composite(x, c, "f64", "transmittance")
    ecol, eT, eend = CP.exact(x, c)
    assert (end == eend).all()
    assert np.abs(col - ecol).max() < 1e-12 and np.abs(T - eT).max() < 1e-12


def test_only_compensated_sums_keep_f16_within_a_step_in_a_haze(media):
    """4,096 segments of depth 1e-5 .. 1e-3: each colour increment and, in
    the product form, each factor exp(-x) is below half an f16 spacing of
    the running value, so the uncompensated sums stall."""
    x, c = media["haze"]
    ecol, _, _ = CP.exact(x, c)
    steps = {form: np.abs(CP.composite(x, c, "f16", form)[0] - ecol).max() * 255 for form in CP.FORMS}
    assert steps["compensated"] < 1.0, steps
    for form in ("transmittance", "optical-depth", "optical-depth-kahan"):
        assert steps[form] > 10.0, steps


def test_segment_depths_are_formed_before_rounding():
    """sigma up to 1e5 and a depth-24 cell's length (6e-8) do not fit f16
    apart; their product is rounded once, so a dense cell still stops the
    ray and a thin one still lets it through."""
    x = np.array([[1e5 * 6e-8, 1e5 * 1.0], [1e-5 * 6e-8, 0.0]])
    c = np.ones((2, 2, 3))
    _, T, _ = CP.composite(x, c, "f16", "compensated")
    assert T[0] == 0.0 and 0.99 < T[1] <= 1.0

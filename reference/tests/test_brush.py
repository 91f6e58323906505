"""Coverage, blend modes, noise and target depth against hand-computed values."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from octopaint_ref import brush as B
from octopaint_ref.noise import fbm, hash32, perlin, permutation

TOL = {"f64": 1e-12}


def smooth(t):
    return t * t * (3 - 2 * t)


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_capsule_coverage_hand_computed(xp):
    # Capsule from (0,0,0) r=1 to (2,0,0) r=0.5, hardness 0.5, flow 1 -> 0.5.
    p0 = xp.array([[0.0, 0.0, 0.0]])
    p1 = xp.array([[2.0, 0.0, 0.0]])
    r0, r1 = xp.array([1.0]), xp.array([0.5])
    f0, f1 = xp.array([1.0]), xp.array([0.5])
    x = xp.array([[1.0, 0.3, 0.0], [1.0, 0.7, 0.0], [2.0, 0.4, 0.0], [-0.9, 0.0, 0.0], [3.0, 0.0, 0.0]])
    cov = np.asarray(B.capsule_coverage(xp, x, p0, p1, r0, r1, f0, f1, 0.5))[:, 0]
    # x0: u = 0.5, r = 0.75, flow 0.75, rho = 0.4 <= 0.5 -> 1 * 0.75
    # x1: rho = 0.7/0.75, t = (1 - rho)/0.5
    t1 = (1 - 0.7 / 0.75) / 0.5
    # x2: u = 1, r = 0.5, flow 0.5, rho = 0.8 -> t = 0.4
    # x3: u = 0 (clamped), dist 0.9, r = 1, rho 0.9 -> t = 0.2
    want = [0.75, smooth(t1) * 0.75, smooth(0.4) * 0.5, smooth(0.2) * 1.0, 0.0]
    np.testing.assert_allclose(cov, want, rtol=0, atol=1e-12)


def test_hard_brush_edge_is_outside():
    x = np.array([[1.0, 0.0, 0.0], [0.999999, 0.0, 0.0]])
    p = np.zeros((1, 3))
    one = np.ones(1)
    cov = B.capsule_coverage(np, x, p, p, one, one, one, one, 1.0)[:, 0]
    assert list(cov) == [0.0, 1.0]


@pytest.mark.parametrize(
    "shape,point,want_rho",
    [
        # aspect (1, 0.5, 2), r = 2, identity rotation
        ("box", (1.0, 0.5, 2.0), max(1.0 / 2, 0.5 / 1, 2.0 / 4)),
        ("cylinder", (1.2, 0.4, 1.0), max(math.hypot(1.2 / 2, 0.4 / 1), 1.0 / 4)),
        ("cone", (0.6, 0.0, -2.0), max(0.5, 2 * 0.3 + (-0.5))),
        ("cone", (0.2, 0.1, 3.0), max(0.75, 2 * math.hypot(0.1, 0.1) + 0.75)),
    ],
)
def test_stamp_gauges(shape, point, want_rho):
    rho = B.stamp_gauge(np, shape, np.array([point]), np.zeros((1, 3)), np.array([2.0]), np.eye(3)[None], (1.0, 0.5, 2.0))
    assert rho[0, 0] == pytest.approx(want_rho, abs=1e-12)


def test_stamp_rotation_moves_the_shape():
    # A box long along local x, turned 90 degrees about z, is long along canvas y.
    rot = B.quat_to_matrix([0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)])
    np.testing.assert_allclose(rot @ np.array([1.0, 0, 0]), [0, 1, 0], atol=1e-15)
    x = np.array([[0.0, 2.5, 0.0], [2.5, 0.0, 0.0]])
    rho = B.stamp_gauge(np, "box", x, np.zeros((1, 3)), np.array([1.0]), rot[None], (3.0, 1.0, 1.0))
    assert rho[0, 0] < 1 < rho[1, 0]


@pytest.mark.parametrize("shape", ["box", "cylinder", "cone", "noise"])
def test_reach_contains_every_covered_point(shape):
    """A cell whose centre has coverage > 0 is always within reach, and reach
    is monotone: a parent of a cell in reach is in reach."""
    rng = np.random.default_rng(1)
    x = rng.uniform(-3, 3, (4000, 3))
    rot = B.quat_to_matrix([0.2, 0.4, -0.1, 0.9])[None]
    c, r, aspect = np.zeros((1, 3)), np.array([1.3]), (1.5, 0.6, 1.1)
    rho = B.stamp_gauge(np, shape, x, c, r, rot, aspect)
    h = np.full(len(x), 0.05)
    reach = B.stamp_reach(np, shape, x, c, r, rot, aspect, h)[:, 0]
    assert np.all(reach[rho[:, 0] < 1])
    # A ball of radius h around each reached-out point misses the shape:
    # sample the ball and check the gauge stays >= 1 there.
    out = x[~reach][:200]
    for d in rng.normal(size=(50, 3)):
        d = d / np.linalg.norm(d) * 0.05 * rng.uniform()
        assert np.all(B.stamp_gauge(np, shape, out + d, c, r, rot, aspect) >= 1 - 1e-12)


def _blend(mode, before_rgb, before_sigma, colour, a, alpha=0.5, radius=2.0, mix_ratio=1.0):
    sb = float(B.sigma_brush(np, alpha, radius))
    rgb, sigma = B.jax_blend(
        mode,
        jnp.array([before_rgb], jnp.float64),
        jnp.array([before_sigma], jnp.float64),
        jnp.array([colour], jnp.float64),
        sb,
        alpha,
        jnp.array([a], jnp.float64),
        mix_ratio,
    )
    return np.asarray(rgb)[0], float(sigma[0]), sb


def test_sigma_brush_gives_alpha_across_one_radius():
    sb = float(B.sigma_brush(np, 0.5, 2.0))
    assert 1 - math.exp(-sb * 2.0) == pytest.approx(0.5, abs=1e-15)
    assert float(B.sigma_brush(np, 1.0, 1.0)) == pytest.approx(-math.log(1 - 0.999))


def test_paint_lerps_towards_the_brush():
    rgb, sigma, sb = _blend("paint", [0.2, 0.4, 0.6], 1.0, [1.0, 0.0, 0.0], 0.25)
    np.testing.assert_allclose(rgb, [0.2 + 0.8 * 0.25, 0.4 - 0.4 * 0.25, 0.6 - 0.6 * 0.25], atol=1e-15)
    assert sigma == pytest.approx(1.0 + (sb - 1.0) * 0.25, abs=1e-15)


def test_paint_on_empty_takes_the_brush_colour():
    rgb, sigma, sb = _blend("paint", [0.0, 0.0, 0.0], 0.0, [0.9, 0.5, 0.1], 0.3)
    np.testing.assert_allclose(rgb, [0.9, 0.5, 0.1], atol=1e-15)
    assert sigma == pytest.approx(0.3 * sb, abs=1e-15)


def test_erase_scales_sigma_and_keeps_colour():
    rgb, sigma, _ = _blend("erase", [0.2, 0.4, 0.6], 3.0, [1, 1, 1], 0.5, alpha=0.8)
    np.testing.assert_allclose(rgb, [0.2, 0.4, 0.6], atol=1e-15)
    assert sigma == pytest.approx(3.0 * (1 - 0.5 * 0.8), abs=1e-15)
    _, sigma, _ = _blend("erase", [0.2, 0.4, 0.6], 3.0, [1, 1, 1], 1.0, alpha=1.0)
    assert sigma == 0.0


def test_recolor_only_where_there_is_density():
    rgb, sigma, _ = _blend("recolor", [0.2, 0.4, 0.6], 2.0, [1.0, 0.0, 0.0], 0.5, alpha=0.5)
    np.testing.assert_allclose(rgb, [0.2 + 0.8 * 0.25, 0.4 * 0.75, 0.6 * 0.75], atol=1e-15)
    assert sigma == 2.0
    rgb, sigma, _ = _blend("recolor", [0.2, 0.4, 0.6], 0.0, [1.0, 0.0, 0.0], 1.0, alpha=1.0)
    np.testing.assert_allclose(rgb, [0.2, 0.4, 0.6], atol=1e-15)


def test_mix_is_a_density_weighted_average():
    rgb, sigma, sb = _blend("mix", [0.2, 0.4, 0.6], 2.0, [1.0, 0.0, 0.0], 0.5, mix_ratio=0.5)
    wb = 0.5 * 0.5 * sb
    np.testing.assert_allclose(rgb, (2.0 * np.array([0.2, 0.4, 0.6]) + wb * np.array([1.0, 0, 0])) / (2.0 + wb), atol=1e-15)
    assert sigma == pytest.approx(2.0 + 0.5 * sb, abs=1e-15)


@pytest.mark.parametrize("mode", ["paint", "erase", "recolor", "mix", "pickup"])
def test_zero_coverage_leaves_the_cell_alone(mode):
    rgb, sigma, _ = _blend(mode, [0.2, 0.4, 0.6], 0.0, [1.0, 0.0, 0.0], 0.0)
    np.testing.assert_allclose(rgb, [0.2, 0.4, 0.6], atol=0)
    assert sigma == 0.0


def test_quantize_rounds_half_up_and_clamps():
    assert list(B.quantize_rgb(np.array([0.0, 0.5 / 255, 1.4999 / 255, 1.0, 1.2, -0.1]))) == [0, 1, 1, 255, 255, 0]


def test_target_depth():
    # root_size 1: cell size 2^-d <= r/10
    assert list(B.target_depth(np.array([10.0, 1.0, 0.1, 0.05, 1e-12]), 1.0, 24)) == [0, 4, 7, 8, 24]
    # exactly on a boundary: r/10 = 2^-3 -> depth 3
    assert int(B.target_depth(np.array([1.25]), 1.0, 24)[0]) == 3


def test_hash_and_permutation_are_fixed():
    # Values pinned so that a change to the hash or the shuffle is caught;
    # the painter's noise.rs tests pin the same numbers.
    assert [hash32(i) for i in range(4)] == [0, 1753845952, 3507691905, 1408362973]
    p = permutation(0)
    assert sorted(p[:256]) == list(range(256)) and np.array_equal(p[:256], p[256:])
    assert [int(v) for v in p[:8]] == [121, 98, 175, 60, 155, 88, 12, 152]
    assert not np.array_equal(permutation(1), p)


def test_perlin_properties_and_jax_agrees_with_numpy():
    perm = permutation(3)
    lattice = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [-4.0, 7.0, 255.0]])
    assert np.all(perlin(np, perm, lattice) == 0)  # zero at integer points
    rng = np.random.default_rng(0)
    pts = rng.uniform(-50, 50, (2000, 3))
    v = perlin(np, perm, pts)
    assert np.all(np.abs(v) <= 1.04) and v.std() > 0.1
    vj = np.asarray(jax.jit(lambda p: perlin(jnp, jnp.asarray(perm), p))(pts))
    np.testing.assert_allclose(vj, v, rtol=0, atol=1e-13)
    f = fbm(np, perm, pts, 0.3, 4, 0.5)
    assert np.all(np.abs(f) <= 1.04)


def test_capsule_reach_is_monotone_for_tapered_segments():
    """A cell in reach has its parent in reach (spec 8.7), however strongly the
    capsule tapers: otherwise the top-down search misses covered leaves."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        p0 = rng.uniform(0, 1, 3)
        p1 = p0 + rng.uniform(-0.01, 0.01, 3)
        r0, r1 = rng.uniform(0.01, 0.1, 2)
        k = B.capsule_slack(p0, p1, r0, r1)
        size = 2.0 ** -rng.integers(4, 9)
        parent = rng.uniform(-0.2, 1.2, (2000, 3))
        octants = np.array([[(o >> a) & 1 for a in range(3)] for o in range(8)]) - 0.5
        child = (parent[:, None, :] + octants[None] * (size / 2)).reshape(-1, 3)
        def reach(x, s):
            dist, _, r = B.capsule_geometry(np, x, p0[None], p1[None], np.array([r0]), np.array([r1]))  # noqa: B023 (called in this iteration only)
            return (dist - r)[:, 0] <= B.HALF_DIAG * s * k  # noqa: B023 (called in this iteration only)
        child_in = reach(child, size / 2).reshape(-1, 8).any(axis=1)
        assert np.all(reach(parent, size)[child_in])


@pytest.mark.parametrize("shape", ["box", "cylinder", "cone"])
def test_stamp_reach_is_monotone(shape):
    rng = np.random.default_rng(6)
    rot = B.quat_to_matrix([0.1, -0.3, 0.5, 0.8])[None]
    c, r, aspect = np.zeros((1, 3)), np.array([0.3]), (1.0, 0.05, 0.7)
    size = 0.05
    parent = rng.uniform(-0.6, 0.6, (5000, 3))
    octants = np.array([[(o >> a) & 1 for a in range(3)] for o in range(8)]) - 0.5
    child = (parent[:, None, :] + octants[None] * (size / 2)).reshape(-1, 3)
    h = lambda n, s: np.full(n, B.HALF_DIAG * s)
    child_in = B.stamp_reach(np, shape, child, c, r, rot, aspect, h(len(child), size / 2))[:, 0].reshape(-1, 8).any(axis=1)
    assert np.all(B.stamp_reach(np, shape, parent, c, r, rot, aspect, h(len(parent), size))[:, 0][child_in])


def test_mix_on_an_empty_cell_takes_the_brush_colour_even_with_zero_weight():
    rgb, sigma, sb = _blend("mix", [0.0, 0.0, 0.0], 0.0, [0.9, 0.5, 0.1], 0.5, mix_ratio=0.0)
    np.testing.assert_allclose(rgb, [0.9, 0.5, 0.1], atol=1e-15)
    assert sigma == pytest.approx(0.5 * sb, abs=1e-15)


def test_capsule_coverage_bounds_hold_over_the_ball():
    """Spec 8.7, settled leaves: [lo, hi] bounds coverage * flow at every
    point of the ball of radius h, tapered and pressure-varying capsules
    included, and is tight enough to settle a ball deep in a hard core."""
    rng = np.random.default_rng(15)
    k, n, m = 6, 200, 64
    p0 = rng.uniform(-5, 5, (k, 3))
    p1 = p0 + rng.uniform(-4, 4, (k, 3))
    r0 = rng.uniform(0.5, 4, k)
    r1 = rng.uniform(0.5, 4, k)
    f0 = rng.uniform(0, 1, k)
    f1 = rng.uniform(0, 1, k)
    x = rng.uniform(-8, 8, (n, 3))
    h = rng.uniform(0, 2, n)
    for hardness in (0.0, 0.5, 0.9, 1.0):
        lo, hi = B.capsule_coverage_bounds(np, x, h, p0, p1, r0, r1, f0, f1, hardness)
        assert np.all(lo <= hi)
        d = rng.normal(size=(n, m, 3))
        d *= (h[:, None] * rng.uniform(0, 1, (n, m)) ** (1 / 3) / np.linalg.norm(d, axis=2))[:, :, None]
        pts = (x[:, None, :] + d).reshape(-1, 3)
        cov = B.capsule_coverage(np, pts, p0, p1, r0, r1, f0, f1, hardness).reshape(n, m, k)
        assert np.all(cov >= lo[:, None, :] - 1e-12)
        assert np.all(cov <= hi[:, None, :] + 1e-12)
    one = np.ones(1)
    lo, hi = B.capsule_coverage_bounds(np, np.zeros((1, 3)), np.array([0.5]), np.zeros((1, 3)), np.zeros((1, 3)), 4 * one, 4 * one, one, one, 0.9)
    assert lo[0, 0] == hi[0, 0] == 1.0


def test_open_starts_follow_capsules_that_do_not_grow():
    """A sphere stroke's capsules after the first have open starts (spec 8.3)
    while the radius and flow do not grow along the previous capsule; a
    repeated sample (no segment) keeps its start."""
    from octopaint_ref.stroke import StrokePath
    from octopaint_ref.trace import Brush, Sample

    path = StrokePath(Brush("sphere", "paint", 0.1, (1, 0, 0), 1.0, 0.5))
    opens = []
    for p, pressure in [((0.5, 0.5, 0.5), 1.0), ((0.52, 0.5, 0.5), 1.0), ((0.54, 0.5, 0.5), 0.8),
                        ((0.56, 0.5, 0.5), 0.9), ((0.58, 0.5, 0.5), 0.9), ((0.58, 0.5, 0.5), 0.9)]:
        opens.append(bool(path.segment(Sample(p, pressure), np.ones(3)).arrays["open"][0]))
    # sphere; after the sphere; after a constant one; after a shrinking one;
    # after a growing one; no segment.
    assert opens == [False, True, True, True, False, False]


def test_an_open_start_is_covered_by_the_capsule_before():
    """Behind an open start the capsule covers nothing, and the capsule
    before it covers those points at least as much as the closed capsule
    would: the stroke maximum is the same but for the last bits."""
    rng = np.random.default_rng(7)
    for _ in range(50):
        pa, pb, pc = rng.uniform(-4, 4, (3, 3))
        ra, rb, rc = 1.0 + rng.uniform(), 0.5 + 0.5 * rng.uniform(), 0.5 + rng.uniform()
        fa, fb, fc = 0.5 + 0.5 * rng.uniform(), 0.5 * rng.uniform(), rng.uniform()
        p0, p1 = np.array([pa, pb]), np.array([pb, pc])
        r0, r1, f0, f1 = np.array([ra, rb]), np.array([rb, rc]), np.array([fa, fb]), np.array([fb, fc])
        x = pb + rng.uniform(-3, 3, (400, 3))
        closed = B.capsule_coverage(np, x, p0, p1, r0, r1, f0, f1, 0.3)
        opened = B.capsule_coverage(np, x, p0, p1, r0, r1, f0, f1, 0.3, np.array([False, True]))
        t = B.capsule_t(np, x, p0, p1)
        behind = t[:, 1] < 0
        assert behind.any() and (~behind).any()
        assert np.all(opened[behind, 1] == 0.0)
        assert np.array_equal(opened[~behind], closed[~behind])
        assert np.all(closed[behind, 0] >= closed[behind, 1] - 1e-12)
        np.testing.assert_allclose(opened.max(axis=1), closed.max(axis=1), rtol=0, atol=1e-12)

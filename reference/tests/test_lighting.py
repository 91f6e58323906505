"""Lighting (spec 6.1): what a cell sees across its faces at depth changes,
the shading weight and normal, the `light` event, shadows that only take
light away, lighting off giving the unlit pixels, and gradients through it."""

import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import TRACES
from octopaint_ref import raycast, shading
from octopaint_ref.dump import tree_arrays
from octopaint_ref.replay import replay
from octopaint_ref.trace import Camera, Light, TraceError, parse_trace, read_trace
from octopaint_ref.tree import Tree

H = '{"format": "ddo-trace", "version": 1, "canvas": {"roots": [1, 1, 1], "max_depth": 4, "root_size": 1.0, "capacity": 4096}}'


def _device(t: Tree):
    return raycast.device_tree(tree_arrays(t))


class _Centre:
    """Every cell's factors at its centre from its exact (unquantised)
    vector: the formulas of spec 6.1 "Gradient, weight, normal"."""

    def __init__(self, tree, canvas, light):
        self.a0, self.a1 = shading.centre_factors(shading.shading(tree, canvas, light, exact=True))


def test_faces_across_depth_changes():
    """Roots (2, 1, 1), root 0 refined: root 1 sees root 0's four children
    on the shared face at 3/4; a child on that face sees root 1 (coarser)
    at 3/2; a sibling at 1; outside the canvas an empty cell at 1."""
    t = Tree((2, 1, 1), 3, 1.0, 1024)
    t.refine_round(np.array([0]))
    fc = int(t.first_child[0])
    for k in range(8):
        t.sigma[fc + k] = 1.0 + k
    t.sigma[1] = 20.0
    tree, canvas = _device(t)
    s_lo, h_lo = (np.asarray(v) for v in shading._face(tree, canvas, 0, -1))
    s_hi, h_hi = (np.asarray(v) for v in shading._face(tree, canvas, 0, 1))
    # Root 1 looks back (-x) at the children with x bit 1: 2, 4, 6, 8.
    assert (s_lo[1], h_lo[1]) == (((2.0 + 4.0) + (6.0 + 8.0)) / 4, 0.75)
    # Child 1 (x bit 1) looks out (+x) at root 1, coarser.
    assert (s_hi[fc + 1], h_hi[fc + 1]) == (20.0, 1.5)
    # Child 0 looks in (+x) at its sibling 1, and out (-x) at nothing.
    assert (s_hi[fc], h_hi[fc]) == (2.0, 1.0)
    assert (s_lo[fc], h_lo[fc]) == (0.0, 1.0)
    # Root 1 looks out of the canvas (+x).
    assert (s_hi[1], h_hi[1]) == (0.0, 1.0)


def _cube(sigma=1.0):
    """3 x 3 x 3 roots of equal sigma: the centre sees paint all round, the
    one at x = 2, y = z = 1 has nothing beyond its +x face."""
    t = Tree((3, 3, 3), 2, 1.0, 4096)
    t.sigma[:27] = sigma
    t.rgb[:27] = (200, 100, 50)
    return _device(t)


def test_even_paint_is_unlit_and_a_surface_faces_out():
    tree, canvas = _cube()
    towards = _Centre(tree, canvas, Light(dir=(1.0, 0.0, 0.0), intensity=0.8, ambient=0.3))
    away = _Centre(tree, canvas, Light(dir=(-2.0, 0.0, 0.0), intensity=0.8, ambient=0.3))
    centre, side = 13, 2 + 3 * (1 + 3 * 1)
    assert float(towards.a0[centre]) == 1.0 and float(towards.a1[centre]) == 0.0
    # The +x side: delta_x = (0 - 1)/2, the normal +x: fully lit (r = 1/2).
    assert float(towards.a0[side]) == pytest.approx(0.3)
    assert float(towards.a1[side]) == pytest.approx(0.8)
    assert float(away.a1[side]) == 0.0 and float(away.a0[side]) == pytest.approx(0.3)


def test_the_weight_ramps_with_the_relative_gradient():
    """r = g / m: a 1% step is past the unlit end of the ramp but not fully
    lit; a 0.2% step stays unlit (spec 6.1: 0.004 to 0.02)."""
    for step, lit in ((0.004, None), (0.02, 0.75), (0.1, 1.0)):
        t = Tree((3, 1, 1), 2, 1.0, 4096)
        t.sigma[:3] = (1.0 - step, 1.0, 1.0 + step)
        tree, canvas = _device(t)
        f = _Centre(tree, canvas, Light(dir=(0.0, 1.0, 0.0), intensity=1.0, ambient=0.0))
        # cell 1: delta_x = 2 step / 2, m = 1 + step
        r = step / (1.0 + step)
        w = min(max((r - shading.R_UNLIT) / (shading.R_LIT - shading.R_UNLIT), 0.0), 1.0)
        assert float(f.a0[1]) == pytest.approx(1.0 - w, rel=1e-4)  # sigma is stored in f32
        if lit is None:
            assert w == 0.0
        else:
            assert w > 0.0


def test_light_events_are_read_with_defaults_and_refused_when_bad():
    t = parse_trace("\n".join([H, '{"ev": "light", "t": 0, "dir": [0, 2, 0]}', '{"ev": "light", "t": 1, "on": false, "dir": "ignored"}']))
    a, b = (e.value for e in t.events)
    assert a == Light(True, (0.0, 2.0, 0.0), 0.8, 0.3, False)
    assert b == Light(on=False)
    for line, kind in (
        ('{"ev": "light", "t": 0, "dir": [0, 0, 1e-13]}', "range"),
        ('{"ev": "light", "t": 0, "dir": [0, 1, 0], "ambient": 2}', "range"),
        ('{"ev": "light", "t": 0, "on": 1, "dir": [0, 1, 0]}', "type"),
        ('{"ev": "light", "t": 0, "dir": [0, 1]}', "type"),
    ):
        with pytest.raises(TraceError) as e:
            parse_trace(H + "\n" + line)
        assert (e.value.line, e.value.kind) == (2, kind)


@pytest.fixture(scope="module")
def lit_scene():
    trace = read_trace(os.path.join(TRACES, "lit.jsonl"))
    images = {}
    stats = replay(trace, None, on_render=lambda name, img: images.setdefault(name, img))
    return tree_arrays(stats.painting.tree), trace, images


def test_lighting_changes_the_picture_and_off_restores_it(lit_scene):
    _, _, images = lit_scene
    unlit, lit, off = (images[n].image.astype(int) for n in ("lit_unlit", "lit_lambert", "lit_off"))
    assert np.array_equal(unlit, off)
    assert (np.abs(unlit - lit).max(axis=-1) > 8).sum() > 2000


def test_shadows_only_take_light_away(lit_scene):
    arrays, trace, _ = lit_scene
    cam = next(e.value for e in trace.events if e.kind == "camera")
    light = Light(True, (-0.5, 1.0, 0.2), 1.2, 0.2, False)
    plain = raycast.render(arrays, cam, light=light).colour
    shaded = raycast.render(arrays, cam, light=Light(**{**light.__dict__, "shadows": True})).colour
    assert np.all(shaded <= plain + 1e-12)
    # The ball's shadow on the slab: a sizeable patch loses over a third.
    assert ((plain - shaded).max(axis=-1) > 0.3 * plain.max(axis=-1)).sum() > 500


def test_lit_pixels_are_differentiable_in_sigma_and_the_light():
    """diffrender.composite with the shading factors gives the ray caster's
    lit colours (no shadows), and reverse-mode gradients through the normals
    and the light's intensity."""
    from octopaint_ref import diffrender

    tree, canvas = _cube(3.0)
    cam = Camera((1.2, 1.9, 5.0), (0.0, 0.0, 0.0, 1.0), (-0.3, 0.3, 0.3, -0.3), (6, 6))
    rays = raycast.camera_rays(cam, canvas)
    light = Light(dir=(0.3, 0.4, 1.0), intensity=0.8, ambient=0.2)
    s, _ = raycast.cast(tree, canvas, rays, light=light)
    paths = diffrender.record_paths(tree, canvas, rays)

    def colours(sigma, intensity):
        f = shading.shading(tree._replace(sigma=sigma), canvas, Light(dir=light.dir, intensity=intensity, ambient=light.ambient))
        return diffrender.composite(tree.rgb, sigma, paths, jnp.asarray(paths.p0), rays.dir_canvas, canvas, jnp.zeros(3), f)

    assert np.allclose(np.asarray(colours(tree.sigma, 0.8)), s.colour, atol=1e-12)
    g_sigma, g_int = jax.grad(lambda a, b: colours(a, b).sum(), argnums=(0, 1))(tree.sigma, 0.8)
    assert np.all(np.isfinite(np.asarray(g_sigma))) and np.isfinite(float(g_int))
    assert float(g_int) > 0  # the front faces the light
    # Through the normals: sigma of cells the rays never composite (the
    # back row) still moves the lit front through the gradient.
    assert np.abs(np.asarray(g_sigma)[18:27]).max() > 0


def test_stored_vectors_are_quantised_to_511ths_and_packed_in_one_word():
    """Spec 6.1: floor(v 511 + 1/2) clamped to +-511, offset by 512, ten
    bits a component; decoding gives the quantised vector back."""
    v = np.array([[0.0, 0.0, 0.0], [0.5, -0.5, 1.0], [-1.0, 2.0, 1.0 / 1022.0], [0.25, -0.001, -0.999]])
    words = shading.pack(v)
    assert int(words[0]) == 512 | 512 << 10 | 512 << 20
    # 0.5 * 511 = 255.5 rounds up, -255.5 rounds up too; 2 clamps at 511.
    assert [((int(words[1]) >> (10 * a)) & 1023) - 512 for a in range(3)] == [256, -255, 511]
    assert [((int(words[2]) >> (10 * a)) & 1023) - 512 for a in range(3)] == [-511, 511, 1]
    assert all(int(w) >> 30 == 0 for w in words)
    back = shading.unpack(words)
    assert np.array_equal(back, np.asarray(shading.quantise(jnp.asarray(v))) / 511.0)
    assert np.abs(back - np.clip(v, -1, 1)).max() <= 0.5 / 511 + 1e-15


def test_the_vector_is_interpolated_across_the_leaf():
    """Spec 6.1: a leaf's own vector at its centre; at the centre of the
    face two same-depth leaves share, the mean of both, from either side;
    towards a coarser neighbour at 3/2; nothing beyond the canvas."""
    t = Tree((4, 1, 1), 2, 1.0, 4096)
    t.sigma[:4] = (1.0, 1.0, 1.006, 1.02)  # cell 1 unlit, cell 2 partly lit
    t.refine_round(np.array([3]))
    tree, canvas = _device(t)
    li = shading.shading(tree, canvas, Light(dir=(-1.0, 0.2, 0.1), intensity=0.9, ambient=0.25))
    v = np.asarray(li.v)
    assert np.abs(v[1]).max() == 0.0 and 0.2 < -v[2][0] < 0.8

    def at(cell, mu):
        mu = jnp.asarray(mu, jnp.float64)
        f = shading.sides(mu)
        nb = jnp.take_along_axis(li.nb[cell], f, axis=-1)
        return np.asarray(shading.mix(li.v[cell], li.v[nb], jnp.take_along_axis(li.inv_h[cell], f, axis=-1), mu))

    assert np.array_equal(at(1, [0.0, 0.0, 0.0]), v[1])
    assert np.allclose(at(1, [0.5, 0.0, 0.0]), (v[1] + v[2]) / 2, atol=1e-15)
    assert np.allclose(at(2, [-0.5, 0.0, 0.0]), (v[1] + v[2]) / 2, atol=1e-15)
    # Root 2 to the refined root 3: a same-depth cell with children, its own vector at 1.
    assert np.allclose(at(2, [0.25, 0.0, 0.0]), v[2] + 0.25 * (v[3] - v[2]), atol=1e-15)
    # A child of root 3 on its -x face sees root 2, one coarser, at 3/2.
    fc = int(t.first_child[3])
    assert np.allclose(at(fc, [-0.5, 0.0, 0.0]), v[fc] + (0.5 / 1.5) * (v[2] - v[fc]), atol=1e-15)
    # Beyond the canvas (-y of root 1): no term.
    assert np.array_equal(at(1, [0.0, -0.4, 0.0]), v[1])
    # The factors at the centre are the spec's centre formulas of the stored vector.
    a0, a1 = shading.factors(li, jnp.asarray(1), jnp.zeros(3))
    c0, c1 = shading.centre_factors(li)
    assert float(a0) == float(c0[1]) and float(a1) == float(c1[1])

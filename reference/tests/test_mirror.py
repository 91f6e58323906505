"""Mirror painting (spec 8.11): the copies of a stroke, the exact mirror
image of a stroke at dyadic positions through a lattice plane, the reader's
field, and undo of a mirrored stroke as one step."""

import os

import numpy as np
import pytest
from conftest import TRACES
from octopaint_ref.brush import mirrored
from octopaint_ref.dump import tree_arrays
from octopaint_ref.replay import replay
from octopaint_ref.stroke import StrokePath
from octopaint_ref.trace import Brush, Mirror, Sample, TraceError, parse_trace, read_trace

H = '{"format": "ddo-trace", "version": 1, "canvas": {"roots": [1, 1, 1], "max_depth": 4, "root_size": 1.0, "capacity": 4096}}'


def test_copies_are_every_combination_of_the_axes_in_order():
    assert Mirror((True, False, False), (0, 0, 0)).copies() == (1,)
    assert Mirror((True, False, True), (0, 0, 0)).copies() == (1, 4, 5)
    assert Mirror((True, True, True), (0, 0, 0)).copies() == (1, 2, 3, 4, 5, 6, 7)
    assert Mirror((False, False, False), (0, 0, 0)).copies() == ()


def test_a_copy_is_placed_mirrored_and_turned_as_a_mirror_image():
    b = Brush("box", "paint", 0.1, (1, 0, 0), 1.0, 0.5, mirror=Mirror((True, False, True), (0.5, 0.25, 0.5)))
    q = (0.2, 0.3, 0.1, 0.9)
    orig = StrokePath(b, 0).segment(Sample((0.3, 0.1, 0.6), 1.0, q), np.ones(3))
    copy = StrokePath(b, 5).segment(Sample((0.3, 0.1, 0.6), 1.0, q), np.ones(3))
    assert np.allclose(copy.arrays["c"][0], [0.7, 0.1, 0.4], atol=1e-15)
    assert np.array_equal(copy.arrays["c"][0], mirrored(orig.arrays["c"][0], 5, (0.5, 0.25, 0.5)))
    r, rc = orig.arrays["rot"][0], copy.arrays["rot"][0]
    assert np.array_equal(rc, r * np.array([-1.0, 1.0, -1.0])[:, None])
    # Two planes make a half turn (det +1); one, or three, a mirror image.
    assert np.linalg.det(rc) == pytest.approx(1.0)
    one = StrokePath(b, 1).segment(Sample((0.3, 0.1, 0.6), 1.0, q), np.ones(3))
    assert np.linalg.det(one.arrays["rot"][0]) == pytest.approx(-1.0)
    assert list(copy.arrays["m"]) == [5]


def test_mirror_events_are_read_and_refused_when_bad():
    t = parse_trace(H + "\n" + '{"ev": "mirror", "t": 0, "axes": [true, false, true], "centre": [0.5, 1, 2]}')
    assert t.events[0].value == Mirror((True, False, True), (0.5, 1.0, 2.0))
    br = '{"ev": "brush", "t": 0, "shape": "sphere", "mode": "paint", "radius": 0.1, "color": [1, 0, 0], "opacity": 1, "hardness": 0.5}'
    for lines, kind in (
        (['{"ev": "mirror", "t": 0, "axes": [true], "centre": [0, 0, 0]}'], "type"),
        (['{"ev": "mirror", "t": 0, "axes": [1, 0, 0], "centre": [0, 0, 0]}'], "type"),
        (['{"ev": "mirror", "t": 0, "axes": [true, true, true]}'], "missing"),
        (['{"ev": "mirror", "t": 0, "axes": [true, true, true], "centre": [0, "x", 0]}'], "type"),
        ([br, '{"ev": "stroke_begin", "t": 0}', '{"ev": "mirror", "t": 0, "axes": [true, true, true], "centre": [0, 0, 0]}'], "event-order"),
    ):
        with pytest.raises(TraceError) as e:
            parse_trace("\n".join([H] + lines))
        assert (e.value.line, e.value.kind) == (1 + len(lines), kind), lines


@pytest.fixture(scope="module")
def snapshots():
    out = {}
    replay(read_trace(os.path.join(TRACES, "mirror.jsonl")), None, on_snapshot=lambda name, p: out.setdefault(name, tree_arrays(p.tree)))
    return out


def _leaves(arrays):
    """(depth, origin) -> (rgb, sigma) of every leaf."""
    d, fc, o = arrays["depth"], arrays["first_child"], arrays["origin"]
    live = (d != 255) & (fc == 0xFFFF_FFFF)
    return {(int(d[c]), tuple(int(v) for v in o[c])): (tuple(arrays["rgb"][c]), float(arrays["sigma"][c])) for c in np.nonzero(live)[0]}


def test_a_stroke_at_dyadic_points_through_a_lattice_plane_is_its_own_mirror_image(snapshots):
    a = snapshots["mirror_x"]
    D = int(a["max_depth"])
    extent = int(np.asarray(a["roots"]).reshape(-1)[0]) << D
    leaves = _leaves(a)
    painted = [k for k, v in leaves.items() if v[1] > 0]
    assert len(painted) > 1000
    for (d, o), v in leaves.items():
        size = 1 << (D - d)
        m = (d, (extent - o[0] - size, o[1], o[2]))
        assert leaves.get(m) == v, f"leaf {d, o} holds {v}, its mirror image {m} holds {leaves.get(m)}"


def test_undo_takes_back_every_copy_at_once(snapshots):
    a, b = snapshots["mirror_mixed"], snapshots["mirror_undone"]
    for k in ("parent", "first_child", "depth", "origin", "rgb", "sigma"):
        assert np.array_equal(a[k], b[k]), k

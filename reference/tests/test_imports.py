"""Imports (spec 15): voxel sets read and checked, painted with the stroke
machinery (the value at every leaf's centre, settled blocks left whole),
one undo step, independent of the order of the voxels."""

import numpy as np
import pytest
from octopaint_ref.check import check_arrays
from octopaint_ref.dump import tree_arrays
from octopaint_ref.paint import Painting
from octopaint_ref.trace import Brush, Canvas, Sample, TraceError, parse_trace
from octopaint_ref.voxelset import VoxelSet, parse, sha256, write_bytes

CANVAS = Canvas((2, 1, 1), 6, 1.0, 1 << 20)


def _same(a, b):
    return all(np.array_equal(a[k], b[k]) for k in ("parent", "first_child", "depth", "rgb", "origin")) and np.array_equal(
        a["sigma"].view(np.uint32), b["sigma"].view(np.uint32)
    )


def _painted():
    p = Painting(CANVAS)
    for c, r, col in (((0.6, 0.5, 0.5), 0.2, (0.9, 0.2, 0.1)), ((1.3, 0.4, 0.6), 0.05, (0.1, 0.8, 0.3))):
        p.begin_stroke(Brush("sphere", "paint", r, col, 0.9, 0.5))
        p.add_sample(Sample(c))
        p.end_stroke()
    return p


def _random_set(rng, depth, n, values=4):
    ext = np.array(CANVAS.roots) << depth
    ijk = np.unique(rng.integers(0, ext, size=(n, 3)), axis=0).astype(np.uint32)
    palette_rgb = rng.integers(0, 256, size=(values, 3)).astype(np.uint8)
    palette_sigma = np.array([0.0, 2.5, 7.0, 40.0][:values], np.float32)
    pick = rng.integers(0, values, size=len(ijk))
    return VoxelSet(depth, ijk, palette_rgb[pick], palette_sigma[pick])


@pytest.mark.parametrize("depth", [2, 4, 6])
def test_every_leaf_holds_its_centre_voxel_or_its_value_before(depth):
    rng = np.random.default_rng(depth)
    p = _painted()
    old = {k: getattr(p.tree, k).copy() for k in ("parent", "first_child", "depth", "rgb", "sigma", "origin")}
    old_n = p.tree.n_used
    vs = _random_set(rng, depth, 300)
    p.import_voxels(vs)
    t = p.tree
    assert check_arrays(tree_arrays(t)) == []
    lookup = {tuple(q): i for i, q in enumerate(vs.ijk.tolist())}
    D = t.max_depth
    n = t.n_used
    leaves = np.nonzero((t.depth[:n] != 255) & (t.first_child[:n] == 0xFFFFFFFF))[0]
    for c in leaves.tolist():
        e = int(t.depth[c])
        o = t.origin[c].astype(np.int64)
        centre = o + ((1 << (D - e - 1)) if e < D else 0)
        q = tuple((o if e >= depth else centre) >> (D - depth))
        if q in lookup:
            i = lookup[q]
            want = (vs.rgb[i], vs.sigma[i:i + 1].view(np.uint32)[0])
        else:
            # The pre-import leaf holding the centre.
            pt = centre if e < D else o
            r = pt >> D
            cell = int(r[0] + CANVAS.roots[0] * (r[1] + CANVAS.roots[1] * r[2]))
            while old["first_child"][cell] != 0xFFFFFFFF:
                d = int(old["depth"][cell])
                k = sum(1 << a for a in range(3) if pt[a] - int(old["origin"][cell][a]) >= 1 << (D - d - 1))
                cell = int(old["first_child"][cell]) + k
            want = (old["rgb"][cell], old["sigma"][cell : cell + 1].view(np.uint32)[0])
        assert t.sigma[c : c + 1].view(np.uint32)[0] == want[1], (c, e)
        if want[1] != 0:
            # An empty leaf's rgb is whatever cleaning kept (octant 0's, spec 9).
            assert np.array_equal(t.rgb[c], want[0]), (c, e)
    # One undo step, byte for byte.
    after = tree_arrays(t)
    p.undo()
    assert t.n_used == old_n
    for k, v in old.items():
        assert np.array_equal(getattr(t, k)[:old_n], v[:old_n]), k
    p.redo()
    assert _same(tree_arrays(t), after)


def test_the_order_of_the_voxels_does_not_matter():
    rng = np.random.default_rng(7)
    vs = _random_set(rng, 5, 500)
    perm = rng.permutation(len(vs))
    shuffled = VoxelSet(vs.depth, vs.ijk[perm], vs.rgb[perm], vs.sigma[perm])
    a, b = _painted(), _painted()
    a.import_voxels(vs)
    b.import_voxels(shuffled)
    assert _same(tree_arrays(a.tree), tree_arrays(b.tree))


def test_a_uniform_block_is_settled_and_never_refined():
    """A whole root of one value at depth 4 on an empty canvas: the root is
    settled, no cell is made, and the root takes the value."""
    ijk = np.stack(np.meshgrid(*(np.arange(16),) * 3, indexing="ij"), -1).reshape(-1, 3).astype(np.uint32)
    vs = VoxelSet(4, ijk, np.tile(np.array([[10, 20, 30]], np.uint8), (len(ijk), 1)), np.full(len(ijk), 3.0, np.float32))
    p = Painting(CANVAS)
    p.import_voxels(vs)
    assert p.tree.n_used == 8  # the two roots and their padding only
    assert p.tree.rgb[0].tolist() == [10, 20, 30] and p.tree.sigma[0] == np.float32(3.0)
    assert p.tree.sigma[1] == 0
    # Half the root of that value, the rest empty as before: refined once
    # (the root's centre voxel is in the set), then the blocks are settled.
    half = ijk[ijk[:, 0] >= 8]
    q = Painting(CANVAS)
    q.import_voxels(VoxelSet(4, half, vs.rgb[: len(half)], vs.sigma[: len(half)]))
    t = q.tree
    assert t.n_used == 16 and t.first_child[0] == 8
    assert [int(t.sigma[8 + k] > 0) for k in range(8)] == [0, 1, 0, 1, 0, 1, 0, 1]


def test_voxel_sets_are_checked():
    good = write_bytes(2, [[1, 1, 1], [2, 0, 3]], [[1, 2, 3], [4, 5, 6]], [1.0, 0.0])
    vs = parse(good, CANVAS)
    assert vs.depth == 2 and len(vs) == 2
    bad = {
        "deeper": write_bytes(7, [[0, 0, 0]], [[1, 2, 3]], [1.0]),
        "outside": write_bytes(2, [[8, 0, 0]], [[1, 2, 3]], [1.0]),
        "twice": write_bytes(2, [[1, 1, 1], [1, 1, 1]], [[1, 2, 3], [1, 2, 3]], [1.0, 2.0]),
        "inf": write_bytes(2, [[1, 1, 1]], [[1, 2, 3]], [np.inf]),
        "minus zero": write_bytes(2, [[1, 1, 1]], [[1, 2, 3]], [-0.0]),
        "truncated": good[: len(good) // 2],
    }
    for why, data in bad.items():
        with pytest.raises(ValueError):
            parse(data, CANVAS)
        assert why


def test_the_reader_checks_the_file_and_its_digest(tmp_path):
    data = write_bytes(3, [[1, 1, 1]], [[9, 9, 9]], [4.0])
    (tmp_path / "v.npz").write_bytes(data)
    head = '{"format": "ddo-trace", "version": 1, "canvas": {"roots": [2, 1, 1], "max_depth": 6, "root_size": 1.0, "capacity": 4096}}\n'
    files = {"v.npz": data}

    def resolve(f):
        if f not in files:
            raise FileNotFoundError(2, "No such file")
        return files[f]

    ok = parse_trace(head + '{"ev": "import", "t": 0, "file": "v.npz", "sha256": "' + sha256(data) + '", "name": "v"}\n', resolve)
    (ev,) = ok.events
    assert ev.kind == "import" and ev.value.voxels.depth == 3 and ev.value.name == "v"
    with pytest.raises(TraceError) as e:
        parse_trace(head + '{"ev": "import", "t": 0, "file": "v.npz", "sha256": "' + "0" * 64 + '"}\n', resolve)
    assert (e.value.line, e.value.kind) == (2, "import")
    with pytest.raises(TraceError) as e:
        parse_trace(head + '{"ev": "import", "t": 0, "file": "v.npz", "sha256": "' + sha256(data) + '"}\n', None)
    assert (e.value.line, e.value.kind) == (2, "import")

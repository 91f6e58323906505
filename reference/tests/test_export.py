"""`octopaint-ref export`: the painting resampled at an export depth, as
regions (octopaint_ref/export.py; the painter's twin is
painter/export/src/values.rs and voxels.rs).

A hand-built tree with every case worked out by hand (a leaf coarser than E,
leaves at E, a cell with children aggregated at E, empty leaves skipped,
linear and sRGB colour, the default depth), the command's refusals, and
replayed traces checked for invariants and against a literal port of the
painter's walk."""

import json
import os
import stat
import subprocess
import sys
from fractions import Fraction

import numpy as np
import pytest
from conftest import TRACES
from octopaint_ref.cli import main
from octopaint_ref.dump import dump_bytes, load_dump, tree_arrays, write_atomic
from octopaint_ref.export import (
    ExportError,
    active_voxels,
    deepest_addressable,
    default_depth,
    export_regions,
    load_export,
    load_input,
    region_values,
    srgb_to_linear,
)
from octopaint_ref.g3 import g3_from_links
from octopaint_ref.trace import TraceError, read_trace

NONE = 0xFFFF_FFFF


# ------------------------------------------------------------------ builder
class Builder:
    """A tree built by hand: roots, then units of eight children allocated
    in call order, each child at its octant (k: bit 0 x, bit 1 y, bit 2 z)."""

    def __init__(self, roots, max_depth, root_size=1.0):
        self.roots, self.d, self.root_size = tuple(roots), max_depth, root_size
        nr = roots[0] * roots[1] * roots[2]
        n = (nr + 7) // 8 * 8
        self.parent = [NONE] * n
        self.first_child = [NONE] * n
        self.depth = [255] * n
        self.rgb = [(0, 0, 0)] * n
        self.sigma = [0.0] * n
        self.origin = [(NONE, NONE, NONE)] * n
        for r in range(nr):
            xyz = (r % roots[0], (r // roots[0]) % roots[1], r // (roots[0] * roots[1]))
            self.depth[r] = 0
            self.origin[r] = tuple(v << max_depth for v in xyz)

    def split(self, c):
        """Give cell c eight children; returns the first one's index."""
        fc = len(self.parent)
        d = self.depth[c]
        half = 1 << (self.d - d - 1)
        for k in range(8):
            self.parent.append(c)
            self.first_child.append(NONE)
            self.depth.append(d + 1)
            self.rgb.append((0, 0, 0))
            self.sigma.append(0.0)
            self.origin.append(tuple(o + ((k >> a) & 1) * half for a, o in enumerate(self.origin[c])))
        self.first_child[c] = fc
        return fc

    def paint(self, c, sigma, rgb):
        self.sigma[c] = sigma
        self.rgb[c] = rgb

    def arrays(self):
        a = {
            "parent": np.array(self.parent, np.uint32),
            "first_child": np.array(self.first_child, np.uint32),
            "depth": np.array(self.depth, np.uint8),
            "rgb": np.array(self.rgb, np.uint8).reshape(-1, 3),
            "sigma": np.array(self.sigma, np.float32),
            "origin": np.array(self.origin, np.uint32).reshape(-1, 3),
            "roots": np.array(self.roots, np.uint32),
            "max_depth": np.array(self.d, np.uint32),
            "root_size": np.array(self.root_size, np.float64),
        }
        a["g3"] = g3_from_links(a["parent"], a["first_child"], a["depth"], self.roots)
        return a


def hand_tree():
    """Two roots side by side (D = 4, root_size 2):

    root 0 ─ 8 (k0) ─ 16 (k0) ─ 24 (k0): sigma 8, red        depth 3
             │        │       └ 31 (k7) ─ 39 (k7): sigma 64, blue   depth 4
             │        │                   (32..38 empty)
             │        ├ 17 (k1): sigma 1.5, (10, 20, 30)     depth 2
             │        ├ 23 (k7): sigma 0.25, white           depth 2
             │        └ 18..22 empty (25..30 green, empty)
             ├ 9 (k1) ─ 40..47: all empty                    depth 2
             ├ 10 (k2): sigma 3, (0, 128, 255)               depth 1
             └ 11..15 empty
    root 1: leaf, sigma 0.5, (255, 0, 51)
    """
    b = Builder((2, 1, 1), 4, 2.0)
    assert b.split(0) == 8
    assert b.split(8) == 16
    assert b.split(16) == 24
    assert b.split(31) == 32
    assert b.split(9) == 40
    b.paint(1, 0.5, (255, 0, 51))
    b.paint(24, 8.0, (255, 0, 0))
    for c in range(25, 31):
        b.paint(c, 0.0, (0, 255, 0))  # empty: must not pale the aggregate
    b.paint(39, 64.0, (0, 0, 255))
    b.paint(17, 1.5, (10, 20, 30))
    b.paint(23, 0.25, (255, 255, 255))
    b.paint(10, 3.0, (0, 128, 255))
    return b.arrays()


def lin(v):
    """sRGB decoding written out, one value."""
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


def f32(x):
    return np.array(x, np.float64).astype(np.float32)


# ------------------------------------------------------------------ hand tree
def test_hand_tree_at_depth_2_srgb():
    out = export_regions(hand_tree(), 2, "srgb")
    # Walk order: 16 (aggregate), 17, 23 (at E), 10 (k = 1), root 1 (k = 2);
    # 18..22, 40..47, 11..15 are empty and skipped.
    assert out["origin"].dtype == np.int32 and out["origin"].tolist() == [
        [0, 0, 0],
        [1, 0, 0],
        [1, 1, 1],
        [0, 2, 0],
        [4, 0, 0],
    ]
    assert out["log2_edge"].dtype == np.uint8 and out["log2_edge"].tolist() == [0, 0, 0, 1, 2]
    # Cell 16: leaf 24 (sigma 8, weight 1/8) and leaf 39 (sigma 64, weight
    # 1/64); the six empty green leaves weigh nothing in the colour.
    assert out["density"].dtype == np.float32
    assert out["density"].tolist() == [2.0, 1.5, 0.25, 3.0, 0.5]
    assert out["color"].dtype == np.float32
    want = [(0.5, 0.0, 0.5), (10 / 255, 20 / 255, 30 / 255), (1.0, 1.0, 1.0), (0.0, 128 / 255, 1.0), (1.0, 0.0, 51 / 255)]
    np.testing.assert_array_equal(out["color"], f32(want))
    assert out["depth"].dtype == np.uint32 and int(out["depth"]) == 2
    assert out["voxel_size"].dtype == np.float64 and float(out["voxel_size"]) == 0.5
    assert str(out["colour_space"]) == "srgb" and out["colour_space"].dtype.kind == "U"
    assert active_voxels(out["log2_edge"]) == 1 + 1 + 1 + 8 + 64


def test_hand_tree_linear_colour():
    srgb = export_regions(hand_tree(), 2, "srgb")
    out = export_regions(hand_tree(), 2, "linear")
    assert str(out["colour_space"]) == "linear"
    for key in ("origin", "log2_edge", "density"):
        np.testing.assert_array_equal(out[key], srgb[key])
    # 10/255 is below the knee (linear segment), 20/255 and up on the power
    # curve; 0.5 decodes to 0.21404.
    assert 10 / 255 <= 0.04045 < 20 / 255
    want = [
        (lin(0.5), 0.0, lin(0.5)),
        (10 / 255 / 12.92, lin(20 / 255), lin(30 / 255)),
        (1.0, 1.0, 1.0),
        (0.0, lin(128 / 255), 1.0),
        (1.0, 0.0, lin(51 / 255)),
    ]
    np.testing.assert_array_equal(out["color"], f32(want))
    assert abs(out["color"][0, 0] - 0.2140411) < 1e-6


def test_hand_tree_at_depth_3_aggregates_one_level():
    out = export_regions(hand_tree(), 3, "srgb")
    # 24 (d3, k0), 31 aggregated (only 39: 64 · 1/8), 17 and 23 (k1),
    # 10 (k2), root 1 (k3).
    assert out["origin"].tolist() == [[0, 0, 0], [1, 1, 1], [2, 0, 0], [2, 2, 2], [0, 4, 0], [8, 0, 0]]
    assert out["log2_edge"].tolist() == [0, 0, 1, 1, 2, 3]
    assert out["density"].tolist() == [8.0, 8.0, 1.5, 0.25, 3.0, 0.5]
    np.testing.assert_array_equal(out["color"][:2], f32([(1, 0, 0), (0, 0, 1)]))
    assert float(out["voxel_size"]) == 0.25


def test_hand_tree_at_depth_0_aggregates_the_root():
    out = export_regions(hand_tree(), 0, "srgb")
    assert out["origin"].tolist() == [[0, 0, 0], [1, 0, 0]]
    assert out["log2_edge"].tolist() == [0, 0]
    # Root 0's leaves, weight 8^-depth: 24 (8/512), 39 (64/4096),
    # 17 (1.5/64), 23 (0.25/64), 10 (3/8).
    F = Fraction
    parts = {
        (255, 0, 0): F(8, 512),
        (0, 0, 255): F(64, 4096),
        (10, 20, 30): F(3, 2) / 64,
        (255, 255, 255): F(1, 4) / 64,
        (0, 128, 255): F(3, 8),
    }
    sigma = sum(parts.values())
    assert sigma == F(111, 256)
    assert out["density"][0] == np.float32(float(sigma))
    colour = [float(sum(F(c[a]) / 255 * w for c, w in parts.items()) / sigma) for a in range(3)]
    np.testing.assert_allclose(out["color"][0], colour, rtol=1e-6)
    assert out["density"][1] == 0.5


def test_all_empty_aggregate_falls_back_to_the_volume_mean():
    """A cell with children whose leaves are all empty: extinction 0 (not
    written), colour the plain volume-weighted mean of its leaves."""
    a = hand_tree()
    a["sigma"][[24, 39]] = 0
    a["rgb"][24] = (255, 0, 0)
    a["rgb"][32:40] = (0, 0, 255)
    sigma, rgb = region_values(a, np.array([16, 8]))
    assert sigma.tolist() == [0.0, 1.5 / 8 + 0.25 / 8]
    # 16: 24 red (1/8), 25..30 green (1/8 each), 31's children blue (1/64 each).
    np.testing.assert_array_equal(rgb[0], [1 / 8, 6 / 8, 1 / 8])
    out = export_regions(a, 2, "srgb")
    assert out["origin"].tolist() == [[1, 0, 0], [1, 1, 1], [0, 2, 0], [4, 0, 0]]


def test_aggregates_sum_in_the_painters_stack_order():
    """The painter sums a cell's leaves in its stack's order (children
    7..0); here the f64 sums differ by order and the f32 density shows it.
    Leaves (weight 1/8): sigma 1, 2^-24, 2^-53, 2^-53 at k = 0..3. In the
    order 3, 2, 1, 0 every partial sum is exact: 1/8 + 2^-27 + 2^-55, just
    above the f32 midpoint 1/8 + 2^-27, so it rounds up; in the order
    0..3 the two 2^-56 are lost to ties-to-even and it would round down."""
    b = Builder((1, 1, 1), 2)
    fc = b.split(0)
    for k, s in enumerate((1.0, 2.0**-24, 2.0**-53, 2.0**-53)):
        b.paint(fc + k, s, (255, 255, 255))
    out = export_regions(b.arrays(), 0, "srgb")
    assert out["density"].tolist() == [0.125 + 2.0**-26]
    forward = np.float32(((0.125 + 2.0**-27) + 2.0**-56) + 2.0**-56)
    assert forward == np.float32(0.125)


def test_a_region_below_the_smallest_f32_is_not_written():
    """sigma > 0 in f64 but 0 once rounded to f32: inactive."""
    b = Builder((1, 1, 1), 2)
    fc = b.split(0)
    b.paint(fc + 3, 2.0**-149, (255, 0, 0))  # the least f32 subnormal
    a = b.arrays()
    sigma, rgb = region_values(a, np.array([0]))
    assert sigma.tolist() == [2.0**-152] and rgb.tolist() == [[1.0, 0.0, 0.0]]
    assert export_regions(a, 0)["density"].shape == (0,)
    assert export_regions(a, 1)["density"].tolist() == [2.0**-149]


def test_srgb_to_linear():
    assert srgb_to_linear(np.array([0.0, 1.0])).tolist() == [0.0, 1.0]
    assert abs(srgb_to_linear(0.5) - 0.2140411405) < 1e-9
    assert srgb_to_linear(0.04045) == 0.04045 / 12.92  # the knee is on the linear segment
    assert srgb_to_linear(0.0405) == ((0.0405 + 0.055) / 1.055) ** 2.4


def test_default_depth_is_the_deepest_painted_leaf():
    a = hand_tree()
    assert default_depth(a) == 4
    out = export_regions(a)
    assert int(out["depth"]) == 4 and str(out["colour_space"]) == "linear"
    # No aggregation at E = D: one region per painted leaf, in walk order.
    assert out["origin"].tolist() == [[0, 0, 0], [3, 3, 3], [4, 0, 0], [4, 4, 4], [0, 8, 0], [16, 0, 0]]
    assert out["log2_edge"].tolist() == [1, 0, 2, 2, 3, 4]
    assert out["density"].tolist() == [8.0, 64.0, 1.5, 0.25, 3.0, 0.5]
    # Erase the depth-4 leaf: the deepest painted one is then at depth 3.
    a["sigma"][39] = 0
    assert default_depth(a) == 3
    a["sigma"][:] = 0
    assert default_depth(a) == 0
    empty = export_regions(a)
    assert int(empty["depth"]) == 0 and empty["origin"].shape == (0, 3) and empty["color"].shape == (0, 3)


def test_deepest_addressable():
    assert deepest_addressable((4, 4, 4), 25) == 25
    assert deepest_addressable((4, 1, 1), 30) == 29
    assert deepest_addressable((1, 1, 1), 31) == 31
    assert deepest_addressable((1, 1, 1), 32) == 31
    assert deepest_addressable((3, 1, 1), 30) == 29
    assert deepest_addressable((65536, 1, 1), 16) == 15


def test_default_depth_is_capped_at_the_addressable():
    """D = 30 on four roots: voxel indices of depth 30 would pass 2^31, so
    the default is 29 and the depth-30 leaf is folded into its parent."""
    b = Builder((4, 1, 1), 30)
    c = 3  # the last root, origin (3 << 30, 0, 0)
    for _ in range(30):
        c = b.split(c) + 7
    b.paint(c, 16.0, (255, 255, 255))
    a = b.arrays()
    assert default_depth(a) == 29
    out = export_regions(a, colour="srgb")
    assert int(out["depth"]) == 29
    top = (1 << 31) - 1
    assert out["origin"].tolist() == [[top, (1 << 29) - 1, (1 << 29) - 1]]
    assert out["log2_edge"].tolist() == [0] and out["density"].tolist() == [2.0]
    with pytest.raises(ExportError, match="export depth 30 is out of range: this canvas goes from depth 0 to 29"):
        export_regions(a, 30)


# ------------------------------------------------------------------ the command
@pytest.fixture
def hand_dump(tmp_path):
    path = tmp_path / "hand.npz"
    write_atomic(str(path), dump_bytes(hand_tree()))
    return path


def test_command_on_a_dump(hand_dump, tmp_path, capsys):
    out_path = tmp_path / "sub" / "regions.npz"
    os.makedirs(out_path.parent)
    assert main(["export", str(hand_dump), "--voxels", str(out_path), "--depth", "2", "--colour", "srgb"]) == 0
    err = capsys.readouterr().err
    assert "exported 5 regions (75 active voxels) at depth 2, voxel size 0.5, srgb colour" in err
    assert stat.S_IMODE(os.stat(out_path).st_mode) == 0o644
    assert os.listdir(out_path.parent) == ["regions.npz"]  # no temporary file left
    got = load_export(str(out_path))
    assert list(got) == ["origin", "log2_edge", "density", "color", "depth", "voxel_size", "colour_space"]
    want = export_regions(hand_tree(), 2, "srgb")
    for k in want:
        assert got[k].dtype == want[k].dtype and got[k].shape == want[k].shape, k
        np.testing.assert_array_equal(got[k], want[k])
    # Deterministic bytes; --quiet prints nothing.
    again = tmp_path / "again.npz"
    assert main(["export", str(hand_dump), "--voxels", str(again), "--depth", "2", "--colour", "srgb", "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert again.read_bytes() == out_path.read_bytes()


def test_command_defaults(hand_dump, tmp_path, capsys):
    out_path = tmp_path / "r.npz"
    assert main(["export", str(hand_dump), "--voxels", str(out_path)]) == 0
    got = load_export(str(out_path))
    assert int(got["depth"]) == 4 and str(got["colour_space"]) == "linear"
    assert "at depth 4, voxel size 0.125, linear colour" in capsys.readouterr().err


@pytest.mark.parametrize("depth", ["5", "-1", "99"])
def test_command_refuses_a_depth_out_of_range(hand_dump, tmp_path, capsys, depth):
    out_path = tmp_path / "r.npz"
    assert main(["export", str(hand_dump), "--voxels", str(out_path), "--depth", depth]) == 2
    err = capsys.readouterr().err
    assert err == f"octopaint-ref: {hand_dump}: export depth {depth} is out of range: this canvas goes from depth 0 to 4\n"
    assert os.listdir(tmp_path) == ["hand.npz"]


def test_command_refuses_a_depth_before_replaying(tmp_path, capsys):
    trace = os.path.join(TRACES, "single_stamp.jsonl")
    assert main(["export", trace, "--voxels", str(tmp_path / "r.npz"), "--depth", "9"]) == 2
    assert capsys.readouterr().err == f"octopaint-ref: {trace}: export depth 9 is out of range: this canvas goes from depth 0 to 8\n"
    assert os.listdir(tmp_path) == []


def _malformed(tmp_path):
    """(name, writer) pairs of broken inputs."""
    good = hand_tree()

    def garbage(p):
        p.write_bytes(b"not a zip at all")

    def missing(p):
        np.savez(p, parent=good["parent"])

    def bad_link(p):
        a = dict(good)
        a["first_child"] = good["first_child"].copy()
        a["first_child"][10] = len(good["depth"]) - 4  # children past the end
        write_atomic(str(p), dump_bytes(a))

    def bad_depth(p):
        a = dict(good)
        a["depth"] = good["depth"].copy()
        a["depth"][17] = 3
        write_atomic(str(p), dump_bytes(a))

    def bad_shape(p):
        a = dict(good)
        a["rgb"] = good["rgb"][:-1]
        write_atomic(str(p), dump_bytes(a))

    return {
        "garbage.npz": (garbage, "not a readable .npz dump"),
        "missing.npz": (missing, "array 'first_child' is missing"),
        "bad_link.npz": (bad_link, "cell 10: first_child 44 is past the 48 cells"),
        "bad_depth.npz": (bad_depth, "cell 17: depth 3 under cell 8 of depth 1"),
        "bad_shape.npz": (bad_shape, "array 'rgb' has shape (47, 3), expected (48, 3)"),
    }


@pytest.mark.parametrize("name", ["garbage.npz", "missing.npz", "bad_link.npz", "bad_depth.npz", "bad_shape.npz"])
def test_command_refuses_a_malformed_dump(tmp_path, capsys, name):
    src = tmp_path / "in"
    os.makedirs(src)
    write, message = _malformed(tmp_path)[name]
    path = src / name
    write(path)
    out_dir = tmp_path / "out"
    os.makedirs(out_dir)
    assert main(["export", str(path), "--voxels", str(out_dir / "r.npz")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"octopaint-ref: {path}: ") and message in err and err.count("\n") == 1, err
    assert os.listdir(out_dir) == []


@pytest.mark.parametrize("name", ["bad_utf8.jsonl", "color_short.jsonl", "empty.jsonl", "end_outside_stroke.jsonl"])
def test_command_refuses_a_malformed_trace(tmp_path, capsys, name):
    with open(os.path.join(TRACES, "malformed", "expected.json")) as f:
        expected = json.load(f)[name]
    path = os.path.join(TRACES, "malformed", name)
    with pytest.raises(TraceError) as e:
        read_trace(path)
    assert e.value.line == expected["line"]
    assert main(["export", path, "--voxels", str(tmp_path / "r.npz")]) == 2
    assert capsys.readouterr().err == f"octopaint-ref: {path}: {e.value}\n"
    assert os.listdir(tmp_path) == []


def test_command_refuses_a_missing_input(tmp_path, capsys):
    for name in ("nothing.npz", "nothing.jsonl"):
        assert main(["export", str(tmp_path / name), "--voxels", str(tmp_path / "r.npz")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"octopaint-ref: {tmp_path / name}: ") and err.count("\n") == 1
    assert os.listdir(tmp_path) == []


def test_command_line_entry_point(hand_dump, tmp_path):
    """The module runs as a program; argparse refuses a bad --colour with 2."""
    out_path = tmp_path / "r.npz"
    run = lambda *a: subprocess.run([sys.executable, "-m", "octopaint_ref.cli", "export", *a], capture_output=True, text=True)
    r = run(str(hand_dump), "--voxels", str(out_path), "--colour", "cmyk")
    assert r.returncode == 2 and "invalid choice: 'cmyk'" in r.stderr and not out_path.exists()
    r = run(str(hand_dump), "--voxels", str(out_path), "--quiet")
    assert r.returncode == 0 and r.stderr == "" and out_path.exists()


# ------------------------------------------------------------------ traces
def naive_export(a, e):
    """A literal port of the painter's walk (voxels.rs, for_each_region) and
    cell values (values.rs, cell_value): a stack of (cell, origin) from the
    roots, f64 sums in its stack order. Slow; for small trees. Returns
    (origin, log2_edge, density, sRGB colour in f64)."""
    fc, depth, sig = a["first_child"].tolist(), a["depth"].tolist(), a["sigma"].tolist()
    rgb = a["rgb"].tolist()
    D = int(a["max_depth"])
    rx, ry, rz = (int(x) for x in a["roots"])

    def leaf(c):
        return float(sig[c]), [v / 255.0 for v in rgb[c]]

    def cell_value(c):
        if fc[c] == NONE:
            return leaf(c)
        sigma, dense, plain, wd = 0.0, [0.0] * 3, [0.0] * 3, 0.0
        stack = [c]
        while stack:
            x = stack.pop()
            if fc[x] != NONE:
                stack.extend(range(fc[x], fc[x] + 8))
                continue
            w = 2.0 ** (-3 * (depth[x] - depth[c]))
            s, cc = leaf(x)
            sigma += s * w
            for i in range(3):
                plain[i] += cc[i] * w
                dense[i] += cc[i] * s * w
            wd += s * w
        return sigma, ([min(max(v / wd, 0.0), 1.0) for v in dense] if wd > 0 else plain)

    regions = []
    stack = [(r, [(r % rx) << D, ((r // rx) % ry) << D, (r // (rx * ry)) << D]) for r in range(rx * ry * rz)][::-1]
    while stack:
        c, o = stack.pop()
        d = depth[c]
        if fc[c] != NONE and d < e:
            half = 1 << (D - d - 1)
            for k in range(7, -1, -1):
                stack.append((fc[c] + k, [o[0] + (k & 1) * half, o[1] + (k >> 1 & 1) * half, o[2] + (k >> 2 & 1) * half]))
            continue
        s, col = cell_value(c)
        if np.float32(s) > 0:
            regions.append(([x >> (D - e) for x in o], e - d, s, col))
    return (
        np.array([r[0] for r in regions], np.int32).reshape(-1, 3),
        np.array([r[1] for r in regions], np.uint8),
        f32([r[2] for r in regions]),
        np.array([r[3] for r in regions], np.float64).reshape(-1, 3),
    )


SMALL_TRACES = ("single_stamp", "capacity_limit", "edges")


@pytest.fixture(scope="module")
def replayed():
    """The final tree of each small trace, through the command's own path."""
    return {name: load_input(os.path.join(TRACES, name + ".jsonl"))[0] for name in SMALL_TRACES}


def _leaves(a):
    live = a["depth"] != 255
    return np.nonzero(live & (a["first_child"] == NONE))[0]


@pytest.mark.parametrize("name", SMALL_TRACES)
def test_trace_export_covers_the_painted_volume_once(replayed, name):
    a = replayed[name]
    leaves = _leaves(a)
    painted = leaves[a["sigma"][leaves] > 0]
    e = default_depth(a)
    assert e == int(a["depth"][painted].max())
    out = export_regions(a)
    k = out["log2_edge"].astype(np.int64)
    # Volume: Σ 8^k voxels, exactly the painted leaves' (in voxels and in canvas units).
    want = sum(1 << 3 * (e - int(d)) for d in a["depth"][painted])
    assert active_voxels(out["log2_edge"]) == want
    vol = sum(float(a["root_size"]) ** 3 * 8.0 ** -int(d) for d in a["depth"][painted])
    assert np.isclose(float(np.sum(np.ldexp(1.0, 3 * k))) * float(out["voxel_size"]) ** 3, vol, rtol=1e-12)
    # Disjoint: aligned cubes overlap only when one holds the other; no
    # region's coarser aligned cube is itself a region.
    o = out["origin"].astype(np.int64)
    key = set(zip(o[:, 0].tolist(), o[:, 1].tolist(), o[:, 2].tolist(), k.tolist()))
    assert len(key) == len(k)
    for kk in range(1, int(k.max(initial=0)) + 1):
        up = (o >> kk) << kk
        hits = [(x, y, z, kk) in key for (x, y, z), k0 in zip(up.tolist(), k.tolist()) if k0 < kk]
        assert not any(hits)
    # Inside the canvas, aligned to their size.
    extent = a["roots"].astype(np.int64) << e
    assert np.all(o >= 0) and np.all(o + (1 << k)[:, None] <= extent)
    assert np.all(o % (1 << k)[:, None] == 0)


@pytest.mark.parametrize("name", SMALL_TRACES)
def test_trace_regions_are_the_leaves_when_nothing_aggregates(replayed, name):
    a = replayed[name]
    e = int(a["depth"][a["depth"] != 255].max())  # no cell with children at E
    for colour in ("linear", "srgb"):
        out = export_regions(a, e, colour)
        leaves = _leaves(a)
        painted = leaves[a["sigma"][leaves] > 0]
        shift = int(a["max_depth"]) - e
        by_origin = {tuple((a["origin"][c].astype(np.int64) >> shift).tolist()): c for c in painted.tolist()}
        assert len(out["density"]) == len(painted)
        cells = np.array([by_origin[tuple(org)] for org in out["origin"].tolist()], np.int64)
        np.testing.assert_array_equal(out["log2_edge"], e - a["depth"][cells].astype(np.int64))
        np.testing.assert_array_equal(out["density"], a["sigma"][cells])
        rgb = a["rgb"][cells] / 255.0
        want = f32(np.vectorize(lin, otypes=[float])(rgb) if colour == "linear" else rgb)
        np.testing.assert_array_equal(out["color"], want)


@pytest.mark.parametrize("name", SMALL_TRACES)
def test_trace_export_matches_a_literal_port_of_the_painter(replayed, name):
    a = replayed[name]
    deepest = int(a["depth"][a["depth"] != 255].max())
    for e in sorted({0, 1, deepest // 2, deepest - 1, deepest}):
        origin, k, density, srgb = naive_export(a, e)
        for colour in ("linear", "srgb"):
            out = export_regions(a, e, colour)
            col = f32(srgb if colour == "srgb" else np.vectorize(lin, otypes=[float])(srgb))
            for key, w in zip(("origin", "log2_edge", "density", "color"), (origin, k, density, col)):
                np.testing.assert_array_equal(out[key], w, err_msg=f"{name} E={e} {colour} {key}")


def test_trace_and_its_dump_export_the_same(tmp_path, capsys):
    """A trace replayed in memory exports what its final tree's dump does."""
    trace = os.path.join(TRACES, "single_stamp.jsonl")
    dump = tmp_path / "final.npz"
    write_atomic(str(dump), dump_bytes(tree_arrays(_painting_tree(trace))))
    assert load_dump(str(dump))  # a valid dump
    assert main(["export", trace, "--voxels", str(tmp_path / "a.npz"), "--depth", "6"]) == 0
    assert main(["export", str(dump), "--voxels", str(tmp_path / "b.npz"), "--depth", "6"]) == 0
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and "after replaying the trace" in err[0] and "after replaying" not in err[1]


def _painting_tree(trace_path):
    from octopaint_ref.replay import replay
    from octopaint_ref.trace import read_trace

    return replay(read_trace(trace_path), None, renders=False).painting.tree

"""Replaying the checked-in traces: valid dumps for every trace, undo/redo
byte-identical, deterministic output, and `check` catching broken dumps."""

import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import TRACES
from octopaint_ref.check import check_arrays
from octopaint_ref.dump import layer_trees, load_dump
from octopaint_ref.replay import replay
from octopaint_ref.trace import read_trace

TRACE_NAMES = sorted(f[:-6] for f in os.listdir(TRACES) if f.endswith(".jsonl"))


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    """Every trace replayed once into one folder; returns (folder, stats)."""
    out = tmp_path_factory.mktemp("replay")
    stats = {name: replay(read_trace(os.path.join(TRACES, name + ".jsonl")), str(out)) for name in TRACE_NAMES}
    return out, stats


@pytest.mark.parametrize("name", TRACE_NAMES)
def test_every_snapshot_is_a_valid_tree(replayed, name):
    out, stats = replayed
    dumps = [p for p in stats[name].written if p.endswith(".npz")]
    assert dumps, f"{name} writes no snapshot"
    for path in dumps:
        for tree in layer_trees(load_dump(path)):
            problems = check_arrays(tree)
            assert not problems, (path, problems)


def _arrays(out, name):
    with np.load(os.path.join(out, name + ".npz")) as z:
        return {k: z[k] for k in z.files}


def test_undo_and_redo_are_byte_identical(replayed):
    out, _ = replayed
    read = lambda n: open(os.path.join(out, n + ".npz"), "rb").read()
    assert read("undo_redo_undone") == read("undo_redo_a")
    assert read("undo_redo_redone") == read("undo_redo_b")
    assert read("undo_redo_a") != read("undo_redo_b")
    empty = _arrays(out, "undo_redo_empty")
    assert len(empty["parent"]) == 8 and np.all(empty["sigma"] == 0)


def test_capacity_limit_warns_and_stays_within_budget(replayed):
    _, stats = replayed
    s = stats["capacity_limit"]
    assert any("cell budget of 4096 cells is exhausted" in w for w in s.warnings)
    assert s.cells <= 4096
    assert s.painting.capacity_refusals > 0


def test_open_stroke_is_ended_with_a_warning(replayed):
    _, stats = replayed
    assert any("ends inside this stroke" in w for w in stats["edges"].warnings)


def test_scene_spans_the_depth_range(replayed):
    out, stats = replayed
    s = stats["scene"]
    assert s.samples >= 5000 and s.max_depth_reached == 25
    a = _arrays(out, "scene")
    live = a["depth"][a["depth"] != 255]
    # Detail at depth >= 20 and haze cells coarser than depth 10 coexist.
    assert (live >= 20).sum() > 100_000 and ((live <= 9) & (a["first_child"][a["depth"] != 255] == 0xFFFFFFFF)).any()
    painted = a["sigma"][(a["depth"] >= 20) & (a["depth"] != 255)]
    assert (painted > 0).sum() > 50_000


def test_replay_is_deterministic(tmp_path):
    path = os.path.join(TRACES, "undo_redo.jsonl")
    a, b = tmp_path / "a", tmp_path / "b"
    replay(read_trace(path), str(a))
    replay(read_trace(path), str(b))
    for f in os.listdir(a):
        assert (a / f).read_bytes() == (b / f).read_bytes(), f


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "octopaint_ref.cli", *args], capture_output=True, text=True)


def test_cli_replay_and_check(tmp_path):
    r = _cli("replay", os.path.join(TRACES, "single_stamp.jsonl"), "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    dump = tmp_path / "single_stamp.npz"
    r = _cli("check", str(dump))
    assert r.returncode == 0 and "ok" in r.stdout
    # Break one parent link and one g3 entry: check names both.
    a = dict(np.load(dump))
    c = int(np.nonzero(a["depth"] == 2)[0][0])
    a["parent"][c] = 0
    a["g3"][c + 1, 0] = 0
    broken = tmp_path / "broken.npz"
    np.savez(broken, **a)
    r = _cli("check", str(broken))
    assert r.returncode == 1
    assert "do not point back" in r.stdout and str(c) in r.stdout
    # Not a dump at all.
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    r = _cli("check", str(tmp_path / "junk.npz"))
    assert r.returncode == 1 and "not a readable .npz dump" in r.stderr


def test_balance_violation_is_reported():
    from octopaint_ref.dump import tree_arrays
    from octopaint_ref.tree import Tree

    t = Tree((2, 1, 1), max_depth=4, capacity=1 << 10)
    t.refine_round([0])
    # Refine cell 9 (touching root 1, still a leaf of depth 0) without the
    # balance recursion: depth-2 leaves now face a depth-0 leaf.
    t._make_children(np.array([9]), t.allocate_units(1))
    problems = check_arrays(tree_arrays(t))
    assert any("2:1 face balance violated" in p for p in problems), problems


def test_every_render_writes_a_png(replayed):
    """Each `render` event leaves <name>.png: 8-bit RGB of the camera's size."""
    from octopaint_ref.png import read_png

    out, stats = replayed
    for name in TRACE_NAMES:
        trace = read_trace(os.path.join(TRACES, name + ".jsonl"))
        camera = None
        for ev in trace.events:
            if ev.kind == "camera":
                camera = ev.value
            elif ev.kind == "render":
                path = os.path.join(out, ev.value + ".png")
                assert path in stats[name].written
                img = read_png(open(path, "rb").read())
                w, h = camera.size
                assert img.shape == (h, w, 3)
                assert img.std() > 1.0, f"{path} is flat"

"""Layers (spec 14, 6.2): the reader's model of a document, one history
for strokes and layer operations, merge down as the common refinement of
two trees with composited values, the dump of a document, and the march
through several layers."""

import os

import numpy as np
import pytest
from conftest import TRACES
from octopaint_ref.dump import layer_trees, tree_arrays
from octopaint_ref.layer_rules import LayerOp
from octopaint_ref.layers import Document
from octopaint_ref.march import render_layers
from octopaint_ref.raycast import render
from octopaint_ref.replay import replay
from octopaint_ref.trace import Brush, Camera, Canvas, Light, Sample, TraceError, parse_trace, read_trace

H2 = '{"format": "ddo-trace", "version": 2, "canvas": {"roots": [1, 1, 1], "max_depth": 5, "root_size": 1.0, "capacity": 65536}}'
CANVAS = Canvas((1, 1, 1), 5, 1.0, 65536)


def _paint(doc, p, radius, colour, line=1):
    doc.begin_stroke(Brush("sphere", "paint", radius, colour, 0.9, 0.5), line)
    doc.add_sample(Sample(p), line)
    doc.end_stroke()


def _arrays(doc):
    return [tree_arrays(la.tree) for la in doc.layers]


def _same(a, b):
    return all(np.array_equal(a[k], b[k]) for k in ("parent", "first_child", "depth", "rgb", "origin")) and np.array_equal(
        a["sigma"].view(np.uint32), b["sigma"].view(np.uint32)
    )


def test_the_reader_follows_names_locks_and_selection_through_undo():
    ok = parse_trace(
        "\n".join(
            [
                H2,
                '{"ev": "layer", "t": 0, "op": "add", "name": "a"}',
                '{"ev": "layer", "t": 0, "op": "rename", "layer": "a", "name": "b"}',
                '{"ev": "undo", "t": 0}',
                '{"ev": "layer", "t": 0, "op": "select", "layer": "a"}',
                '{"ev": "redo", "t": 0}',
                '{"ev": "layer", "t": 0, "op": "set", "layer": "b", "opacity": 0.3}',
            ]
        )
    )
    assert ok.version == 2
    op = ok.events[-1].value
    assert op == LayerOp("set", layer="b", opacity=np.float32(0.3).item())
    # select is no step: one undo goes back past the rename, a second past the add.
    bad = "\n".join([H2, '{"ev": "layer", "t": 0, "op": "add", "name": "a"}', '{"ev": "layer", "t": 0, "op": "select", "layer": "Layer 1"}', '{"ev": "undo", "t": 0}', '{"ev": "undo", "t": 0}'])
    with pytest.raises(TraceError) as e:
        parse_trace(bad)
    assert (e.value.line, e.value.kind) == (5, "event-order")


def test_undo_restores_every_layer_byte_for_byte_and_redo_replays():
    doc = Document(CANVAS)
    _paint(doc, (0.4, 0.5, 0.5), 0.2, (0.9, 0.2, 0.1))
    assert doc.apply(LayerOp("add", name="top"), 2)
    _paint(doc, (0.6, 0.5, 0.5), 0.1, (0.1, 0.2, 0.9))
    before = _arrays(doc)
    assert doc.apply(LayerOp("merge_down", layer="top"), 3)
    assert [la.name for la in doc.layers] == ["Layer 1"]
    merged = _arrays(doc)
    _paint(doc, (0.5, 0.3, 0.5), 0.05, (0.2, 0.9, 0.2))
    doc.undo()
    assert all(_same(a, b) for a, b in zip(merged, _arrays(doc)))
    doc.undo()
    assert [la.name for la in doc.layers] == ["Layer 1", "top"] and doc.selected == 1
    assert all(_same(a, b) for a, b in zip(before, _arrays(doc)))
    doc.redo()
    assert all(_same(a, b) for a, b in zip(merged, _arrays(doc)))


def test_merge_down_holds_both_layers_composited_at_every_point():
    doc = Document(CANVAS)
    _paint(doc, (0.4, 0.5, 0.5), 0.25, (0.9, 0.2, 0.1))
    doc.apply(LayerOp("add", name="top"), 2)
    _paint(doc, (0.6, 0.45, 0.5), 0.12, (0.1, 0.2, 0.9))
    doc.apply(LayerOp("set", layer="top", opacity=np.float32(0.6).item()), 3)
    A, B = doc.layers[0].tree, doc.layers[1].tree
    oB = float(np.float32(0.6))
    probes = np.random.default_rng(5).random((400, 3))
    want = []
    for p in probes:
        a, b = A.leaf_at(p), B.leaf_at(p)
        wa, wb = float(A.sigma[a]), oB * float(B.sigma[b])
        w = wa + wb
        rgb = np.floor((wa * A.rgb[a].astype(float) + wb * B.rgb[b].astype(float)) / w + 0.5) if w > 0 else A.rgb[a]
        want.append((np.float32(w), rgb))
    doc.apply(LayerOp("merge_down", layer="top"), 4)
    M = doc.layers[0].tree
    assert doc.layers[0].opacity == 1.0
    for p, (sigma, rgb) in zip(probes, want):
        m = M.leaf_at(p)
        assert M.sigma[m] == sigma and np.array_equal(M.rgb[m], rgb), p
    # Cleaning ran: no 8 leaf siblings are all equal.
    from octopaint_ref.clean import collapsible_anywhere

    assert len(collapsible_anywhere(M)) == 0


def test_a_document_dump_holds_settings_and_every_layer(tmp_path):
    stats = replay(read_trace(os.path.join(TRACES, "layers.jsonl")), str(tmp_path), renders=False)
    from octopaint_ref.dump import load_dump

    d = load_dump(tmp_path / "layers_before_merge.npz")
    names = [bytes(r[r != 0]).decode() for r in d["layer_names"]]
    assert names == ["ground haze", "Layer 1", "detail", "detail copy"]
    assert d["layer_visible"].tolist() == [0, 1, 1, 0] and d["layer_locked"].tolist() == [0, 0, 0, 1]
    assert d["layer_opacity"].tolist() == [1.0, 1.0, 0.5, 0.5] and int(d["selected"]) == 3
    trees = layer_trees(d)
    doc = stats.document
    assert len(trees) == 4
    # Undoing the merge (and the opacity change before it) gives the same bytes.
    assert (tmp_path / "layers_unmerged.npz").read_bytes() == (tmp_path / "layers_before_merge.npz").read_bytes()
    assert [la.name for la in doc.layers] == ["ground haze", "Layer 1", "detail copy"]


CAM = Camera((0.5, 0.62, 1.9), (-0.15, 0.0, 0.0, 0.988771), (-0.3, 0.3, 0.25, -0.25), (24, 20))


def test_the_march_of_an_empty_layer_or_two_halves_is_the_single_image():
    doc = Document(CANVAS)
    _paint(doc, (0.45, 0.5, 0.5), 0.25, (0.9, 0.4, 0.1))
    _paint(doc, (0.6, 0.55, 0.45), 0.08, (0.1, 0.5, 0.9))
    one = tree_arrays(doc.layers[0].tree)
    single = render(one, CAM)
    empty = tree_arrays(Document(CANVAS).layers[0].tree)
    with_empty = render_layers([(one, 1.0), (empty, 1.0)], CAM)
    assert np.abs(with_empty.image.astype(int) - single.image.astype(int)).max() <= 1
    halves = render_layers([(one, 0.5), (one, 0.5)], CAM)
    assert np.abs(halves.image.astype(int) - single.image.astype(int)).max() <= 1
    # Opacity is a density scale, so half of it shows: less, not nothing.
    half = render_layers([(one, 0.5)], CAM)
    assert single.image.astype(int).sum() > half.image.astype(int).sum() > 0
    lit = Light(dir=(0.3, 1.0, 0.4), shadows=True)
    assert np.abs(render_layers([(one, 0.5), (one, 0.5)], CAM, light=lit).image.astype(int) - render(one, CAM, light=lit).image.astype(int)).max() <= 1

"""A document's recorded session replays to the same tree in both
implementations: `octopaint import` makes a document from a trace,
`octopaint undo`/`redo` change it, `octopaint record` writes its session,
and `octopaint replay` and `octopaint-ref replay` of that recording give
dumps with the same arrays (spec 11.1) as each other and as the original
trace's."""

from __future__ import annotations

import os
import subprocess
import sys

import dumps
from conftest import REPO

REF = [sys.executable, "-m", "octopaint_ref.cli"]


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, (cmd, r.stderr)
    return r


def test_recorded_sessions_replay_identically_in_both(painter, tmp_path):
    trace = os.path.join(REPO, "traces", "undo_redo.jsonl")
    doc = tmp_path / "d.octo"
    run([painter, "import", trace, str(doc)])
    # Two undos and one redo on the document, through saves.
    run([painter, "undo", str(doc), "--steps", "2"])
    run([painter, "redo", str(doc)])
    rec = tmp_path / "rec.jsonl"
    run([painter, "record", str(doc), "--out", str(rec)])
    text = rec.read_text().rstrip("\n") + '\n{"ev": "snapshot", "t": 1e9, "name": "end"}\n'
    rec.write_text(text)
    run([painter, "replay", str(rec), "--out", str(tmp_path / "p"), "--renderer", "none", "--quiet"])
    run(REF + ["replay", str(rec), "--out", str(tmp_path / "r"), "--quiet"])
    p = dumps.load(str(tmp_path / "p" / "end.npz"))
    r = dumps.load(str(tmp_path / "r" / "end.npz"))
    assert dumps.compare(r, p) == [], "the painter and the reference replay the recording differently"
    # Every snapshot of the original trace is reproduced by the recording too.
    names = sorted(f for f in os.listdir(tmp_path / "p") if f.endswith(".npz") and f != "end.npz")
    assert names
    run([painter, "replay", trace, "--out", str(tmp_path / "o"), "--renderer", "none", "--quiet"])
    for n in names:
        assert (tmp_path / "p" / n).read_bytes() == (tmp_path / "o" / n).read_bytes(), n
    # The document's tree is the original's with its last stroke undone
    # (two undos, one redo): the original trace plus one undo, replayed.
    once = tmp_path / "once.jsonl"
    with open(trace) as f:
        base = f.read().rstrip("\n")
    once.write_text(base + '\n{"ev": "undo", "t": 1e9}\n{"ev": "snapshot", "t": 1e9, "name": "end"}\n')
    run(REF + ["replay", str(once), "--out", str(tmp_path / "u"), "--quiet"])
    assert dumps.compare(dumps.load(str(tmp_path / "u" / "end.npz")), p) == []


def test_imports_recorded_from_a_document_replay_identically_in_both(painter, tmp_path):
    """`import-vdb` and `import-mesh` on a document (spec 15): its recorded
    session names voxel sets written beside the trace, and the reference
    replays it to the document's own layers."""
    trace = os.path.join(REPO, "traces", "shapes_modes.jsonl")
    vdb = tmp_path / "s.vdb"
    doc = tmp_path / "d.octo"
    run([painter, "export", trace, "--vdb", str(vdb), "--depth", "6", "--quiet"])
    run([painter, "new", str(doc), "--like", trace])
    run([painter, "import-vdb", str(vdb), str(doc), "--layer", "volume", "--scale", "1"])
    obj = tmp_path / "tet.obj"
    # A closed tetrahedron with vertex colours, its faces oriented outward.
    obj.write_text(
        "v 0.1 0.1 0.1 1 0 0\nv 0.6 0.1 0.1 0 1 0\nv 0.1 0.6 0.1 0 0 1\nv 0.1 0.1 0.6 1 1 0\n"
        "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    )
    run([painter, "import-mesh", str(obj), str(doc), "--layer", "solid", "--depth", "6"])
    rec = tmp_path / "rec" / "rec.jsonl"
    rec.parent.mkdir()
    run([painter, "record", str(doc), "--out", str(rec)])
    rec.write_text(rec.read_text().rstrip("\n") + '\n{"ev": "snapshot", "t": 1e9, "name": "end"}\n')
    run(REF + ["replay", str(rec), "--out", str(tmp_path / "r"), "--quiet"])
    run([painter, "dump", str(doc), str(tmp_path / "doc.npz")])
    r = dumps.load(str(tmp_path / "r" / "end.npz"))
    p = dumps.load(str(tmp_path / "doc.npz"))
    assert dumps.compare_document(r, p) == [], "the reference replays the imports differently"
    assert int(p["layer_count"]) == 3

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

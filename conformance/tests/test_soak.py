"""The short soak (docs/benchmarks.md, "The soak"; docs/documents.md):
`octopaint bench soak` paints 10^4 stamps through the window's engine into
a new document of layers with a small undo budget (8 MiB) and a save
every 20 s of its clock, and this checks what it found:

- every save left the journal at its header alone, the last one too;
- the saved document, opened again, and the replay of the session's
  trace with the same undo bound both equal the live document;
- the history reached its budget and was trimmed to it (steps
  forgotten, never more than the budget and one step held);
- the engine's records stayed bounded (a live session keeps the newest
  4,096 to 8,192 jobs), whatever the stamps painted;
- the trace's section of the saved document, which the session deflates
  a save at a time and never finishes (docs/documents.md, "Memory over a
  long session"), is an ordinary zlib stream: Python's zlib inflates it
  to exactly what `octopaint record` writes;
- the plot script draws the run.

Resident memory is recorded, not asserted: its slope is a benchmark
figure (10^6 stamps, docs/benchmarks.md), too noisy over 10^4 stamps.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))

UNDO_MIB = 8
LIVE_RECORDS = 4096


def test_a_short_soak_keeps_memory_bounded_and_loses_nothing(painter, tmp_path):
    out = tmp_path / "soak"
    env = dict(os.environ, NODEVICE_SELECT="1")
    run = subprocess.run(
        [painter, "bench", "soak", "--stamps", "10000", "--undo-mib", str(UNDO_MIB), "--save-every", "20", "--points", "20", "--out", str(out)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    r = json.loads((out / "soak.json").read_text())
    assert r["stamps"] >= 10000 and r["strokes"] > 50 and r["undos"] > 0 and r["layer_ops"] > 0, r
    assert len(r["saves"]) >= 5, r["saves"]
    assert all(s["lines_after"] == 0 for s in r["saves"]), r["saves"]
    assert all(s["journal_before"] > s["journal_after"] for s in r["saves"]), r["saves"]
    assert r["journal_emptied"] and r["saved_equals_live"] and r["replay_equals_live"], r
    last = r["points"][-1]
    assert r["budget_reached_at"] is not None and last["forgotten"] > 0, r
    # Trimmed after every stroke: at most the budget, or the one newest
    # step when that alone is larger (never the case at these sizes).
    assert max(p["undo_mib"] for p in r["points"]) < 2 * UNDO_MIB, r["points"]
    assert max(p["records"] for p in r["points"]) <= 2 * LIVE_RECORDS + 4096, r["points"]
    assert max(p["journal_kib"] for p in r["points"]) < 4096, r["points"]

    # The trace's section, inflated by another zlib.
    doc = (out / "soak.octo").read_bytes()
    assert doc[:12] == b"OCTOPAINTDOC"
    tag, flags, stored, raw, crc = struct.unpack_from("<4sIQQI", doc, 32)
    assert tag == b"TRCE" and flags & 1, (tag, flags)
    text = zlib.decompress(doc[64 : 64 + stored])
    assert len(text) == raw and zlib.crc32(text) == crc
    recorded = tmp_path / "soak.jsonl"
    rec = subprocess.run([painter, "record", "--out", str(recorded), str(out / "soak.octo")], capture_output=True, text=True, env=env)
    assert rec.returncode == 0, rec.stderr
    assert recorded.read_bytes() == text + b"\n"

    png = tmp_path / "soak.png"
    plot = subprocess.run([sys.executable, os.path.join(REPO, "painter", "bench", "plot_soak.py"), str(out / "soak.json"), str(png)], capture_output=True, text=True)
    assert plot.returncode == 0, plot.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

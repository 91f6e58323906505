"""The Windows build of the painter, run under Wine, does what the Linux
build does: the same dumps (array for array and byte for byte) for every
trace, the same refusals of every malformed trace, the same documents,
exports and recordings, crash recovery after the Wine process is killed,
the same GPU images through Wine's Vulkan (lavapipe underneath), and the
documented answer when there is no VR. The Linux build is held to the
reference by conformance/, so this holds the Windows build to it too."""

from __future__ import annotations

import glob
import json
import os
import signal
import threading

import numpy as np
import pytest
from conftest import REPO, Program, windows_path
from images import compare

TRACES = sorted(os.path.relpath(p, REPO) for p in glob.glob(os.path.join(REPO, "traces", "*.jsonl")))
MALFORMED = sorted(os.path.relpath(p, REPO) for p in glob.glob(os.path.join(REPO, "traces", "malformed", "*.jsonl")))


def assert_same_dumps(a: str, b: str) -> list[str]:
    """Every .npz of folder a equals b's: same arrays, dtypes, shapes and
    bits, and the same bytes. Returns the names compared."""
    names = sorted(f for f in os.listdir(a) if f.endswith(".npz"))
    assert names == sorted(f for f in os.listdir(b) if f.endswith(".npz")), (a, b)
    for n in names:
        with np.load(os.path.join(a, n)) as x, np.load(os.path.join(b, n)) as y:
            assert sorted(x.files) == sorted(y.files), n
            for k in x.files:
                assert x[k].dtype == y[k].dtype and x[k].shape == y[k].shape, (n, k)
                assert x[k].tobytes() == y[k].tobytes(), (n, k)
        with open(os.path.join(a, n), "rb") as fa, open(os.path.join(b, n), "rb") as fb:
            assert fa.read() == fb.read(), n
    return names


@pytest.mark.parametrize("trace", TRACES)
def test_every_trace_replays_to_the_linux_dumps(trace, linux, windows, tmp_path):
    lout, wout = tmp_path / "linux", tmp_path / "windows"
    rl = linux.run("replay", trace, "--out", lout, "--renderer", "none", "--quiet")
    rw = windows.run("replay", trace, "--out", wout, "--renderer", "none", "--quiet")
    # Warnings (the capacity trace's exhausted budget) are the same too.
    assert rw.stderr == rl.stderr and rw.stdout == rl.stdout
    assert assert_same_dumps(str(lout), str(wout))


LAVAPIPE = sorted(glob.glob("/usr/share/vulkan/icd.d/lvp_icd.*.json"))


def test_gpu_images_through_wines_vulkan_match_linux(linux, windows, tmp_path):
    """The scene replayed with the GPU renderer: under Wine, wgpu finds
    Vulkan through winevulkan and draws the same pictures as the Linux
    build on the host's Vulkan. Both are given lavapipe only (Vulkan's
    loader reads VK_ICD_FILENAMES under Wine too), so a machine with a GPU
    compares one driver with itself."""
    assert LAVAPIPE, "no lavapipe (apt-get install mesa-vulkan-drivers)"
    trace = "traces/scene.jsonl"
    lout, wout = tmp_path / "linux", tmp_path / "windows"
    icd = {"VK_ICD_FILENAMES": LAVAPIPE[0]}
    rl = Program(linux.argv, {**linux.env, **icd}).run("replay", trace, "--out", lout)
    rw = Program(windows.argv, {**windows.env, **icd}).run("replay", trace, "--out", wout)
    assert "rendering on" in rw.stderr and "(Vulkan," in rw.stderr, rw.stderr
    pngs = sorted(f for f in os.listdir(lout) if f.endswith(".png"))
    assert pngs and pngs == sorted(f for f in os.listdir(wout) if f.endswith(".png"))
    # The same lavapipe draws both from the same SPIR-V, so the pixels are
    # equal, not merely within the reference's tolerance: a difference is
    # a bug on the Windows path.
    for p in pngs:
        res = compare(str(lout / p), str(wout / p))
        assert res.ok and res.max_steps == 0, (p, res.detail)
    assert_same_dumps(str(lout), str(wout))
    assert "rendering on" in rl.stderr


def test_every_malformed_trace_is_refused_with_the_same_message(linux, windows):
    """The Windows build refuses each on the line traces/malformed/expected.json
    gives, with the Linux build's message."""
    with open(os.path.join(REPO, "traces", "malformed", "expected.json")) as f:
        expected = json.load(f)
    rl = linux.run("check", *MALFORMED, "traces/scene.jsonl", ok=False)
    rw = windows.run("check", *MALFORMED, "traces/scene.jsonl", ok=False)
    assert rw.returncode == rl.returncode == 2
    assert rw.stdout == rl.stdout and rw.stderr == rl.stderr
    lines = rw.stdout.splitlines()
    assert len(lines) == len(MALFORMED) + 1 and lines[-1] == "traces/scene.jsonl: ok"
    for path, line in zip(MALFORMED, lines):
        assert line.startswith(f"{path}: line {expected[os.path.basename(path)]['line']}: "), line
    # One at a time, each is its own refusal with exit status 2.
    for path in MALFORMED[:3]:
        r = windows.run("replay", path, "--out", "/nonexistent-octopaint-out", ok=False)
        assert r.returncode == 2 and rl.stdout.splitlines()[MALFORMED.index(path)].split(": ", 1)[1] in r.stderr, r.stderr
        assert not os.path.exists("/nonexistent-octopaint-out")


def session(program, folder, trace="traces/undo_redo.jsonl"):
    """The document commands an artist's session goes through, in
    `folder`; returns their outputs with the folder's name taken out."""
    d = os.path.join(folder, "art.octo")
    outs = []
    for args in (
        ["import", trace, d],
        ["info", d],
        ["undo", d, "--steps", "2"],
        ["redo", d],
        ["info", d],
        ["record", d, "--out", os.path.join(folder, "recorded.jsonl")],
        ["dump", d, os.path.join(folder, "art.npz")],
        ["export", d, "--vdb", os.path.join(folder, "art.vdb"), "--gltf", os.path.join(folder, "art.glb"), "--quiet"],
    ):
        r = program.run(*args)
        outs.append((r.stdout + r.stderr).replace(windows_path(folder), "DIR").replace(folder, "DIR"))
    return outs


def test_documents_exports_and_recordings_are_the_linux_ones(linux, windows, tmp_path):
    lf, wf = tmp_path / "linux", tmp_path / "windows"
    lf.mkdir()
    wf.mkdir()
    lo = session(linux, str(lf))
    wo = session(windows, str(wf))
    assert wo == lo
    # The same bytes in every file the two sessions wrote: documents
    # (tree, history, session), dumps, recordings, OpenVDB and glTF.
    names = sorted(os.listdir(lf))
    assert names == sorted(os.listdir(wf)) == sorted(
        ["art.octo", "art.octo.journal", "art.octo.lock", "recorded.jsonl", "art.npz", "art.vdb", "art.glb"]
    )
    for n in names:
        a, b = (lf / n).read_bytes(), (wf / n).read_bytes()
        if n.endswith(".lock"):
            # The writer lock's file (docs/documents.md): the last writer's
            # process id, which differs; no document content.
            assert a.isdigit() and b.isdigit(), (a, b)
            continue
        if n.endswith(".vdb"):
            # An OpenVDB file names itself with a random UUID (36 ASCII
            # bytes after the 21-byte header); everything else is equal.
            assert a[21:57] != b[21:57]
            a, b = a[:21] + a[57:], b[:21] + b[57:]
        assert a == b, n


def test_a_killed_windows_session_recovers_every_completed_stroke(linux, windows, tmp_path):
    """`octopaint paint` at an artist's pace, its Wine process killed
    (SIGKILL: Windows sees the process vanish, nothing is flushed or
    closed), then `recover` under Wine: the document holds at least every
    stroke the session reported journalled, and exactly the trace's first
    strokes. While the session paints, a second writer is refused
    (LockFileEx on the document's lock file) and a reader reads it."""
    trace = "traces/shapes_modes.jsonl"
    doc = tmp_path / "art.octo"
    windows.run("new", doc, "--like", trace)
    child = windows.popen(
        "paint", doc, "--input", trace, "--events-per-second", "150", "--no-save", stderr=-1, text=True
    )
    # A stalled Wine must fail the test, not hang it: the watchdog kills
    # the session after two minutes (the reads below then see the end).
    watchdog = threading.Timer(120, child.kill)
    watchdog.start()
    try:
        journalled = 0
        while journalled < 12:
            line = child.stderr.readline()
            assert line, "the session ended (or stalled) before a dozen strokes"
            journalled += line.rstrip().endswith("journalled")
        # While it paints: a second writer is refused at once, naming the
        # document, and writes nothing; a reader reads the journal's strokes.
        before = doc.read_bytes()
        r = windows.run("recover", doc, ok=False)
        assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
        assert "art.octo" in r.stderr and "another Octopaint has this document open" in r.stderr, r.stderr
        assert doc.read_bytes() == before
        assert "recovered here" in windows.run("info", doc).stdout
    finally:
        watchdog.cancel()
        child.send_signal(signal.SIGKILL)
        child.wait()
        child.stderr.close()
    assert child.returncode != 0
    # The journal's complete strokes come back: the dead writer's lock went
    # with its process.
    r = windows.run("info", doc)
    assert "recovered here" in r.stdout, r.stdout
    r = windows.run("recover", doc)
    assert "nothing unsaved" in windows.run("info", doc).stdout
    rec = tmp_path / "recovered.jsonl"
    windows.run("record", doc, "--out", rec)
    text = rec.read_text()
    k = sum('"stroke_end"' in line for line in text.splitlines())
    assert k >= 12, k
    # They are the trace's first k strokes: the Linux build replays the
    # recording and the trace cut after k strokes to the same tree.
    with open(os.path.join(REPO, trace)) as f:
        lines = f.read().splitlines()
    ends = [i for i, line in enumerate(lines) if '"stroke_end"' in line]
    prefix = lines[: ends[k - 1] + 1]
    snap = '{"ev": "snapshot", "t": 1e9, "name": "end"}'
    (tmp_path / "a.jsonl").write_text(text.rstrip("\n") + "\n" + snap + "\n")
    (tmp_path / "b.jsonl").write_text("\n".join(prefix + [snap]) + "\n")
    for n in "ab":
        linux.run("replay", tmp_path / f"{n}.jsonl", "--out", tmp_path / n, "--renderer", "none", "--quiet")
    assert (tmp_path / "a" / "end.npz").read_bytes() == (tmp_path / "b" / "end.npz").read_bytes()


def test_without_vr_the_windows_build_says_what_is_missing(windows, tmp_path):
    """Next to the bare executable there is no openxr_loader.dll (the
    package ships one: test_dist.py), and Wine has no OpenXR runtime."""
    r = windows.run("xr-info", ok=False)
    assert r.returncode == 3, (r.stdout, r.stderr)
    assert "octopaint: no VR here: no OpenXR loader (openxr_loader.dll" in r.stderr, r.stderr
    doc = tmp_path / "d.octo"
    windows.run("new", doc)
    r = windows.run("vr", doc, "--no-fallback", "--frames", "1", ok=False)
    assert r.returncode == 3 and "no VR here: no OpenXR loader" in r.stderr, r.stderr

"""Faults injected at every step of a painting session's journal appends and
its save, and nothing lost (docs/documents.md, "Faults").

`octopaint paint` paints a small trace (strokes, an undo, a redo, mirror
planes: conformance/fuzz_seeds.py's) onto a document made from the same
trace, quietly, so that every `write`, `fsync`, `fdatasync` and `renameat`
the painter makes is one of the session's own: the lock file, a journal
append per stroke end, undo and redo (a write and an fdatasync each), then
the save: the document's temporary file (write,
fsync), its rename, the folder's fsync, and the same for the new journal.
A clean run under strace lists them in order (`-y` names each call's
file). Then each one in turn fails, through strace's syscall fault
injection (`-e inject=SYSCALL:error=ERRNO:when=N`: the N-th such call is
not made and returns the error), with EIO and with ENOSPC, and every time:

- the session fails with a clear message naming the error, no panic;
- the document is the previous one byte for byte when the fault came
  before its rename, the complete new one after it;
- `octopaint info` reads the document and its journal;
- the journal gives back every stroke (and undo, redo) whose append had
  returned success before the fault (and the one whose fdatasync failed,
  whose lines are in the file), no more; after the document's rename,
  all of them are in the document;
- `octopaint recover` then saves a document whose tree is the replay of
  exactly those events.

With `--keep-going` (a live session that goes on after a failed append,
as the window does), a fault in any journal append loses nothing: the
next flush writes the journal whole and the final save holds every event.

A short write (the disk fills in the middle of a write) is what a full
file system gives; `test_a_disk_that_fills_up_loses_nothing` makes one
with a size-limited tmpfs.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import NamedTuple

import fuzz_seeds
import pytest

# The session: strokes, an undo, a redo, mirror planes on a small canvas
# (fuzz_seeds.journal_trace), so that its document is small and each of
# the many runs below quick.
TRACE_TEXT = fuzz_seeds.journal_trace(1, fuzz_seeds.SMALL_CANVAS)
SYSCALLS = ("write", "fsync", "fdatasync", "rename", "renameat", "renameat2")
ERRNOS = {"EIO": "Input/output error", "ENOSPC": "No space left on device"}
ENDS = ('"stroke_end"', '"undo"', '"redo"')


def run(cmd, ok=True, **kw):
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=300, **kw)
    if ok:
        assert r.returncode == 0, (cmd, r.returncode, r.stdout, r.stderr)
    return r


def strace():
    path = shutil.which("strace")
    if path is None:
        raise FileNotFoundError("strace is missing: apt-get install strace (make setup installs it)")
    return path


class Base(NamedTuple):
    doc: bytes
    journal: bytes
    input: Path


@pytest.fixture(scope="module")
def base(painter, tmp_path_factory):
    """The document the sessions paint on: the trace imported, saved (its
    file and its journal's header); and the session's input, the trace's
    events without its renders and snapshots."""
    folder = tmp_path_factory.mktemp("base")
    trace = folder / "trace.jsonl"
    trace.write_text(TRACE_TEXT)
    doc = folder / "d.octo"
    run([painter, "import", trace, doc])
    lines = TRACE_TEXT.splitlines()
    kept = [e for e in lines[1:] if json.loads(e)["ev"] not in ("render", "snapshot")]
    session_input = folder / "input.jsonl"
    session_input.write_text("\n".join([lines[0], *kept]) + "\n")
    return Base(doc.read_bytes(), (folder / "d.octo.journal").read_bytes(), session_input)


def fresh(base, folder):
    """A copy of the base document in an empty `folder`."""
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir()
    doc = folder / "d.octo"
    doc.write_bytes(base.doc)
    (folder / "d.octo.journal").write_bytes(base.journal)
    return doc


def session(painter, base, doc, *extra):
    return [painter, "paint", doc, "--input", base.input, "--quiet", *extra]


def calls(log):
    """The traced calls in order: (syscall, the file it names)."""
    out = []
    for line in log.read_text().splitlines():
        m = re.match(r"^\d+\s+(\w+)\((?:AT_FDCWD|\d+)<([^>]*)>", line)
        if m and m.group(1) in SYSCALLS:
            out.append((m.group(1), m.group(2)))
    return out


def recovered(painter, doc):
    """How many strokes, undos and redos the journal gives back."""
    info = run([painter, "info", doc]).stdout
    m = re.search(r"journal\s+(\d+) stroke\(s\) not saved yet", info)
    return int(m.group(1)) if m else 0


def dump(painter, doc, out):
    run([painter, "dump", doc, out])
    return out.read_bytes()


@pytest.fixture(scope="module")
def expected(painter, tmp_path_factory):
    """The tree after the document and the first k ending events (stroke
    ends, undos, redos) of the session, for every k: replays of the trace
    followed by its own events cut after the k-th, times after its last."""
    folder = tmp_path_factory.mktemp("expected")
    lines = TRACE_TEXT.splitlines()
    header, events = lines[0], lines[1:]
    last_t = max(json.loads(e)["t"] for e in events)
    ends = [i for i, e in enumerate(events) if any(k in e for k in ENDS)]
    out = {}
    for k in range(len(ends) + 1):
        cut = events[: ends[k - 1] + 1] if k else []
        # Renders and snapshots change no tree (and their names are taken).
        kept = [json.loads(e) for e in cut if json.loads(e)["ev"] not in ("render", "snapshot")]
        shifted = [json.dumps({**e, "t": last_t + e["t"]}) for e in kept]
        t = folder / f"k{k}.jsonl"
        t.write_text("\n".join([header, *events, *shifted]) + "\n")
        doc = folder / f"k{k}.octo"
        run([painter, "import", t, doc])
        out[k] = dump(painter, doc, folder / f"k{k}.npz")
    return out


def test_a_fault_at_any_step_of_a_session_loses_no_completed_stroke(painter, tmp_path, base, expected):
    st = strace()
    # The clean run: every call, and what it leaves.
    doc = fresh(base, tmp_path / "clean")
    before = base.doc
    log = tmp_path / "clean.log"
    run([st, "-f", "-qq", "-y", "-o", log, "-e", "trace=" + ",".join(SYSCALLS), *session(painter, base, doc)])
    clean = dump(painter, doc, tmp_path / "clean.npz")
    order = calls(log)
    journal = str(doc) + ".journal"
    appends = [i for i, (name, f) in enumerate(order) if name == "fdatasync" and f == journal]
    renames = [i for i, (name, _) in enumerate(order) if name.startswith("rename")]
    assert len(appends) == len(expected) - 1, (appends, order)
    assert len(renames) == 2, order
    assert clean == expected[len(appends)]
    doc_renamed = renames[0]
    seen = {}
    for g, (name, target) in enumerate(order):
        n = seen[name] = seen.get(name, 0) + 1
        for errno, text in ERRNOS.items():
            what = f"{errno} at {name} #{n} ({os.path.basename(target)})"
            folder = tmp_path / f"{name}{n}{errno}"
            doc = fresh(base, folder)
            assert doc.read_bytes() == before
            r = run([st, "-f", "-qq", "-o", os.devnull, "-e", f"trace={name}", "-e", f"inject={name}:error={errno}:when={n}", *session(painter, base, doc)], ok=False)
            assert r.returncode != 0, what
            assert text in r.stderr and "octopaint:" in r.stderr, (what, r.stderr)
            assert "panicked" not in r.stderr, (what, r.stderr)
            # The document: the old one before its rename, the new one after.
            if g <= doc_renamed:
                assert doc.read_bytes() == before, what
            else:
                assert dump(painter, doc, folder / "after.npz") == clean, what
            # The journal reads, and gives back what was journalled.
            k = recovered(painter, doc)
            ok = sum(1 for a in appends if a < g)
            if g > doc_renamed:
                allowed = {0}  # every event is in the document already
            elif name == "fdatasync" and g in appends:
                allowed = {ok, ok + 1}  # its lines are in the file
            else:
                allowed = {ok}
            assert k in allowed, (what, k, allowed)
            run([painter, "recover", doc])
            want = expected[len(appends)] if g > doc_renamed else expected[k]
            assert dump(painter, doc, folder / "recovered.npz") == want, what
            assert not any(p.name.startswith(".tmp-") for p in folder.iterdir()), (what, sorted(os.listdir(folder)))
            shutil.rmtree(folder)


def test_with_keep_going_a_failed_append_is_written_by_the_next(painter, tmp_path, base, expected):
    """A live session goes on after a failed journal append: the stroke
    stays in the session, and the next flush writes the journal whole, so
    that the journal alone (the session does not save) gives back every
    stroke once, with no torn or repeated line."""
    st = strace()
    every = max(expected)
    for name in ("write", "fdatasync"):
        for n in range(1, every + 1):
            folder = tmp_path / f"{name}{n}"
            doc = fresh(base, folder)
            # The first write is the lock file's; the journal's follow.
            when = n + 1 if name == "write" else n
            r = run([st, "-f", "-qq", "-o", os.devnull, "-e", f"trace={name}", "-e", f"inject={name}:error=EIO:when={when}", *session(painter, base, doc, "--keep-going", "--no-save")], ok=False)
            what = f"EIO at {name} #{when}"
            assert r.returncode == 1, (what, r.returncode, r.stderr)
            assert "Input/output error" in r.stderr and "1 event(s) failed" in r.stderr, (what, r.stderr)
            assert doc.read_bytes() == base.doc, what
            if n < every:
                # A later flush wrote the failed one's lines.
                assert recovered(painter, doc) == every, what
                run([painter, "recover", doc])
                assert dump(painter, doc, folder / "recovered.npz") == expected[every], what
            else:
                # The last append failed and nothing came after it: the
                # journal holds the ones before (its fdatasync's lines too).
                assert recovered(painter, doc) in ({every - 1, every} if name == "fdatasync" else {every - 1}), what
            shutil.rmtree(folder)


def test_a_disk_that_fills_up_loses_nothing(painter, tmp_path, base, expected):
    """The session on a tmpfs that fills up part way: writes come back
    short, then ENOSPC, wherever the space ends (swept a page at a time
    across the session's appends and its save). Every time: a clear error,
    the document readable, the old one or the new one whole, and the
    journal's strokes recovered (on a roomy disk) to a tree the replay of
    exactly them."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root (CI and make test run as root)")
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    doc_size = len(base.doc)
    run(["mount", "-t", "tmpfs", "-o", f"size={2 * doc_size + (1 << 20)}", "tmpfs", mnt])
    try:
        doc = mnt / "d.octo"
        page = 4096
        # The room left when the session starts: none, a page or three
        # (the lock file, the journal's pages), half a document, about one
        # (the save's temporary file), and plenty.
        rooms = [0, page, 2 * page, 3 * page, doc_size // 2, doc_size - page, doc_size, doc_size + 2 * page, doc_size + 4 * page, doc_size + (1 << 19)]
        outcomes = set()
        for room in rooms:
            for p in mnt.iterdir():
                p.unlink()
            doc.write_bytes(base.doc)
            (mnt / "d.octo.journal").write_bytes(base.journal)
            free = shutil.disk_usage(mnt).free
            (mnt / "filler").write_bytes(b"\0" * max(0, free - room))
            r = run(session(painter, base, doc), ok=False)
            assert "panicked" not in r.stderr, (room, r.stderr)
            if r.returncode == 0:
                outcomes.add("saved")
                assert dump(painter, doc, tmp_path / "t.npz") == expected[max(expected)], room
                continue
            assert "No space left on device" in r.stderr, (room, r.stderr)
            # Room again: what is there reads, and recovers.
            (mnt / "filler").unlink()
            after = doc.read_bytes()
            k = recovered(painter, doc)
            run([painter, "recover", doc])
            tree = dump(painter, doc, tmp_path / "t.npz")
            if after == base.doc:
                outcomes.add("journal" if k else "nothing")
                assert tree == expected[k], (room, k)
            else:
                outcomes.add("document")
                assert tree == expected[max(expected)], room
            assert not any(p.name.startswith(".tmp-") for p in mnt.iterdir()), (room, sorted(os.listdir(mnt)))
        # The sweep reached the appends, the save and the end.
        assert {"nothing", "journal", "saved"} <= outcomes, outcomes
    finally:
        run(["umount", mnt])

"""Seed corpora for the painter's fuzz targets, generated (docs/documents.md,
"Fuzzing"): a folder per target, a few small files each, made from the
repository's traces by the painter itself, so that nothing of them is kept
in git and they follow the formats as they change.

    .venv/bin/python conformance/fuzz_seeds.py --painter painter/target/release/octopaint OUT

| target | seeds |
| --- | --- |
| trace_reader, replay | every trace under traces/ but the scene (replay: the valid ones) and the malformed ones (trace_reader) |
| voxels | the voxel sets of traces/imports/ of at most 16 KB |
| document | documents of format versions 1 (one tree), 2 (layers) and 3 (imports: traces/imports_budget.jsonl), from small traces |
| journal | journals painted against the journal target's own empty document (`octopaint fuzz-smoke --journal-base`): strokes, undo and redo, layers; one torn mid-line |
| vdb, glb, obj | a small painting exported (`octopaint export --vdb/--gltf/--obj`) |
| gltf | a glTF JSON tetrahedron with its buffer inline (a data URI), written here |
| every target | what a fuzzer once found: painter/fuzz/regressions/TARGET/* |

`octopaint fuzz-smoke OUT` runs every target on these and on variants of
them (CI); `make fuzz-long` gives them to libFuzzer as starting corpora.
"""

from __future__ import annotations

import argparse
import base64
import glob
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
TARGETS = ("trace_reader", "replay", "voxels", "document", "journal", "vdb", "glb", "gltf", "obj")
MAX_SEED = 64 * 1024


def run(cmd):
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{cmd}: exit {r.returncode}: {r.stderr}")
    return r


def put(out, target, name, data: bytes):
    if len(data) > MAX_SEED:
        raise RuntimeError(f"seed {target}/{name} is {len(data)} bytes, more than {MAX_SEED}: use a smaller input")
    with open(os.path.join(out, target, name), "wb") as f:
        f.write(data)


# The journal target's canvas (its empty document's), and a coarser one
# for documents small enough to be seeds.
JOURNAL_CANVAS = {"roots": [2, 1, 1], "max_depth": 8, "root_size": 1.0, "capacity": 16384}
SMALL_CANVAS = {"roots": [2, 1, 1], "max_depth": 4, "root_size": 1.0, "capacity": 2048}


def journal_trace(version: int = 1, canvas=JOURNAL_CANVAS) -> str:
    """Strokes, an undo, a redo and mirror planes on `canvas`; in version
    2 a second layer too."""
    head = {"format": "ddo-trace", "version": version, "canvas": canvas, "meta": {"title": "seed"}}
    ev = [{"ev": "brush", "t": 0.1, "shape": "sphere", "mode": "paint", "radius": 0.2, "color": [0.8, 0.3, 0.2], "opacity": 0.8, "hardness": 0.5}]
    t = 0.2
    for k in range(3):
        ev.append({"ev": "stroke_begin", "t": t})
        for i in range(4):
            ev.append({"ev": "sample", "t": t, "p": [0.4 + 0.3 * i + 0.1 * k, 0.5, 0.5]})
            t += 0.05
        ev.append({"ev": "stroke_end", "t": t})
        t += 0.1
    if version == 2:
        ev.append({"ev": "layer", "t": t, "op": "add", "name": "Layer 2"})
    ev.append({"ev": "undo", "t": t})
    ev.append({"ev": "redo", "t": t + 0.1})
    ev.append({"ev": "mirror", "t": t + 0.2, "axes": [True, False, False], "centre": [1.0, 0.5, 0.5]})
    ev.append({"ev": "stroke_begin", "t": t + 0.3})
    ev.append({"ev": "sample", "t": t + 0.3, "p": [0.6, 0.5, 0.5]})
    ev.append({"ev": "stroke_end", "t": t + 0.4})
    return "\n".join(json.dumps(e) for e in [head, *ev]) + "\n"


def gltf_triangle() -> bytes:
    """A glTF 2.0 JSON file: one closed tetrahedron, its buffer inline."""
    positions = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    indices = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]
    pos = b"".join(struct.pack("<3f", *p) for p in positions)
    idx = b"".join(struct.pack("<H", i) for i in indices)
    buf = pos + idx
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)}, {"buffer": 0, "byteOffset": len(pos), "byteLength": len(idx)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5123, "count": len(indices), "type": "SCALAR"},
        ],
    }
    return json.dumps(doc).encode()


def seeds(painter: str, out: str) -> dict[str, int]:
    for t in TARGETS:
        os.makedirs(os.path.join(out, t), exist_ok=True)
    traces = sorted(p for p in glob.glob(os.path.join(REPO, "traces", "*.jsonl")) if os.path.getsize(p) <= MAX_SEED)
    malformed = sorted(glob.glob(os.path.join(REPO, "traces", "malformed", "*.jsonl")))
    for p in traces:
        data = open(p, "rb").read()
        put(out, "trace_reader", os.path.basename(p), data)
        put(out, "replay", os.path.basename(p), data)
    for p in malformed:
        put(out, "trace_reader", "malformed-" + os.path.basename(p), open(p, "rb").read())
    for p in sorted(glob.glob(os.path.join(REPO, "traces", "imports", "*.npz"))):
        if os.path.getsize(p) <= 16 * 1024:
            put(out, "voxels", os.path.basename(p), open(p, "rb").read())
    with tempfile.TemporaryDirectory() as tmp:
        # Documents of each format version.
        for version in (1, 2):
            with open(os.path.join(tmp, f"v{version}.jsonl"), "w") as f:
                f.write(journal_trace(version, SMALL_CANVAS))
        made = ((1, os.path.join(tmp, "v1.jsonl")), (2, os.path.join(tmp, "v2.jsonl")), (3, os.path.join(REPO, "traces", "imports_budget.jsonl")))
        for version, trace in made:
            doc = os.path.join(tmp, f"v{version}.octo")
            run([painter, "import", trace, doc])
            data = open(doc, "rb").read()
            got = struct.unpack("<I", data[16:20])[0]
            if got != version:
                raise RuntimeError(f"{trace} made a document of format version {got}, not {version}")
            put(out, "document", f"v{version}.octo", data)
        # Journals against the journal target's own document.
        base = os.path.join(tmp, "base.octo")
        run([painter, "fuzz-smoke", tmp, "--journal-base", base])
        jt = os.path.join(tmp, "journal.jsonl")
        with open(jt, "w") as f:
            f.write(journal_trace())
        run([painter, "paint", base, "--input", jt, "--no-save", "--quiet"])
        journal = open(base + ".journal", "rb").read()
        put(out, "journal", "strokes.journal", journal)
        put(out, "journal", "torn.journal", journal[: len(journal) * 2 // 3])
        put(out, "journal", "header.journal", journal.split(b"\n", 1)[0] + b"\n")
        # A small painting exported.
        painting = os.path.join(tmp, "v1.jsonl")
        vdb, glb, obj = (os.path.join(tmp, f"p.{e}") for e in ("vdb", "glb", "obj"))
        run([painter, "export", painting, "--vdb", vdb, "--gltf", glb, "--obj", obj, "--max-mib", "1", "--mesh-depth", "2"])
        for target, path in (("vdb", vdb), ("glb", glb), ("obj", obj)):
            put(out, target, os.path.basename(path), open(path, "rb").read())
    put(out, "gltf", "tetrahedron.gltf", gltf_triangle())
    # What a fuzzer once found (painter/fuzz/regressions/TARGET).
    for t in TARGETS:
        for p in sorted(glob.glob(os.path.join(REPO, "painter", "fuzz", "regressions", t, "*"))):
            put(out, t, "regression-" + os.path.basename(p), open(p, "rb").read())
    return {t: len(os.listdir(os.path.join(out, t))) for t in TARGETS}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--painter", default=os.path.join(REPO, "painter", "target", "release", "octopaint"))
    ap.add_argument("out")
    a = ap.parse_args(argv)
    if os.path.exists(a.out):
        shutil.rmtree(a.out)
    counts = seeds(a.painter, a.out)
    for t, n in counts.items():
        print(f"{t:13} {n} seed(s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

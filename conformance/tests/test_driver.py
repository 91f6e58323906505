"""The conformance driver must find differences, not only report sameness:
each comparison is fed a planted difference and must name it."""

import os
import shutil
import stat
import subprocess
import sys

import dumps
import images
import numpy as np
import readers
from PIL import Image

CONFORMANCE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REPO = os.path.dirname(CONFORMANCE)


def _dump(painter, tmp_path, trace="single_stamp"):
    out = tmp_path / "painter"
    subprocess.run([painter, "replay", os.path.join(REPO, "traces", trace + ".jsonl"), "--out", str(out), "--quiet"], check=True)
    return dumps.load(str(out / (trace + ".npz")))


def test_every_array_difference_is_found_with_its_first_cell(painter, tmp_path):
    ref = _dump(painter, tmp_path)
    assert dumps.compare(ref, {k: v.copy() for k, v in ref.items()}) == []
    n = len(ref["parent"])
    for name in ("parent", "first_child", "depth", "origin", "g3", "rgb", "sigma"):
        other = {k: v.copy() for k, v in ref.items()}
        cells = [n // 3, n // 2]
        if name == "sigma":
            other[name][cells] = np.nextafter(other[name][cells], np.float32(np.inf))  # one ulp
        else:
            other[name][cells] ^= 1
        diffs = dumps.compare(ref, other)
        assert [(d.array, d.count, d.first_cell) for d in diffs] == [(name, 2, n // 3)], name
    other = {k: v.copy() for k, v in ref.items()}
    other["root_size"] = np.array(2.0)
    assert [d.array for d in dumps.compare(ref, other)] == ["root_size"]
    other = {k: v[:-8].copy() if v.ndim and k not in ("roots",) else v for k, v in ref.items()}
    assert "parent" in [d.array for d in dumps.compare(ref, other)]


def test_image_tolerance_accepts_noise_and_refuses_a_wrong_image(tmp_path):
    rng = np.random.default_rng(7)
    a = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    paths = {}
    sparse = a.astype(int)
    sparse[::10, ::10] += 1  # 1% of pixels one step off
    for name, img in {
        "a": a,
        "sparse": np.clip(sparse, 0, 255).astype(np.uint8),
        "noise": np.clip(a.astype(int) + rng.integers(-1, 2, a.shape), 0, 255).astype(np.uint8),
        "wrong": 255 - a,
    }.items():
        paths[name] = str(tmp_path / f"{name}.png")
        Image.fromarray(img).save(paths[name])
    assert images.compare(paths["a"], paths["a"]).ok
    ok = images.compare(paths["a"], paths["sparse"], str(tmp_path / "d1.png"))
    assert ok.ok and ok.max_steps == 1 and ok.psnr_db > 60
    # Dense one-step noise (PSNR 50 dB) passes the f16 tolerance, not the f32 one.
    assert images.compare(paths["a"], paths["noise"], None, images.IMAGE_TOLERANCES["f16"]).ok
    assert not images.compare(paths["a"], paths["noise"], None, images.IMAGE_TOLERANCES["f32"]).ok
    bad = images.compare(paths["a"], paths["wrong"], str(tmp_path / "d2.png"))
    assert not bad.ok and os.path.exists(tmp_path / "d2.png")


def test_reader_disagreements_are_reported(painter, tmp_path):
    fake = tmp_path / "fake_octopaint"
    # A painter whose reader accepts everything: its verdicts differ on every malformed trace.
    fake.write_text(
        "#!/usr/bin/env bash\n"
        f'"{painter}" "$@" | sed -e \'s/^\\["error".*/["canvas", [1, 1, 1], 6, 1.0, 4096]/\'\n'
        "exit 0\n"
    )
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    n, bad = readers.compare_readers(str(fake), REPO, str(tmp_path / "work"), 20)
    malformed = [p for p, _, _ in bad if "/malformed/" in p]
    assert len(malformed) >= 40
    assert n >= 60


def test_generated_variants_are_reproducible(tmp_path):
    a = readers.variants([os.path.join(REPO, "traces", "edges.jsonl")], 30, str(tmp_path / "a"))
    b = readers.variants([os.path.join(REPO, "traces", "edges.jsonl")], 30, str(tmp_path / "b"))
    assert [open(p, "rb").read() for p in a] == [open(p, "rb").read() for p in b]
    assert len({open(p, "rb").read() for p in a}) == 30


def test_the_driver_reports_a_planted_difference_with_the_cell_history(painter, tmp_path):
    # A painter that paints one cell one step redder than it should.
    fake = tmp_path / "fake_octopaint"
    fake.write_text(
        "#!/usr/bin/env bash\n"
        f'"{painter}" "$@" || exit $?\n'
        'if [ "$1" = replay ]; then\n'
        '  out="$4"\n'
        f'  "{sys.executable}" - "$out" <<\'PY\'\n'
        "import glob, sys, zipfile, io, numpy as np\n"
        f"sys.path.insert(0, {REPO + '/reference'!r})\n"
        "from octopaint_ref.dump import dump_bytes\n"
        "for p in glob.glob(sys.argv[1] + '/*.npz'):\n"
        "    with np.load(p) as z: d = {k: z[k].copy() for k in z.files}\n"
        "    d['rgb'][100, 0] ^= 1\n"
        "    open(p, 'wb').write(dump_bytes(d))\n"
        "PY\n"
        "fi\n"
    )
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    report = tmp_path / "report"
    res = subprocess.run(
        [sys.executable, os.path.join(CONFORMANCE, "driver.py"), os.path.join(REPO, "traces", "single_stamp.jsonl"),
         "--report", str(report), "--painter", str(fake), "--generated", "10"],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 1, res.stdout + res.stderr
    text = (report / "report.md").read_text()
    assert "**dump `single_stamp.npz`** differs" in text
    assert "`rgb`: 1 cells differ; first cell 100" in text
    assert "First differing cell 100" in text
    assert "Its history in the reference:" in text and "line 4 sample:" in text
    shutil.rmtree(report)


def test_the_real_painter_conforms_on_a_small_trace(painter, tmp_path):
    res = subprocess.run(
        [sys.executable, os.path.join(CONFORMANCE, "driver.py"), os.path.join(REPO, "traces", "undo_redo.jsonl"),
         "--report", str(tmp_path / "r"), "--painter", painter, "--generated", "50"],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stdout + res.stderr

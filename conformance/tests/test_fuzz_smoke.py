"""CI's short run of the readers' fuzz targets (docs/documents.md,
"Fuzzing"): the seed corpora generated from the repository's traces
(conformance/fuzz_seeds.py) are small and cover every target and every
document format version, and `octopaint fuzz-smoke` runs every target's body
on them and 20,000 deterministic variants each (about half a minute), with
no panic. The same bodies are painter/fuzz's cargo-fuzz targets, which
`make fuzz-long` runs under libFuzzer."""

import os
import re
import struct
import subprocess

import fuzz_seeds

RUNS = 20000


def test_the_seeds_are_small_and_cover_every_target(painter, tmp_path):
    counts = fuzz_seeds.seeds(painter, str(tmp_path))
    assert set(counts) == set(fuzz_seeds.TARGETS)
    assert all(n >= 1 for n in counts.values()), counts
    sizes = [os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(tmp_path) for f in fs]
    assert max(sizes) <= fuzz_seeds.MAX_SEED and sum(sizes) < 2 << 20, (max(sizes), sum(sizes))
    versions = sorted(struct.unpack("<I", open(tmp_path / "document" / f, "rb").read()[16:20])[0] for f in os.listdir(tmp_path / "document"))
    assert versions == [1, 2, 3], versions
    # The journal seeds extend the journal target's own document: the
    # painter recovers the full one's strokes.
    base = tmp_path / "base.octo"
    subprocess.run([painter, "fuzz-smoke", str(tmp_path), "--journal-base", str(base)], check=True)
    (tmp_path / "base.octo.journal").write_bytes((tmp_path / "journal" / "strokes.journal").read_bytes())
    info = subprocess.run([painter, "info", str(base)], capture_output=True, text=True, check=True).stdout
    assert re.search(r"journal\s+[1-9]\d* stroke\(s\) not saved yet", info), info


def test_every_target_runs_its_seeds_and_variants_without_a_panic(painter, tmp_path):
    seeds = tmp_path / "seeds"
    fuzz_seeds.seeds(painter, str(seeds))
    r = subprocess.run([painter, "fuzz-smoke", str(seeds), "--runs", str(RUNS), "--crashes", str(tmp_path / "crashes")], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, (r.stdout, r.stderr[-4000:])
    lines = {line.split()[0]: line for line in r.stdout.splitlines() if line.strip()}
    assert set(lines) == set(fuzz_seeds.TARGETS), r.stdout
    for line in lines.values():
        m = re.search(r"(\d+) seeds, (\d+) inputs, (\d+) panics", line)
        assert m and int(m.group(2)) == int(m.group(1)) + RUNS and m.group(3) == "0", line
    assert not (tmp_path / "crashes").exists()

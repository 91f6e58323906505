"""Differential fuzzing (conformance/fuzz.py): random traces replayed by the
reference and the painter must agree, and the fuzzer must find a painter
that leaves out a feature."""

import json
import stat

import fuzz

# About 2 s a seed (the reference's start-up and images): 32 seeds is about a
# minute of CI; `fuzz.py --seeds N` runs longer campaigns.
SEEDS = 32


def test_random_traces_are_reproducible_and_cover_the_features():
    a = [fuzz.random_trace(s) for s in range(SEEDS)]
    assert a == [fuzz.random_trace(s) for s in range(SEEDS)]
    events = [json.loads(line) for t in a for line in t.splitlines()[1:]]
    kinds = {e["ev"] for e in events}
    assert {"brush", "sample", "mirror", "undo", "redo", "layer", "import", "snapshot"} <= kinds, kinds
    brushes = [e for e in events if e["ev"] == "brush"]
    assert {b["shape"] for b in brushes} == set(fuzz.SHAPES)
    assert {b["mode"] for b in brushes} == set(fuzz.MODES)
    assert {b["hardness"] for b in brushes} == set(fuzz.HARDNESS)
    headers = [json.loads(t.splitlines()[0]) for t in a]
    assert {h["version"] for h in headers} == {1, 2}
    assert min(h["canvas"]["capacity"] for h in headers) <= 4000  # budget refusals
    depths = {h["canvas"]["max_depth"] for h in headers}
    assert min(depths) <= 1 and max(depths) >= 25, depths  # a root that barely refines, 0.3 mm cells


def test_the_painter_agrees_with_the_reference_on_random_traces(painter, tmp_path):
    bad = fuzz.fuzz(painter, range(SEEDS), str(tmp_path), log=lambda _: None)
    reports = {s: (tmp_path / f"fuzz_{s}.md").read_text()[:2000] for s in bad}
    assert bad == [], reports


def test_the_fuzzer_finds_a_painter_without_mirror_painting(painter, tmp_path):
    # A painter that replays every trace with its mirror events left out.
    fake = tmp_path / "no_mirror_octopaint"
    fake.write_text(
        "#!/usr/bin/env bash\n"
        'if [ "$1" = replay ]; then\n'
        '  grep -v \'"ev": "mirror"\' "$2" > "$2.no_mirror"\n'
        f'  exec "{painter}" replay "$2.no_mirror" "${{@:3}}"\n'
        "fi\n"
        f'exec "{painter}" "$@"\n'
    )
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)

    def mirrors(seed):
        return any(e.get("ev") == "mirror" and any(e["axes"]) for e in map(json.loads, fuzz.random_trace(seed).splitlines()[1:]))

    seeds = [s for s in range(200) if mirrors(s)][:8]
    out = tmp_path / "out"
    bad = fuzz.fuzz(str(fake), seeds, str(out), log=lambda _: None)
    assert bad, "no seed with mirror copies differed"
    for s in bad:
        assert (out / f"fuzz_{s}.jsonl").exists() and (out / f"fuzz_{s}.md").read_text()
    # The seeds that agreed leave nothing behind.
    assert sorted(p.name for p in out.glob("fuzz_*.jsonl")) == sorted(f"fuzz_{s}.jsonl" for s in bad)

"""The trace reader: every malformed trace fails with its exact message and
nothing is written; valid traces parse."""

import json
import os
import subprocess
import sys

import pytest

from conftest import TRACES
from octopaint_ref.trace import TraceError, parse_trace, read_trace

EXPECTED = json.load(open(os.path.join(TRACES, "malformed", "expected.json")))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_malformed_trace_fails_with_its_message(name):
    with pytest.raises(TraceError) as e:
        read_trace(os.path.join(TRACES, "malformed", name))
    assert str(e.value) == EXPECTED[name]


def test_every_malformed_file_has_an_expected_message():
    files = {f for f in os.listdir(os.path.join(TRACES, "malformed")) if f.endswith(".jsonl")}
    assert files == set(EXPECTED)


@pytest.mark.parametrize("name", ["name_traversal.jsonl", "nan_sample.jsonl", "absurd_segment.jsonl"])
def test_cli_writes_nothing_for_a_bad_trace(tmp_path, name):
    out = tmp_path / "out"
    r = subprocess.run(
        [sys.executable, "-m", "octopaint_ref.cli", "replay", os.path.join(TRACES, "malformed", name), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2
    assert EXPECTED[name] in r.stderr
    assert not out.exists()


H = '{"format": "ddo-trace", "version": 1, "canvas": {"roots": [1, 1, 1], "max_depth": 6, "root_size": 1.0, "capacity": 4096}}'


def test_defaults_unknown_keys_and_blank_lines():
    t = parse_trace(
        H
        + "\n\n"
        + '{"ev": "brush", "t": 0, "shape": "noise", "mode": "mix", "radius": 0.1, "color": [1, 0, 0], '
        '"opacity": 1, "hardness": 0.5, "future_key": 3}\n'
        '{"ev": "stroke_begin", "t": 0}\n{"ev": "sample", "t": 0, "p": [2, -1, 0.5]}\n'
    )
    b = t.events[0].value
    assert (b.spacing, b.mix_ratio, b.pickup_rate, b.noise.octaves, b.noise.seed) == (0.25, 1.0, 0.25, 4, 0)
    s = t.events[2].value
    assert s.pressure == 1.0 and s.q == (0.0, 0.0, 0.0, 1.0)
    # the trace ends inside the stroke: ended with a warning, not an error
    assert t.events[-1].kind == "stroke_end"
    assert "ends inside this stroke" in t.warnings[0]


def test_redo_history_is_dropped_by_a_new_stroke():
    br = '{"ev": "brush", "t": 0, "shape": "sphere", "mode": "paint", "radius": 0.1, "color": [1, 0, 0], "opacity": 1, "hardness": 0.5}'
    stroke = '{"ev": "stroke_begin", "t": 0}\n{"ev": "sample", "t": 0, "p": [0.5, 0.5, 0.5]}\n{"ev": "stroke_end", "t": 0}\n'
    with pytest.raises(TraceError, match="line 10: ev: redo with nothing undone"):
        parse_trace(H + "\n" + br + "\n" + stroke + '{"ev": "undo", "t": 0}\n' + stroke + '{"ev": "redo", "t": 0}\n')


@pytest.mark.parametrize("name", sorted(f for f in os.listdir(TRACES) if f.endswith(".jsonl")))
def test_checked_in_traces_parse(name):
    t = read_trace(os.path.join(TRACES, name))
    assert t.events

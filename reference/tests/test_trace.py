"""The trace reader: every malformed trace fails on its line with its error
kind (spec 12.2) and nothing is written; valid traces parse."""

import json
import os
import subprocess
import sys

import pytest
from conftest import TRACES
from octopaint_ref.trace import TraceError, parse_trace, read_trace

EXPECTED = json.load(open(os.path.join(TRACES, "malformed", "expected.json")))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_malformed_trace_fails_on_its_line_with_its_kind(name):
    with pytest.raises(TraceError) as e:
        read_trace(os.path.join(TRACES, "malformed", name))
    assert (e.value.line, e.value.kind) == (EXPECTED[name]["line"], EXPECTED[name]["kind"]), str(e.value)
    assert str(e.value).startswith(f"line {e.value.line}: "), str(e.value)


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
    assert f"line {EXPECTED[name]['line']}: " in r.stderr
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


@pytest.mark.parametrize(
    "value",
    ["NaN", "-Infinity", "1.8e308", "1e999", "1e0309", "2" + "0" * 308, "1" + "0" * 250 + "e99", "1" + "0" * 5000,
     '0, "x": "\\ud800"', '0, "\\udfff": 0', '0, "t": "\\udc00", "t": 0'],
)
def test_json_rules_refuse(value):
    """Spec 12.2: what is not JSON (or beyond f64) is refused as `json` on its line."""
    with pytest.raises(TraceError) as e:
        parse_trace(H + '\n{"ev": "undo", "t": ' + value + "}")
    assert (e.value.line, e.value.kind) == (2, "json"), str(e.value)


def test_json_rules_accept():
    line = '{"ev": "camera", "t": 5, "t": 1e-400, "eye": [1.7976931348623157e308, 1' + "0" * 200 + ', 0], "q": [0, 0, 0, 1], ' \
        '"fov": [-0.5, 0.5, 0.5, -0.5], "size": [4, 4], "x": "\\ud83d\\ude00"}'
    t = parse_trace(H + "\n" + line)
    assert t.events[0].t == 0.0 and t.events[0].value.eye[:2] == (1.7976931348623157e308, 1e200)
    deep = '{"ev": "camera", "t": 0, "x": ' + "[" * 64 + "]" * 64 + "}"
    with pytest.raises(TraceError) as e:
        parse_trace(H + "\n" + deep)
    assert (e.value.line, e.value.kind) == (2, "json")

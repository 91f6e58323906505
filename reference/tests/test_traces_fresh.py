"""Checked-in traces are exactly what traces/generate.py writes."""

import os
import subprocess
import sys

from conftest import TRACES


def _files(root):
    out = {}
    for d, _, names in os.walk(root):
        for n in names:
            if n.endswith((".jsonl", ".json", ".npz")):
                p = os.path.join(d, n)
                out[os.path.relpath(p, root)] = open(p, "rb").read()
    return out


def test_traces_are_not_stale(tmp_path):
    subprocess.run([sys.executable, os.path.join(TRACES, "generate.py"), "--out", str(tmp_path)], check=True, capture_output=True)
    fresh = _files(tmp_path)
    checked_in = _files(TRACES)
    assert sorted(fresh) == sorted(checked_in), "a trace was added or removed without regenerating"
    stale = [k for k in fresh if fresh[k] != checked_in[k]]
    assert not stale, f"stale traces (run python3 traces/generate.py): {stale}"

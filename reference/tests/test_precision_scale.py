"""The precision study at scale (precision_scale.py): its reductions are
exact, so one device, eight simulated devices and two processes on
localhost give the same bits; an interrupted run resumes from its
checkpoints to the same result."""

import json
import os
import socket
import subprocess
import sys

import numpy as np
from octopaint_ref.precision_scale import empty_summary, merge, summarise

ARGS = ["--rays", "600", "--shard", "256", "--precision", "f16", "--quiet"]


def run(tmp_path, name, *extra, env=None, check=True):
    out = tmp_path / f"{name}.json"
    cmd = [sys.executable, "-m", "octopaint_ref.precision_scale", *ARGS, "--out", str(out), *extra]
    r = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **(env or {})}, timeout=600)
    if check:
        assert r.returncode == 0, r.stderr
    return r, out


def test_merging_summaries_is_exact_in_any_order_and_partition():
    rng = np.random.default_rng(5)
    angle = 10.0 ** rng.uniform(-12, -3, 1000)
    angle[[100, 700]] = angle.max() * 2  # a tie: the smaller index must win
    within = rng.random(1000) < 0.9
    e0 = rng.random(1000)
    whole = summarise(0, angle, within, e0)
    assert whole["argmax"] == 100 and whole["rays"] == 1000 and sum(whole["hist"]) == 1000
    for cuts in ([500], [1, 999], [100, 101, 700, 701], list(range(50, 1000, 50))):
        parts = [summarise(a, angle[a:b], within[a:b], e0[a:b]) for a, b in zip([0] + cuts, cuts + [1000])]
        for order in (parts, parts[::-1], parts[1::2] + parts[::2]):
            total = empty_summary()
            for p in order:
                total = merge(total, p)
            assert total == whole


def test_one_device_eight_devices_and_two_processes_agree(tmp_path):
    _, one = run(tmp_path, "one")
    _, eight = run(tmp_path, "eight", env={"XLA_FLAGS": "--xla_force_host_platform_device_count=8"})
    with socket.socket() as s:
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    # Two processes of two devices each (JAX gathers across processes that
    # hold the same number of devices).
    coord = ["--processes", "2", "--coordinator", f"localhost:{port}"]
    two_devices = {"XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    p0 = subprocess.Popen(
        [sys.executable, "-m", "octopaint_ref.precision_scale", *ARGS, "--out", str(tmp_path / "two.json"), *coord, "--process-id", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, **two_devices},
    )
    run(tmp_path, "unused", *coord, "--process-id", "1", env=two_devices)
    assert p0.wait(timeout=600) == 0, p0.stderr.read()
    results = [json.loads(p.read_text()) for p in (one, eight, tmp_path / "two.json")]
    assert results[0]["rays"] == 600 and results[0]["within"] == 600  # every f16 ray within the bound
    assert results[0]["max_angle"] > 0
    assert results[0] == results[1] == results[2]
    assert not (tmp_path / "unused.json").exists()  # only process 0 writes


def test_an_interrupted_run_resumes_from_its_checkpoints(tmp_path):
    ck = ["--checkpoint", str(tmp_path / "ck")]
    r, out = run(tmp_path, "cut", *ck, "--stop-after", "1", check=False)
    assert r.returncode == 3 and not out.exists()
    assert sorted(os.listdir(tmp_path / "ck")) == ["shard_0000000.json"]
    first = (tmp_path / "ck" / "shard_0000000.json").read_text()
    _, resumed = run(tmp_path, "resumed", *ck)
    _, straight = run(tmp_path, "straight")
    assert sorted(os.listdir(tmp_path / "ck")) == ["shard_0000000.json", "shard_0000001.json", "shard_0000002.json"]
    assert (tmp_path / "ck" / "shard_0000000.json").read_text() == first  # not recomputed
    assert json.loads(resumed.read_text()) == json.loads(straight.read_text())

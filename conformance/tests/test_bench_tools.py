"""The core's benchmark tools keep working: painter/bench/many_cores.sh (and
tree_vs_openvdb.sh inside it) end to end at a toy radius against the real
OpenVDB peer, the table's thread-count checks, and the flame graph maker
(docs/benchmarks.md)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BENCH = os.path.join(REPO, "painter", "bench")
sys.path.insert(0, BENCH)

import flamegraph  # noqa: E402


def test_many_cores_runs_every_part_at_a_toy_radius(tmp_path, painter):
    env = dict(os.environ, THREADS="2", SCENE_RUNS="2", REALTIME_SIZE="48x27", OCTOPAINT=painter,
               BUILD=str(tmp_path / "build"), NODEVICE_SELECT="1")
    p = subprocess.run(["bash", os.path.join(BENCH, "many_cores.sh"), str(tmp_path / "out"), "2"],
                       capture_output=True, text=True, env=env, timeout=900)
    assert p.returncode == 0, p.stdout[-4000:] + p.stderr[-4000:]
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert p.stdout.endswith(summary)
    # 1 is always run beside the counts asked for.
    assert "- threads: 1 2" in summary and "threads 1, 2." in summary
    scene = re.findall(r"^\| (\d+) \| ([0-9.]+) \| ([0-9. ]+)\| ([0-9.]+)x \|$", summary, re.M)
    assert [row[0] for row in scene] == ["1", "2"], summary
    assert all(len(row[2].split()) == 2 and float(row[1]) > 0 for row in scene)
    realtime = [ln for ln in summary.splitlines() if re.match(r"^\| (10|32) \| ", ln)]
    assert len(realtime) == 2 and not any("failed" in ln for ln in realtime), summary
    for ln in realtime:
        p50, p99 = (float(x) for x in ln.split("|")[3:5])
        assert 0 < p50 <= p99
    # Both programs at both counts, with the scaling rows; no density-only
    # rows (CONTEXT=0 inside many_cores.sh).
    assert re.search(r"^\| 2 \| octopaint \| 2 \| ", summary, re.M)
    assert re.search(r"^\| 2 \| OpenVDB [0-9.]+ \| 2 \| ", summary, re.M)
    assert re.search(r"^\| 2 \| OpenVDB \| 1\.00x \| [0-9.]+x \|$", summary, re.M)
    assert "Density only" not in summary
    files = subprocess.run(["tar", "-tzf", str(tmp_path / "out" / "files.tar.gz")], capture_output=True, text=True, check=True).stdout
    assert "files/tree/octopaint_2_2.json" in files and "files/realtime_32/results.json" in files


def _runs(build, digests, sums):
    """JSON files as tree_vs_openvdb.sh writes them, for threads 1, 2, 4."""
    for t, digest, s in zip(("1", "2", "4"), digests, sums):
        o = {"seconds": 2.0 / int(t) ** 0.5, "cell_updates": 1e7, "cells_used": 1e6, "leaves": 8e5,
             "bytes_per_cell_pools": 16, "bytes_per_cell_allocated": 16.5, "history_bytes_per_cell": 0.5,
             "peak_rss_mib": 100.0, "tree_digest": digest, "cells_created": 1.2e6, "cells_created_per_s": 1e6,
             "stroke_end_seconds": 0.1}
        v = {"seconds": 1.0 / int(t), "voxel_writes": 2e7, "active_voxels": 7e5, "mem_bytes": 2e7,
             "peak_rss_mib": 120.0, "version": "10.0.1", "sigma_sum": s, "rgb_sum": 5.0}
        (build / f"octopaint_{t}_3.json").write_text(json.dumps(o))
        (build / f"openvdb_equal_{t}_3.json").write_text(json.dumps(v))


def _table(build):
    return subprocess.run([sys.executable, os.path.join(BENCH, "tree_vs_openvdb_table.py"), str(build), "1,2,4", "0", "3"],
                          capture_output=True, text=True)


def test_the_table_prints_every_thread_count_and_refuses_a_different_tree(tmp_path):
    _runs(tmp_path, ["a", "a", "a"], [1.0, 1.0, 1.0])
    p = _table(tmp_path)
    assert p.returncode == 0, p.stderr
    assert "| 3 | octopaint | 4 | 1.00 |" in p.stdout
    assert "| 3 | 4 | 0.25x |" in p.stdout  # OpenVDB 0.25 s against octopaint's 1.00 s
    assert "| 3 | octopaint | 1.00x | 1.41x | 2.00x |" in p.stdout
    assert "| 3 | OpenVDB | 1.00x | 2.00x | 4.00x |" in p.stdout

    _runs(tmp_path, ["a", "a", "b"], [1.0, 1.0, 1.0])
    p = _table(tmp_path)
    assert p.returncode != 0 and "octopaint painted differently on 1 and 4 threads" in p.stderr
    _runs(tmp_path, ["a", "a", "a"], [1.0, 1.5, 1.0])
    p = _table(tmp_path)
    assert p.returncode != 0 and "OpenVDB painted differently on 1 and 2 threads" in p.stderr


PERF_SCRIPT = """\
octopaint 11009   796.234744:    5000000 cpu-clock:pppH:
\t          fea941 octopaint_tree::lanes::avx::unit_coverage+0x481 (/x/octopaint)
\t          ff73e4 octopaint_tree::paint::walk_run+0x8f4 (/x/octopaint)
\t          ff3555 octopaint_tree::paint::Painting::step+0x4535 (/x/octopaint)
\t          febc37 octopaint_tree::paint::Painting::add_sample+0x27 (/x/octopaint)
\t          58f1cc main+0x12c (/x/octopaint)

octopaint 11009   796.243761:    5000000 cpu-clock:pppH:
\t          ffb434 octopaint_tree::balance::<impl octopaint_tree::pool::Tree>::neighbour+0x134 (/x/octopaint)
\t          ff3555 octopaint_tree::paint::Painting::step+0x4535 (/x/octopaint)
\t          febc37 octopaint_tree::paint::Painting::add_sample+0x27 (/x/octopaint)
\t          58f1cc main+0x12c (/x/octopaint)

octopaint 11009   796.253761:    5000000 cpu-clock:pppH:
\t          ff3555 octopaint_tree::paint::Painting::step+0x4535 (/x/octopaint)
\t          febc37 octopaint_tree::paint::Painting::add_sample+0x27 (/x/octopaint)
\t          58f1cc main+0x12c (/x/octopaint)

octopaint 11009   796.263761:    5000000 cpu-clock:pppH:
\t          1 octopaint::bench_tree::digest+0x1 (/x/octopaint)
\t          58f1cc main+0x12c (/x/octopaint)

helper 11010   796.263761:    5000000 cpu-clock:pppH:
\t          febc37 octopaint_tree::paint::Painting::add_sample+0x27 (/x/octopaint)
"""


def test_the_flame_graph_folds_stacks_and_draws_their_shares():
    counts = flamegraph.fold(PERF_SCRIPT.splitlines(), "octopaint", re.compile(r"Painting::add_sample$"))
    step = ("octopaint_tree::paint::Painting::add_sample", "octopaint_tree::paint::Painting::step")
    assert counts == {
        step + ("octopaint_tree::paint::walk_run", "octopaint_tree::lanes::avx::unit_coverage"): 1,
        step + ("octopaint_tree::balance::Tree::neighbour",): 1,
        step: 1,
    }
    svg = flamegraph.render(counts, "t")
    boxes = {m[0]: float(m[1]) for m in re.findall(r"<title>([^:]+(?:::[^:]+)*): \d+ samples, ([0-9.]+)%</title>", svg)}
    assert boxes["octopaint_tree::paint::Painting::add_sample"] == 100.0
    assert boxes["octopaint_tree::paint::Painting::step"] == 100.0
    assert boxes["octopaint_tree::paint::walk_run"] == pytest.approx(33.3, abs=0.1)
    assert boxes["octopaint_tree::balance::Tree::neighbour"] == pytest.approx(33.3, abs=0.1)
    # Without a cut every thread's stacks stay, rooted at their outermost frame.
    assert sum(flamegraph.fold(PERF_SCRIPT.splitlines(), "", None).values()) == 5
    assert flamegraph.short("<alloc::vec::Vec<T> as alloc::vec::spec_from_iter::SpecFromIter<T,I>>::from_iter+0x12") == \
        "Vec as SpecFromIter::from_iter"
    assert flamegraph.short("alloc::vec::Vec<T,A>::extend_with::h0123456789abcdef") == "alloc::vec::Vec::extend_with"


def test_the_window_benchmark_makes_valid_traces_and_its_table(tmp_path, painter):
    """painter/bench/window_engine.py: the traces it plays are ones the
    painter reads (the scene as four layers imports as a document of four
    layers), and its table classes frames by what the frame log says."""
    import window_engine

    window_engine.traces(tmp_path)
    for name in ("heavy.jsonl", "heavy_layers.jsonl", "scene_layers.jsonl"):
        p = subprocess.run([painter, "check", str(tmp_path / name)], capture_output=True, text=True)
        assert p.returncode == 0, (name, p.stdout, p.stderr)
    doc = tmp_path / "four.octo"
    p = subprocess.run([painter, "import", str(tmp_path / "scene_layers.jsonl"), str(doc)], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    info = subprocess.run([painter, "info", str(doc)], capture_output=True, text=True).stdout
    assert len([line for line in info.splitlines() if " cells, opacity" in line]) == 4, info
    # A frame log: two warm-up frames, orbiting at 100 ms, painting with
    # one frame of 400 ms (inside the heavy strokes' span), a save of 300 ms.
    t0, t1 = window_engine.heavy_span(tmp_path)
    head = "t_ms,interval_ms,scale,width,height,still,mirror,cast,engine,prepare_ms"
    rows, t = [], 0.0
    def frame(iv, engine=0, still=0):
        nonlocal t
        t += iv
        rows.append(f"{t:.1f},{iv:.2f},0.5,400,300,{still},0,1,{engine},1.0")
    frame(0), frame(3000), frame(100)
    while t < 1e3 * t0:
        frame(100)
    frame(400, 1)
    while t < 1e3 * (t1 + 1.0):
        frame(100)
    frame(300, 2), frame(100), frame(5000, 0, 1)
    for run in ("one_tree", "four_layers"):
        (tmp_path / f"{run}.csv").write_text(head + "\n" + "\n".join(rows) + "\n")
        (tmp_path / f"{run}.log").write_text("octopaint: saved x (12 ms)\noctopaint: 9 jobs shown, stroke-to-display latency p50 1.0 ms, p99 2.0 ms; the heaviest sample painted in 3.0 ms\n")
    import contextlib
    import io
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        window_engine.report(tmp_path)
    table = out.getvalue()
    row = next(line for line in table.splitlines() if line.startswith("| one tree"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2] == "100", row  # the median frame
    assert cells[4].endswith("/ 400"), row  # painting's longest frame
    # The intervals either side of a frame that began while saving.
    assert cells[5] == "2, 300 / 300", row
    assert cells[6] == "4.00x", row
    assert cells[7] == "1.0 ms / 2.0 ms" and cells[8] == "3.0", row
    # The headset's runs (painter/bench/vr_engine.sh): the same table from
    # OUT/vr_<run>.csv and the headset's log lines ("octopaint: vr: ...").
    for run in ("one_tree", "four_layers"):
        (tmp_path / f"vr_{run}.csv").write_text(head + "\n" + "\n".join(rows) + "\n")
        (tmp_path / f"vr_{run}.log").write_text("octopaint: vr: 9 jobs shown, stroke-to-display latency p50 5.0 ms, p99 6.0 ms; the heaviest sample painted in 7.0 ms\noctopaint: vr: saved x (12 ms)\n")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        window_engine.report(tmp_path, "vr_")
    vr_row = next(line for line in out.getvalue().splitlines() if line.startswith("| one tree"))
    vr_cells = [c.strip() for c in vr_row.strip("|").split("|")]
    assert vr_cells[:7] == cells[:7], vr_row
    assert vr_cells[7] == "5.0 ms / 6.0 ms" and vr_cells[8] == "7.0", vr_row

"""The traces and the table of painter/bench/window_engine.sh: the desktop
window as a front end of the real-time engine (docs/benchmarks.md, "The
window through the engine").

    window_engine.py traces OUT    # OUT/scene_layers.jsonl, OUT/heavy.jsonl, OUT/heavy_layers.jsonl
    window_engine.py report OUT [PREFIX]   # the table from OUT/<PREFIX><run>.csv and .log

The headset's runs (painter/bench/vr_engine.sh) use the same traces and
table, with PREFIX `vr_`: their frame logs have the same columns.

`heavy.jsonl` is the paper's limitation case (its section 8.3) on the scene's
canvas: after 3 s of nothing, an erase of radius 5 canvas units through the
scene's finest detail (depth 21 to 25), a paint stroke of radius 5 back across
it, and a sphere of haze of radius 3000 over the island, at an artist's pace.
`scene_layers.jsonl` is the scene trace as a document of four layers (a
`layer add` before each quarter of its strokes), `heavy_layers.jsonl` the
heavy strokes for it (version 2).
"""

import json
import statistics
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def strokes(t0):
    """The heavy strokes' events from time t0: (brush, samples) per stroke."""
    out = []
    t = t0

    def stroke(brush, points, dt):
        nonlocal t
        out.append({"ev": "brush", "t": round(t, 4), **brush})
        out.append({"ev": "stroke_begin", "t": round(t, 4)})
        for p in points:
            out.append({"ev": "sample", "t": round(t, 4), "p": p})
            t += dt
        out.append({"ev": "stroke_end", "t": round(t, 4)})
        t += 0.5

    base = {"shape": "sphere", "opacity": 0.9, "hardness": 0.6}
    detail = [[19997.0 + 0.75 * i, 20000.0, 20000.0 + 0.1 * i] for i in range(9)]
    stroke({**base, "mode": "erase", "radius": 5.0, "color": [0, 0, 0]}, detail, 0.12)
    stroke({**base, "mode": "paint", "radius": 5.0, "color": [0.9, 0.3, 0.2]}, list(reversed(detail)), 0.12)
    haze = [[17000.0 + 800.0 * i, 21000.0, 19500.0] for i in range(8)]
    stroke({**base, "mode": "paint", "radius": 3000.0, "opacity": 0.05, "color": [0.6, 0.7, 0.9]}, haze, 0.15)
    return out


def write(path, header, events):
    with open(path, "w") as f:
        f.write(json.dumps(header) + "\n")
        for e in events:
            f.write(json.dumps(e) + "\n")


def traces(out):
    out = Path(out)
    lines = (REPO / "traces/scene.jsonl").read_text().splitlines()
    header = json.loads(lines[0])
    events = [json.loads(line) for line in lines[1:]]
    # The heavy strokes, one tree and layers: a camera at t = 0 so that the
    # window plays them after 3 s of nothing.
    camera = next(e for e in events if e["ev"] == "camera")
    pre = [{**camera, "t": 0.0}]
    write(out / "heavy.jsonl", header, pre + strokes(3.0))
    layered = {**header, "version": 2}
    write(out / "heavy_layers.jsonl", layered, pre + strokes(3.0))
    # The scene as four layers: a new layer before each quarter of its strokes.
    begins = [i for i, e in enumerate(events) if e["ev"] == "stroke_begin"]
    cut = {begins[len(begins) * k // 4] for k in (1, 2, 3)}
    split = []
    n = 1
    for i, e in enumerate(events):
        if i in cut:
            # A brush event belongs to its stroke: the layer goes before it.
            j = len(split)
            while j > 0 and split[j - 1]["ev"] == "brush":
                j -= 1
            n += 1
            split.insert(j, {"ev": "layer", "t": split[j - 1]["t"] if j else 0.0, "op": "add", "name": f"Layer {n}"})
        split.append(e)
    write(out / "scene_layers.jsonl", layered, split)


def load(path):
    rows = []
    with open(path) as f:
        head = f.readline().strip().split(",")
        for line in f:
            rows.append(dict(zip(head, map(float, line.strip().split(",")))))
    return rows


def pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))] if xs else float("nan")


def heavy_span(out):
    """The heavy trace's strokes: from the first brush to the last stroke's end, s."""
    events = [json.loads(line) for line in (Path(out) / "heavy.jsonl").read_text().splitlines()[1:]]
    times = [e["t"] for e in events if e["ev"] != "camera"]
    return min(times), max(times)


def report(out, prefix=""):
    out = Path(out)
    t0, t1 = heavy_span(out)
    print("| document | frames | median frame ms | view moving, nothing else: frames, p50 / p99 ms | painting: frames, p50 / p99 / max ms | saving: frames, p50 / max ms | longest painting or saving / median | latency p50 / p99 ms | heaviest sample ms |")
    print("| --- | ---: | ---: | --- | --- | --- | ---: | --- | ---: |")
    for run in ("one_tree", "four_layers"):
        rows = load(out / f"{prefix}{run}.csv")
        log = (out / f"{prefix}{run}.log").read_text()
        # The trace plays from the first frame presented (row 0): its
        # strokes paint from t0 to t1 after it (and their last levels and
        # uploads a little after: half a second more). The first two
        # intervals hold the ray caster's compilation and the opening
        # upload: left out.
        start = rows[0]["t_ms"]
        span = (start + 1e3 * t0, start + 1e3 * (t1 + 0.5))
        orbit, paint, save = [], [], []
        for a, b in list(zip(rows, rows[1:]))[2:]:
            iv = b["interval_ms"]
            if b["still"]:
                # The view stopped (the orbit's end): the window draws
                # nothing until something changes, so the interval is idle
                # time, not a frame.
                continue
            if a["engine"] == 2 or b["engine"] == 2:
                save.append(iv)
            elif a["t_ms"] < span[1] and b["t_ms"] > span[0]:
                paint.append(iv)
            elif a["engine"] == 0 and b["engine"] == 0:
                orbit.append(iv)
        every = orbit + paint + save
        median = statistics.median(every)
        summary = next((line for line in log.splitlines() if "stroke-to-display latency" in line), "")
        lat = summary.split("latency ")[1].split(";")[0].replace("p50 ", "").replace(", p99 ", " / ") if summary else "-"
        heaviest = summary.split("painted in ")[1].replace(" ms", "") if "painted in" in summary else "-"
        busy = paint + save
        prep = max((b["prepare_ms"] for a, b in zip(rows, rows[1:]) if a["t_ms"] < span[1] and b["t_ms"] > span[0]), default=float("nan"))
        print(f"<!-- {run}: the longest uploads and g3 of a frame while painting took {prep:.0f} ms -->")
        print(
            f"| {run.replace('_', ' ')} | {len(rows)} | {median:.0f} | {len(orbit)}, {pct(orbit, 0.5):.0f} / {pct(orbit, 0.99):.0f} | "
            f"{len(paint)}, {pct(paint, 0.5):.0f} / {pct(paint, 0.99):.0f} / {max(paint, default=float('nan')):.0f} | "
            f"{len(save)}, {pct(save, 0.5):.0f} / {max(save, default=float('nan')):.0f} | "
            f"{max(busy, default=float('nan')) / median:.2f}x | {lat} | {heaviest} |"
        )
        saves = [line.split("(")[-1].rstrip(")") for line in log.splitlines() if "saved " in line]
        print(f"<!-- {run}: saves took {', '.join(saves)} -->")


if __name__ == "__main__":
    {"traces": traces, "report": report}[sys.argv[1]](*sys.argv[2:])

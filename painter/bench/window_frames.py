"""The table and plot of painter/bench/window_frames.sh: frame intervals and
resolution of the desktop window over one scripted session, with dynamic
resolution and with the resolution fixed (docs/desktop.md)."""

import csv
import statistics
import sys


def load(path):
    with open(path) as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))] if xs else float("nan")


out = sys.argv[1]
runs = {mode: load(f"{out}/{mode}.csv") for mode in ("dynamic", "fixed")}
print("| run | frames | moving: frames, interval p50 / p90 ms, mean scale | still: frames, interval p50 ms |")
print("| --- | ---: | --- | --- |")
for mode, rows in runs.items():
    # A frame's interval is the time since the previous frame began: it
    # belongs to the previous frame's kind.
    moving = [b["interval_ms"] for a, b in zip(rows, rows[1:]) if not a["still"]]
    scales = [r["scale"] for r in rows if not r["still"]]
    still = [b["interval_ms"] for a, b in zip(rows, rows[1:]) if a["still"]]
    print(
        f"| {mode} | {len(rows)} | {len(moving)}, {pct(moving, 0.5):.0f} / {pct(moving, 0.9):.0f}, "
        f"{statistics.mean(scales) if scales else float('nan'):.2f} | {len(still)}, {pct(still, 0.5):.0f} |"
    )

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
for mode, rows in runs.items():
    t = [r["t_ms"] / 1e3 for r in rows[1:]]
    ax1.plot(t, [r["interval_ms"] for r in rows[1:]], ".-", ms=3, lw=0.8, label=mode)
    ax2.plot([r["t_ms"] / 1e3 for r in rows], [r["scale"] for r in rows], ".-", ms=3, lw=0.8, label=mode)
ax1.axhline(16.7, color="k", ls="--", lw=0.8, label="target 16.7 ms")
ax1.set_ylabel("frame interval (ms)")
ax1.set_yscale("log")
ax1.legend(fontsize=8)
ax2.set_ylabel("resolution scale")
ax2.set_xlabel("time (s): still, orbit, still, stroke, still")
ax2.legend(fontsize=8)
fig.tight_layout()
fig.savefig(f"{out}/frames.png", dpi=110)
print(f"wrote {out}/frames.png")

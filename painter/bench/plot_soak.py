"""The figure of `octopaint bench soak` (docs/benchmarks.md, "The soak"):
resident memory over the stamps painted, with what the session itself
holds (the pools, the undo history, the trace in memory), the undo budget,
the stamp count at which the history reached it, and the saves.

    .venv/bin/python painter/bench/plot_soak.py out/soak/soak.json docs/soak/soak.png
"""

from __future__ import annotations

import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    src, out = sys.argv[1], sys.argv[2]
    with open(src) as f:
        run = json.load(f)
    pts = run["points"]
    if len(pts) < 2:
        print(f"{src}: fewer than two memory samples", file=sys.stderr)
        return 1
    x = [p["stamps"] for p in pts]
    fig, ax = plt.subplots(figsize=(8, 4.2))
    ax.plot(x, [p["rss_mib"] for p in pts], lw=1.6, color="k", label="resident memory")
    ax.plot(x, [p["pool_mib"] for p in pts], lw=1, label="pools (every layer the history holds)")
    ax.plot(x, [p["undo_mib"] for p in pts], lw=1, label="undo history")
    ax.plot(x, [p["trace_kib"] / 1024 for p in pts], lw=1, label="trace in memory")
    if "gpu_mib" in pts[0]:
        ax.plot(x, [p["gpu_mib"] for p in pts], lw=1, label="GPU pages (host memory on lavapipe)")
    if pts[0].get("heap_in_use_mib") is not None:
        ax.plot(x, [p["heap_in_use_mib"] for p in pts], lw=1, ls="--", label="C heap in use (glibc)")
    ax.axhline(run["undo_budget_mib"], color="tab:orange", lw=0.6, ls="--", label=f"undo budget ({run['undo_budget_mib']:.0f} MiB)")
    if run.get("budget_reached_at") is not None:
        ax.axvline(run["budget_reached_at"], color="tab:orange", lw=0.6, ls=":", label="history reaches the budget")
    half = run["stamps"] / 2
    ax.axvspan(half, run["stamps"], color="0.93", zorder=0, label="last half (the slope's span)")
    for s in run["saves"]:
        ax.plot([s["stamps"]], [0], marker="|", color="tab:green", ms=8)
    ax.plot([], [], marker="|", ls="", color="tab:green", label="saves")
    ax.set_xlabel("stamps painted")
    ax.set_ylabel("MiB")
    ax.set_ylim(bottom=-5)
    ax.set_title(
        f"{run['stamps']:,} stamps, {run['strokes']:,} strokes: resident memory's slope over the last half "
        f"{run['rss_slope_mib']:+.2f} MiB per 10^5 stamps ({run['rss_slope_percent_of_budget']:+.2f} % of the budget)",
        fontsize=8,
    )
    # Below the resident memory and above the pools, where the lines leave room.
    ax.legend(fontsize=7, loc="center right", bbox_to_anchor=(1.0, 0.42), ncol=2)
    fig.tight_layout()
    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

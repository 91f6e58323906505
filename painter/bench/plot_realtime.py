"""Figures of `octopaint bench realtime` (docs/benchmarks.md): frame times
over the run per mask size (the paper's Fig. 8a) and per block size (Fig.
8b), corrupted frames per staging strategy (Fig. 9), and the latency
distribution of the default configuration.

    .venv/bin/python painter/bench/plot_realtime.py out/realtime/results.json docs/realtime
"""

from __future__ import annotations

import json
import os
import sys
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def series(ax, runs, title):
    for r in runs:
        xs = [t for t, _ in r["frame_series"]]
        ys = [ms for _, ms in r["frame_series"]]
        ax.plot(xs, ys, lw=0.8, label=r["label"])
    ax.axhline(1000 / 90, color="k", lw=0.6, ls="--", label="90 Hz (11.1 ms)")
    ax.set_xlabel("time since the live stroke began (s)")
    ax.set_ylabel("frame time (ms)")
    ax.set_title(title)
    ax.legend(fontsize=7)


def main() -> int:
    src, out = sys.argv[1], sys.argv[2]
    with open(src) as f:
        doc = json.load(f)
    runs = doc["runs"]
    os.makedirs(out, exist_ok=True)
    by = lambda g: [r for r in runs if r["group"] == g]
    note = f"{doc['adapter']}, {doc['image'][0]}x{doc['image'][1]}"

    if by("fig8a"):
        fig, ax = plt.subplots(figsize=(8, 4))
        series(ax, by("fig8a"), f"Frame time per neighbour-mask size (262K-cell blocks, K=1)\n{note}")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "fig8a_mask.png"), dpi=110)
        plt.close(fig)
    if by("table1"):
        fig, ax = plt.subplots(figsize=(8, 4))
        series(ax, by("table1"), f"Frame time per block size (64x32 mask, K=1)\n{note}")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "fig8b_blocks.png"), dpi=110)
        plt.close(fig)
    for group, k in (("fig9", 1), ("fig9_k4", 4)):
        rs = [r for r in by(group) if r["corruption"]]
        if not rs:
            continue
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
        labels = [textwrap.fill(r["label"].split(", K=")[0], 16) for r in rs]
        x = list(range(len(rs)))
        a1.bar(x, [r["corruption"]["percent"] for r in rs], color="tab:red")
        a1.set_xticks(x, labels)
        a1.set_ylabel("frames with corrupted pixels (%)")
        a1.tick_params(axis="x", labelsize=7)
        w = 0.38
        a2.bar([i - w / 2 for i in x], [r["corruption"]["median_ms"] for r in rs], w, color="tab:blue", label="median span")
        a2.bar([i + w / 2 for i in x], [r["corruption"]["longest_ms"] for r in rs], w, color="tab:orange", label="longest span")
        a2.set_xticks(x, labels)
        a2.set_ylabel("corruption lasts (ms)")
        a2.tick_params(axis="x", labelsize=7)
        a2.legend(fontsize=7)
        fig.suptitle(f"Corruption per staging strategy, K={k} (cf. the paper's Fig. 9)\n{note}", fontsize=9)
        fig.tight_layout()
        fig.savefig(os.path.join(out, f"{group}_corruption.png"), dpi=110)
        plt.close(fig)
    d = by("default")
    if d:
        fig, ax = plt.subplots(figsize=(6, 3.5))
        series(ax, d, f"Default configuration: frame time\n{note}")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "default_frames.png"), dpi=110)
        plt.close(fig)
    for p in sorted(os.listdir(out)):
        print(os.path.join(out, p))
    return 0


if __name__ == "__main__":
    sys.exit(main())

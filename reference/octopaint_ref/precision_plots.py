"""Figures of the precision study (matplotlib, Agg): precision.py measures,
this draws. Every function writes one PNG."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from . import ray_error as RE

PRECISIONS = ("f16", "f32", "f64")
FRAMES = ("local", "world")
TINY_ANGLE = 1e-20  # log scale floor: an exact zero is drawn here


def _log(a):
    return np.log10(np.maximum(np.asarray(a, np.float64), TINY_ANGLE))


def angle_images(per: dict, side: int, path: str) -> None:
    """Fig. 11(b)/12: log10 of each pixel's final angle error, and (c) the
    cells crossed, for every frame and precision."""
    fig, axes = plt.subplots(2, 4, figsize=(15, 7.2), constrained_layout=True)
    for r, frame in enumerate(FRAMES):
        for c, prec in enumerate(PRECISIONS):
            m = per[(prec, frame)]
            ax = axes[r, c]
            im = ax.imshow(_log(m["final_angle"]).reshape(side, side), cmap="magma")
            ax.set_title(f"{frame} {prec}: log10 angle error (rad)\nmax {m['final_angle'].max():.2e}", fontsize=9)
            ax.axis("off")
            fig.colorbar(im, ax=ax, shrink=0.8)
        m = per[("f64", frame)]
        ax = axes[r, 3]
        im = ax.imshow(m["steps"].reshape(side, side), cmap="viridis")
        ax.set_title(f"{frame} f64: cells crossed", fontsize=9)
        ax.axis("off")
        fig.colorbar(im, ax=ax, shrink=0.8)
    fig.suptitle("Ray-angle error at the ray's last point, camera in a depth-24 leaf (cf. paper Fig. 11(b, c) and Fig. 12)")
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _subsample(n: int, k: int = 40000) -> np.ndarray:
    return np.arange(n) if n <= k else np.linspace(0, n - 1, k).astype(np.int64)


def error_vs_length(per: dict, path: str) -> None:
    """Fig. 11(d): angle error of every exit point against its distance
    from the eye, with asin(e0/L + 5 eps) for the largest e0 measured."""
    fig, axes = plt.subplots(2, 3, figsize=(15, 8), constrained_layout=True, sharex=True)
    for r, frame in enumerate(FRAMES):
        for c, prec in enumerate(PRECISIONS):
            m = per[(prec, frame)]
            ax = axes[r, c]
            i = _subsample(len(m["angle"]))
            ax.scatter(m["step_length"][i], np.maximum(m["angle"][i], TINY_ANGLE), s=1, alpha=0.3, label="exit points")
            ax.scatter(m["length"], np.maximum(m["final_angle"], TINY_ANGLE), s=2, c="k", label="ray's last point")
            lengths = np.logspace(np.log10(max(m["step_length"].min(), 1e-3)), np.log10(m["step_length"].max()), 200)
            ax.plot(lengths, RE.bound(m["e0"].max(), lengths, m["eps"]), "r-", label="asin(e0/L + 5 eps)")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_ylim(TINY_ANGLE / 2, 3)
            ax.set_title(f"{frame} {prec} (e0 = {m['e0'].max():.2g} lattice units)", fontsize=9)
            ax.set_xlabel("L: distance from the eye (lattice units = depth-24 cell edges)")
            ax.set_ylabel("angle error (rad)")
            if r == 0 and c == 0:
                ax.legend(fontsize=8, markerscale=4)
    fig.suptitle("Angle error against ray length (cf. paper Fig. 11(d))")
    fig.savefig(path, dpi=80)
    plt.close(fig)


def error_vs_cells(per: dict, path: str) -> None:
    """Fig. 11(e): angle error against the number of cells crossed."""
    fig, axes = plt.subplots(1, 2, figsize=(14, 5), constrained_layout=True)
    for r, frame in enumerate(FRAMES):
        ax = axes[r]
        for prec in PRECISIONS:
            m = per[(prec, frame)]
            i = _subsample(len(m["angle"]), 20000)
            ax.scatter(m["step_index"][i], np.maximum(m["angle"][i], TINY_ANGLE), s=1, alpha=0.3, label=prec)
            ax.axhline(5 * m["eps"], ls="--", lw=0.8, c=ax.collections[-1].get_facecolor()[0][:3])
        ax.set_yscale("log")
        ax.set_ylim(TINY_ANGLE / 2, 3)
        ax.set_xlabel("cells crossed")
        ax.set_ylabel("angle error (rad)")
        ax.set_title(f"{frame} frame (dashed: 5 eps)")
        ax.legend(markerscale=6)
    fig.suptitle("Angle error against cells crossed (cf. paper Fig. 11(e))")
    fig.savefig(path, dpi=80)
    plt.close(fig)


def depth_sweep(sweep: dict, path: str) -> None:
    """Max angle error by the depth of the leaf holding the eye."""
    depths = sorted(sweep)
    fig, ax = plt.subplots(figsize=(8, 5), constrained_layout=True)
    for frame, style in (("local", "-o"), ("world", "--s")):
        for prec in PRECISIONS:
            ys = [max(sweep[d][f"{prec}_{frame}"]["max_angle_rad"], TINY_ANGLE) for d in depths]
            ax.plot(depths, ys, style, label=f"{frame} {prec}")
    ax.set_yscale("log")
    ax.set_xlabel("depth of the eye's leaf")
    ax.set_ylabel("max angle error (rad), first 64 cells, L >= 16 leaf edges")
    ax.legend(fontsize=8, ncol=2)
    ax.set_title("Where the frames break: error by depth")
    fig.savefig(path, dpi=80)
    plt.close(fig)


def image_grid(shots: dict, path: str) -> None:
    """Renders side by side, with the f16 local difference to f64 (x16)."""
    names = list(shots)
    ref = shots["f64_local"].astype(np.int64)
    diff = np.clip(np.abs(shots["f16_local"].astype(np.int64) - ref) * 16, 0, 255).astype(np.uint8)
    cols = len(names) + 1
    fig, axes = plt.subplots(1, cols, figsize=(3 * cols, 3.4), constrained_layout=True)
    for ax, name in zip(axes, names):
        ax.imshow(shots[name], interpolation="nearest")
        ax.set_title(name.replace("_", " "), fontsize=9)
        ax.axis("off")
    axes[-1].imshow(diff, interpolation="nearest")
    axes[-1].set_title("|f16 local - f64 local| x16", fontsize=9)
    axes[-1].axis("off")
    fig.savefig(path, dpi=80)
    plt.close(fig)


def angle_histograms(scale: dict, edges: np.ndarray, path: str) -> None:
    """The at-scale runs: how many rays end at each quarter decade of final
    angle error, per precision, with each precision's 5 eps."""
    fig, ax = plt.subplots(figsize=(7.5, 4.2), constrained_layout=True)
    for prec, colour in zip(PRECISIONS, ("tab:red", "tab:blue", "tab:green")):
        s = scale[prec]
        counts = np.asarray(s["hist"][1:-1], np.float64)  # the finite bins
        ax.stairs(np.maximum(counts, 0.5), edges, label=f"{prec}: {s['rays']:,} rays, max {s['max_angle']:.2g} rad", color=colour)
        ax.axvline(np.log10(5 * s["eps"]), color=colour, ls=":", lw=1)
    ax.set_yscale("log")
    ax.set_ylim(0.8, None)
    ax.set_xlabel("log10 final angle error (rad); dotted: 5 eps")
    ax.set_ylabel("rays")
    ax.set_title("Rays from a depth-24 leaf to the canvas boundary, local frame", fontsize=10)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def compositing_errors(comp: dict, path: str) -> None:
    """Largest colour error (8-bit steps) of each formulation, per medium,
    in f16 and bf16."""
    from .composite_precision import FORMS

    media = list(dict.fromkeys(k[0] for k in comp))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True, sharey=True)
    width = 0.8 / len(FORMS)
    for ax, fmt in zip(axes, ("f16", "bf16")):
        for j, form in enumerate(FORMS):
            v = [max(comp[(m, fmt, form)]["max_colour_steps"], 1e-3) for m in media]
            ax.bar(np.arange(len(media)) + (j - (len(FORMS) - 1) / 2) * width, v, width, label=form)
        ax.axhline(1.0, color="k", lw=0.8, ls=":")
        ax.set_yscale("log")
        ax.set_xticks(np.arange(len(media)), media, rotation=20, fontsize=8)
        ax.set_title(f"{fmt}: max colour error against mpmath (8-bit steps; dotted: 1 step)", fontsize=9)
    axes[0].legend(fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


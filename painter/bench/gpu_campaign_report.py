"""The GPU campaign's summary: `python painter/bench/gpu_campaign_report.py OUT`
prints OUT's figures (painter/bench/gpu_campaign.sh writes them) as Markdown,
with the issue's goals marked met or not. Standard library only."""

from __future__ import annotations

import json
import os
import sys

FRAME_GOAL_MS = 11.1  # 90 Hz
LATENCY_GOAL_MS = 11.0
CORRUPTION_GOAL_PCT = 1.0


def load(out: str, name: str):
    path = os.path.join(out, name)
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return json.load(f)


def verdict(ok: bool) -> str:
    return "met" if ok else "**not met**"


def adapter_line(d: dict) -> str:
    a = d["adapter"]
    return f"{a['name']} ({a['backend']}, {a['device_type']}, driver {a['driver']} {a['driver_info']})"


def gpu_section(title: str, d: dict, lines: list[str]) -> None:
    lines += [f"## {title}", "", f"Adapter: {adapter_line(d)}.", ""]
    t = d["tree"]
    lines.append(
        f"Tree: {t['cells']:,} cells (capacity {t['capacity']:,}); GPU pages {t['allocated_bytes'] / 1e6:,.1f} MB allocated, "
        f"{t['bytes_per_cell']:.1f} B a cell (the layout is 28 B a cell; pages are allocated whole but the last, which grows by powers of two)."
    )
    if "grow" in d:
        g = d["grow"]
        lines.append(
            f"Grown by {g['strokes']:,} generated strokes ({g['samples']:,} samples) to {g['cells']:,} cells in {g['seconds']:.1f} s "
            f"({g['cells'] / g['seconds'] / 1e6:.2f} M cells/s on the CPU, the trace's cells included)."
        )
    fs = d["first_sync"]
    lines.append(
        f"First sync: {fs['blocks']} blocks staged in {fs['stage_ms']:.1f} ms, uploads and g3 over {fs['regions']} regions "
        f"in {fs['gpu_ms']:.1f} ms ({fs['total_ms']:.1f} ms in all)."
    )
    b = d["bandwidth"]
    lines.append(
        f"Bandwidth: a copy on the GPU {b['gpu_copy_gbs_read_plus_write']:.1f} GB/s (read plus written), write_buffer from the "
        f"host {b['host_write_gbs']:.1f} GB/s; an empty submit-and-wait {b['empty_submit_ms']:.3f} ms."
    )
    g = d["g3"]
    lines.append(
        f"g3 over every region ({g['all_regions']}): {g['all_ms']:.2f} ms with the uploads, {g['per_block_ms']:.3f} ms a "
        f"65,536-cell block; one brush sample's frame ({g['sample_blocks']} blocks, {g['sample_regions']} regions): "
        f"{g['sample_frame_ms']:.2f} ms, {g['sample_per_region_ms']:.3f} ms a region."
    )
    lines.append("")
    if d.get("blocks"):
        lines += ["| block (cells) | blocks | stage (ms) | upload (ms) | staged and uploaded MB/s | upload alone MB/s |",
                  "| ---: | ---: | ---: | ---: | ---: | ---: |"]
        for r in d["blocks"]:
            lines.append(f"| {r['block']:,} | {r['blocks']} | {r['stage_ms']:.1f} | {r['upload_ms']:.1f} | {r['mb_per_s']:,.0f} | {r['upload_mb_per_s']:,.0f} |")
        lines.append("")
    lines += ["| camera | view | precision | light | level of detail | ms a frame | M rays/s | 90 Hz (11.1 ms) |", "| --- | --- | --- | --- | ---: | ---: | ---: | --- |"]
    for c in d["casts"]:
        size = f"2×{c['width']}×{c['height']}" if c["eyes"] == 2 else f"{c['width']}×{c['height']}"
        goal = verdict(c["ms"] < FRAME_GOAL_MS) if c["eyes"] == 2 else ""
        # Runs from before the level of detail (spec 7) cast every ray to the leaves.
        lod = c.get("lod", 0)
        lines.append(f"| {c['camera']} | {c['view']} {size} | {c['precision']} | {c['light']} | {lod:g} | {c['ms']:.2f} | {c['rays_per_s'] / 1e6:,.1f} | {goal} |")
    lines.append("")


def realtime_row(r: dict) -> str:
    c = r.get("corruption")
    corr = f"{c['percent']:.1f}% ({c['spans']} spans, longest {c['longest_ms']:.0f} ms)" if c else ""
    return (
        f"| {r['label']} | {r['frames']} | {r['frame_ms']['p50']:.1f} / {r['frame_ms']['p99']:.1f} | {r['cast_ms']['p50']:.1f} | "
        f"{r['latency_ms']['p50']:.1f} / {r['latency_ms']['p99']:.1f} | {r['staging_ms']['mean']:.2f} | {r['cells_uploaded_per_s'] / 1e6:.1f} | {corr} |"
    )


REALTIME_HEAD = [
    "| configuration | frames | frame ms p50 / p99 | cast ms p50 | latency ms p50 / p99 | staging ms mean | M cells/s uploaded | corrupted frames |",
    "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
]


def main(out: str) -> int:
    lines = ["# GPU campaign", ""]
    env = os.path.join(out, "env.txt")
    if os.path.exists(env):
        lines += ["```", open(env).read().strip(), "```", ""]
    steps = os.path.join(out, "steps.txt")
    if os.path.exists(steps):
        lines += ["| step | exit | seconds |", "| --- | ---: | ---: |"]
        for ln in open(steps):
            p = ln.split(None, 2)
            if len(p) == 3:
                lines.append(f"| {p[0]} | {p[1]} | {p[2].strip()} |")
        lines.append("")
    mem = os.path.join(out, "gpumem.csv")
    if os.path.exists(mem):
        used = []
        for ln in open(mem):
            p = [x.strip() for x in ln.split(",")]
            if len(p) >= 2 and p[1].split()[0].isdigit():
                used.append(int(p[1].split()[0]))
        if used:
            lines += [f"GPU memory in use (nvidia-smi every 250 ms): at most {max(used):,} MiB, at least {min(used):,} MiB.", ""]
    for name, title in (("gpu_scene.json", "The scene (`bench gpu`)"), ("gpu_big.json", "The grown canvas (`bench gpu --grow`)")):
        d = load(out, name)
        if d:
            gpu_section(title, d, lines)
    rt = sorted(f for f in os.listdir(out) if f.startswith("realtime_") and f.endswith(".json") and f != "realtime_all.json")
    if rt:
        lines += ["## Painting under way (`bench realtime --default-only`)", "", *REALTIME_HEAD]
        goals = []
        for f in rt:
            d = load(out, f)
            for r in d["runs"]:
                lines.append(realtime_row({**r, "label": f"{d['image'][0]}×{d['image'][1]}: {r['label']}"}))
                goals.append((d["image"], r))
        lines.append("")
        for img, r in goals:
            lines.append(
                f"- {img[0]}×{img[1]}: frame p99 {r['frame_ms']['p99']:.1f} ms against {FRAME_GOAL_MS} ({verdict(r['frame_ms']['p99'] < FRAME_GOAL_MS)}); "
                f"stroke-to-display p99 {r['latency_ms']['p99']:.1f} ms against {LATENCY_GOAL_MS} ({verdict(r['latency_ms']['p99'] < LATENCY_GOAL_MS)})."
            )
        lines.append("")
    d = load(out, "realtime_all.json")
    if d:
        lines += [f"## Table 1, Fig. 8, Fig. 9 (`bench realtime`, {d['image'][0]}×{d['image'][1]})", "", f"Adapter: {d['adapter']}.", "", *REALTIME_HEAD]
        for r in d["runs"]:
            lines.append(realtime_row(r))
        lines.append("")
        for r in d["runs"]:
            c = r.get("corruption")
            if c and r.get("grouped"):
                lines.append(f"- {r['label']}: {c['percent']:.2f}% corrupted frames against {CORRUPTION_GOAL_PCT}% ({verdict(c['percent'] < CORRUPTION_GOAL_PCT)}).")
        lines.append("")
    d = load(out, "jax_raycast.json")
    if d:
        lines += [f"## The reference's ray caster (JAX {d['jax']} on {', '.join(d['devices'])})", "",
                  "| camera | precision | size | first call (s) | second call (s) | rays/s | cells/ray |", "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
        for r in d["rows"]:
            lines.append(f"| {r['camera']} | {r['precision']} | {r['size']}² | {r['first_s']:.2f} | {r['second_s']:.3f} | {r['rays_per_s']:,.0f} | {r['cells_per_ray']:.1f} |")
        lines.append("")
    prec = [(p, a, load(out, f"precision_{p}_{a}.json")) for p in ("f16", "f32") for a in ("emulated", "native")]
    if any(x[2] for x in prec):
        lines += ["## The precision study, emulated and native", "", "| precision | arithmetic | rays | within the bound | max angle (rad) | ray |",
                  "| --- | --- | ---: | ---: | ---: | ---: |"]
        for p, a, d in prec:
            if d:
                lines.append(f"| {p} | {a} | {d['rays']:,} | {d['within_pct']:.4f}% | {d['max_angle']:.3g} | {d['argmax']} |")
        lines.append("")
    probe = os.path.join(out, "gpu_probe", "gpu_probe.md")
    if os.path.exists(probe):
        lines += ["## The painter's ray caster ray by ray (`octopaint-ref gpu-probe`)", "", open(probe).read().strip(), ""]
    d = load(out, "images.json")
    if d:
        ok = sum(r["ok"] for r in d["rows"])
        lines += [f"## Images against the reference's: {ok} of {len(d['rows'])} within spec 13's tolerance", "",
                  "| trace | image | precision | within | % within | largest step | PSNR (dB) |", "| --- | --- | --- | --- | ---: | ---: | ---: |"]
        for r in d["rows"]:
            psnr = "identical" if r["psnr_db"] is None else f"{r['psnr_db']:.1f}"
            lines.append(f"| {r['trace']} | {r['image']} | {r['precision']} | {'yes' if r['ok'] else '**no**'} | {100 * r['fraction_within']:.3f} | {r['max_steps']} | {psnr} |")
        lines.append("")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))

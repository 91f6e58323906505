"""The conformance driver (run it through conformance/run).

For every trace: replay it with the reference (`octopaint-ref replay`) and
the painter (`octopaint replay`), then compare what they wrote: tree dumps
array by array (dumps.TOLERANCES: dtype, shape and values), images within
images.IMAGE_TOLERANCES (per precision of the painter's ray caster), and
the warnings the spec defines. Before that, the
two trace readers are compared on every malformed trace and on generated
variants (readers.py). The report (Markdown) lists every difference; for a
differing dump it gives the first differing cell and its history in both
implementations. Exit status 1 on any difference.
"""

from __future__ import annotations

import argparse
import difflib
import glob
import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)

import dumps  # noqa: E402
import history  # noqa: E402
import images  # noqa: E402
import readers  # noqa: E402

# Warnings both implementations must give, word for word (spec 2.4, 12.2).
SPEC_WARNINGS = ("the cell budget of", "the trace ends inside this stroke")


@dataclass
class TraceResult:
    name: str
    ref_seconds: float = 0.0
    painter_seconds: float = 0.0
    dumps: int = 0
    cells: int = 0
    images_compared: int = 0
    worst_psnr: float = float("inf")
    images_not_rendered: list = field(default_factory=list)
    problems: list = field(default_factory=list)  # Markdown paragraphs


def _run(cmd: list[str]) -> tuple[subprocess.CompletedProcess, float]:
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, timeout=3600)
    return res, time.perf_counter() - t0


def _warnings(stderr: bytes, prefix: str) -> list[str]:
    out = []
    for line in stderr.decode("utf-8", errors="replace").split("\n"):
        if line.startswith(prefix) and any(w in line for w in SPEC_WARNINGS):
            out.append(line[len(prefix) :])
    return out


def _fence(lines: list[str]) -> str:
    return "```\n" + "\n".join(lines) + "\n```"


def check_trace(trace: str, painter: str, work: str, report_dir: str, precision: str = "f32", require_images: bool = False, lods: str = "0,1") -> TraceResult:
    """Replay `trace` with both implementations and compare what they
    wrote; with `require_images`, an image the painter did not write is a
    problem too. lods: the levels of detail (spec 7) every image is drawn
    at by both (`--lod`: `<name>.png` at 0, `<name>.lod<k>.png` else)."""
    name = os.path.basename(trace)[: -len(".jsonl")]
    r = TraceResult(name)
    ref_dir = os.path.join(work, name, "reference")
    pt_dir = os.path.join(work, name, "painter")
    for d in (ref_dir, pt_dir):
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
    ref_cmd = [os.path.join(REPO, ".venv", "bin", "octopaint-ref"), "replay", trace, "--out", ref_dir, "--quiet", "--lod", lods]
    pt_cmd = [painter, "replay", trace, "--out", pt_dir, "--quiet", "--precision", precision, "--lod", lods]
    ref, r.ref_seconds = _run(ref_cmd)
    pt, r.painter_seconds = _run(pt_cmd)
    if ref.returncode != pt.returncode:
        r.problems.append(
            f"**exit status**: reference {ref.returncode}, painter {pt.returncode}\n\n"
            + _fence(["reference: " + ref.stderr.decode(errors="replace")[-1500:], "painter: " + pt.stderr.decode(errors="replace")[-1500:]])
        )
        return r
    if ref.returncode != 0:
        r.problems.append("both refused the trace:\n\n" + _fence([ref.stderr.decode(errors="replace")[-1500:]]))
        return r
    wr = _warnings(ref.stderr, f"octopaint-ref: warning: {trace}: ")
    wp = _warnings(pt.stderr, f"octopaint: warning: {trace}: ")
    if wr != wp:
        r.problems.append("**warnings differ**\n\n" + _fence(list(difflib.unified_diff(wr, wp, "reference", "painter", lineterm=""))))
    ref_files = sorted(os.listdir(ref_dir))
    pt_files = set(os.listdir(pt_dir))
    for f in ref_files:
        a, b = os.path.join(ref_dir, f), os.path.join(pt_dir, f)
        if f.endswith(".png"):
            if f not in pt_files:
                r.images_not_rendered.append(f)
                continue
            diff_path = os.path.join(report_dir, f"{name}-{f[:-4]}-diff.png")
            res = images.compare(a, b, diff_path, images.IMAGE_TOLERANCES[precision])
            r.images_compared += 1
            r.worst_psnr = min(r.worst_psnr, res.psnr_db)
            if not res.ok:
                r.problems.append(f"**image `{f}`**: {res.detail}; diff image `{os.path.basename(diff_path)}`")
            continue
        if f not in pt_files:
            r.problems.append(f"**`{f}`**: written by the reference only")
            continue
        r.dumps += 1
        da, db = dumps.load(a), dumps.load(b)
        r.cells = max(r.cells, sum(len(t["parent"]) for t in dumps.layers_of(da)))
        diffs = dumps.compare_document(da, db)
        if diffs:
            lines = [f"- `{d.array}`: {d.detail}" for d in diffs]
            para = f"**dump `{f}`** differs:\n\n" + "\n".join(lines)
            cell = next((d.first_cell for d in diffs if d.first_cell is not None), None)
            if cell is not None:
                hr = history.reference_history(trace, cell)
                hp = history.painter_history(painter, trace, cell, os.path.join(work, name, "history"))
                para += (
                    f"\n\nFirst differing cell {cell}:\n\n- reference: {dumps.record(da, cell)}\n- painter: {dumps.record(db, cell)}"
                    f"\n\nIts history in the reference:\n\n{_fence(hr or ['(never written)'])}"
                    f"\n\nIts history in the painter:\n\n{_fence(hp or ['(never written)'])}"
                )
            r.problems.append(para)
    for f in sorted(pt_files - set(ref_files)):
        r.problems.append(f"**`{f}`**: written by the painter only")
    if r.images_not_rendered and require_images:
        r.problems.append(f"images not written by the painter: {', '.join(r.images_not_rendered)}")
    return r


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Compare the reference and the painter on traces (docs/spec.md 13).")
    ap.add_argument("traces", nargs="*", help="traces to replay (default: every traces/*.jsonl)")
    ap.add_argument("--report", required=True, help="folder for report.md and diff images")
    ap.add_argument("--painter", required=True, help="the octopaint binary")
    ap.add_argument("--generated", type=int, default=2000, help="generated trace variants for the reader comparison")
    ap.add_argument("--require-images", action="store_true", help="an image the painter does not write is a difference")
    ap.add_argument("--precision", choices=("f32", "f16"), default="f32", help="the painter's ray caster precision (and its image tolerance)")
    ap.add_argument("--lod", default="0,1", metavar="K[,K...]", help="levels of detail every image is compared at (spec 7; default 0,1)")
    args = ap.parse_args(argv)
    traces = args.traces or sorted(glob.glob(os.path.join(REPO, "traces", "*.jsonl")))
    os.makedirs(args.report, exist_ok=True)
    work = os.path.join(args.report, "work")
    failed = False
    out = ["# Conformance report", ""]

    t0 = time.perf_counter()
    n, bad = readers.compare_readers(args.painter, REPO, work, args.generated)
    out += ["## Trace readers", "", f"{n} traces ({args.generated} generated) read by both readers in {time.perf_counter() - t0:.1f} s: "
            + ("the same verdict on every one." if not bad else f"**{len(bad)} disagree**."), ""]
    for path, want, have in bad[:50]:
        failed = True
        diff = difflib.unified_diff([json.dumps(r) for r in want], [json.dumps(r) for r in have], "reference", "painter", lineterm="", n=1)
        out += [f"`{os.path.relpath(path, args.report)}`:", "", _fence(list(diff)), ""]
    print(f"readers: {n} traces, {len(bad)} disagreements", flush=True)

    out += ["## Replays", "", "| trace | dumps | cells | images | reference (s) | painter (s) | speed-up | result |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    details = []
    for trace in traces:
        r = check_trace(os.path.abspath(trace), args.painter, work, args.report, args.precision, args.require_images, args.lod)
        ok = not r.problems
        failed |= not ok
        speed = r.ref_seconds / r.painter_seconds if r.painter_seconds > 0 else float("nan")
        imgs = f"{r.images_compared}" + (f", worst {r.worst_psnr:.1f} dB" if r.images_compared and r.worst_psnr != float("inf") else "")
        imgs += (f" (+{len(r.images_not_rendered)} not rendered by the painter)" if r.images_not_rendered else "")
        out.append(f"| {r.name} | {r.dumps} | {r.cells:,} | {imgs} | {r.ref_seconds:.2f} | {r.painter_seconds:.2f} | {speed:.1f}x | {'same' if ok else '**differs**'} |")
        print(f"{r.name}: {'same' if ok else 'DIFFERS'} ({r.dumps} dumps, reference {r.ref_seconds:.1f} s, painter {r.painter_seconds:.1f} s)", flush=True)
        if r.problems:
            details += [f"### {r.name}", ""] + [p + "\n" for p in r.problems]
    out += ["", "Dumps are compared array by array with the tolerances of `conformance/dumps.py` (all exact: dtype, shape and every value; the files' bytes are each zip library's business, spec 11.1); "
            f"images with those of `conformance/images.py` for the painter's {args.precision} ray caster (PSNR: inf where identical).", ""]
    if any("not rendered" in line for line in out):
        out += ["Images the painter does not write yet are listed, not compared: the painter's GPU ray caster is a later "
                "issue; `--require-images` makes them differences.", ""]
    out += ["## Differences", ""] + (details or ["None."])
    with open(os.path.join(args.report, "report.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")
    print(f"report: {os.path.join(args.report, 'report.md')}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

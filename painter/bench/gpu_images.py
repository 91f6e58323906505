"""The painter's images on this machine's GPU against the reference's.

    python painter/bench/gpu_images.py --painter BIN --reference DIR --json OUT.json TRACE...

For each trace with render events, `octopaint replay --precision f32` and
`--precision f16` draw its images on the adapter wgpu finds here, and each
image is compared with the reference's f64 render of the same event
(DIR/<trace>/<name>.png, what `octopaint-ref replay` writes) under spec 13's
tolerance for that precision (conformance/images.py). `--make-reference`
runs `octopaint-ref replay` for traces whose reference images are missing
(the GPU campaign carries them instead: the reference's replay is slow and
the same on every machine). Prints a Markdown table; exits 1 if an image is
outside its tolerance, 2 if something could not run.

Only numpy and Pillow are needed (the device machine's Python has them).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "conformance"))

import images  # noqa: E402  (conformance/images.py)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("traces", nargs="+")
    ap.add_argument("--painter", required=True)
    ap.add_argument("--reference", required=True, help="folder of the reference's images, one subfolder per trace")
    ap.add_argument("--make-reference", action="store_true", help="render missing reference images with octopaint-ref")
    ap.add_argument("--precisions", default="f32,f16")
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args(argv)
    rows = []
    bad = 0
    with tempfile.TemporaryDirectory() as work:
        for trace in args.traces:
            name = os.path.basename(trace)[: -len(".jsonl")]
            ref_dir = os.path.join(args.reference, name)
            if not os.path.isdir(ref_dir):
                if not args.make_reference:
                    print(f"gpu_images: no reference images for {name} in {args.reference}", file=sys.stderr)
                    return 2
                ref = shutil.which("octopaint-ref") or os.path.join(REPO, ".venv", "bin", "octopaint-ref")
                partial = ref_dir + ".partial"
                shutil.rmtree(partial, ignore_errors=True)
                p = subprocess.run([ref, "replay", trace, "--out", partial, "--quiet"], capture_output=True)
                if p.returncode != 0:
                    print(f"gpu_images: {name}: the reference failed:\n{p.stderr.decode(errors='replace')[-2000:]}", file=sys.stderr)
                    return 2
                os.rename(partial, ref_dir)  # complete or absent, never half written
            pngs = sorted(f for f in os.listdir(ref_dir) if f.endswith(".png"))
            for prec in args.precisions.split(","):
                out = os.path.join(work, name, prec)
                t0 = time.perf_counter()
                p = subprocess.run([args.painter, "replay", trace, "--out", out, "--quiet", "--precision", prec], capture_output=True)
                seconds = time.perf_counter() - t0
                if p.returncode != 0:
                    print(f"gpu_images: {name} {prec}: the painter failed:\n{p.stderr.decode(errors='replace')[-2000:]}", file=sys.stderr)
                    return 2
                for f in pngs:
                    res = images.compare(os.path.join(ref_dir, f), os.path.join(out, f), None, images.IMAGE_TOLERANCES[prec])
                    bad += not res.ok
                    rows.append({"trace": name, "image": f[:-4], "precision": prec, "ok": res.ok, "fraction_within": res.fraction_within,
                                 "psnr_db": None if res.psnr_db == float("inf") else res.psnr_db, "max_steps": res.max_steps,
                                 "replay_seconds": seconds})
    print("| trace | image | precision | within tolerance | % of pixels within | largest step | PSNR (dB) |")
    print("| --- | --- | --- | --- | ---: | ---: | ---: |")
    for r in rows:
        psnr = "identical" if r["psnr_db"] is None else f"{r['psnr_db']:.1f}"
        print(f"| {r['trace']} | {r['image']} | {r['precision']} | {'yes' if r['ok'] else '**no**'} | "
              f"{100 * r['fraction_within']:.3f} | {r['max_steps']} | {psnr} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rows": rows}, f, indent=1)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

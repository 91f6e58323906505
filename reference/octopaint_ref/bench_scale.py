"""Throughput of `octopaint-ref precision` by device count (docs/benchmarks.md,
"Precision study at scale"): the same rays traced with 1, 2, 4 and 8
simulated CPU devices (XLA_FLAGS), each in a fresh process; prints rays/s
(scene build and compilation included, as a user sees them) and the ratio
to one device, and checks that every run gives the same result.

    .venv/bin/python -m octopaint_ref.bench_scale --rays 16384 --precision f16
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m octopaint_ref.bench_scale", description=__doc__.split("\n\n")[0])
    ap.add_argument("--rays", type=int, default=16384)
    ap.add_argument("--precision", default="f16")
    ap.add_argument("--devices", default="1,2,4,8")
    args = ap.parse_args(argv)
    base = None
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in [int(x) for x in args.devices.split(",")]:
            out = os.path.join(tmp, f"{n}.json")
            env = {**os.environ, "XLA_FLAGS": f"--xla_force_host_platform_device_count={n}"}
            cmd = [sys.executable, "-m", "octopaint_ref.precision_scale", "--rays", str(args.rays), "--precision", args.precision, "--out", out]
            r = subprocess.run(cmd, capture_output=True, text=True, env=env)
            if r.returncode != 0:
                print(r.stderr, file=sys.stderr)
                return 1
            m = re.search(r"in ([0-9.]+) s;", r.stderr)
            seconds = float(m.group(1))
            with open(out) as f:
                results.append(json.load(f))
            rate = args.rays / seconds
            base = base or rate
            print(f"{n} devices: {args.rays:,} rays in {seconds:.1f} s, {rate:,.0f} rays/s, {rate / base:.2f}x one device", flush=True)
    same = all(r == results[0] for r in results)
    print(f"same result on every device count: {'yes' if same else 'NO'}; max angle {results[0]['max_angle']:.3g} rad, "
          f"{results[0]['within_pct']:.4f}% within the bound")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())

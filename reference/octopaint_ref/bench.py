"""Replay timing of the reference: `python3 -m octopaint_ref.bench [TRACES...]`.

Replays each trace twice in one process and prints samples, cells and
seconds: the first run includes tracing JAX kernels (and compiling them when
the on-disk cache is cold), the second is the steady state. Figures go into
docs/benchmarks.md.
"""

from __future__ import annotations

import glob
import os
import sys

from .jax_setup import configure
from .replay import replay
from .trace import read_trace


def main(argv=None) -> int:
    configure()
    argv = sys.argv[1:] if argv is None else argv
    here = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    traces = argv or sorted(glob.glob(os.path.join(here, "traces", "*.jsonl")))
    print(f"{'trace':<22}{'samples':>9}{'cells':>11}{'depth':>7}{'first s':>10}{'second s':>10}{'samples/s':>11}{'cells/s':>11}")
    for path in traces:
        trace = read_trace(path)
        first = replay(trace, None)
        second = replay(trace, None)
        name = os.path.basename(path)[:-6]
        print(
            f"{name:<22}{second.samples:>9}{second.cells:>11}{second.max_depth_reached:>7}"
            f"{first.seconds:>10.2f}{second.seconds:>10.2f}"
            f"{second.samples / second.seconds:>11.0f}{second.cells / second.seconds:>11.0f}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""One row of painter/bench/many_cores.sh's realtime table from a
`bench realtime --default-only` results.json: ARGS RESULTS.json RADIUS."""

import json
import sys

path, radius = sys.argv[1], sys.argv[2]
with open(path) as f:
    doc = json.load(f)
(run,) = doc["runs"]  # --default-only: the default configuration alone
print(
    f"| {radius} | {doc['adapter']} | {run['paint_ms']['p50']:.2f} | {run['paint_ms']['p99']:.2f} | "
    f"{run['frame_ms']['p50']:.2f} | {run['frame_ms']['p99']:.2f} |"
)

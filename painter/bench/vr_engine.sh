#!/usr/bin/env bash
# The headset through the real-time engine (docs/benchmarks.md, "The
# headset through the engine"): frame intervals while the simulated head
# moves with nothing else happening and while heavy strokes paint (the
# paper's limitation case, its 8.3), for the scene as one tree and as a
# document of four layers; stroke-to-display latency from the engine's
# ledger.
#
#   sudo painter/bench/vr_engine.sh OUT
#
# The traces are painter/bench/window_engine.py's (the window's benchmark):
# for each document the scene trace imported, then `octopaint vr DOC
# --play HEAVY --frame-log` against Monado's simulated headset
# (painter/xr/monado/run.sh: needs root, the chroot made once) for 240
# frames; the trace waits 3 s, then paints its heavy strokes. Monado's
# null compositor paces frames at 20 Hz (50 ms) whatever the session asks,
# and its simulated head never stops, so every frame is a moving one and
# no frame is shorter than 50 ms. The headset saves once its frames are
# over (no frame waits for it), so there are no frames while saving.
# window_engine.py prints the table from OUT/vr_<run>.csv and .log.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$(dirname "$here")")"
out="$1"
frames="${FRAMES:-240}"
octopaint="$repo/painter/target/release/octopaint"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
py="$repo/.venv/bin/python"; [ -x "$py" ] || py=python3
"$py" "$here/window_engine.py" traces "$out"
# run.sh mounts the current folder at /work in the chroot: relative paths.
cd "$out"
run() { # name scene-trace heavy-trace
    local name=$1 scene=$2 heavy=$3
    rm -f "vr_$name.octo" "vr_$name.octo".* "vr_$name.csv"
    "$octopaint" import "$scene" "vr_$name.octo" >/dev/null
    "$repo/painter/xr/monado/run.sh" vr "vr_$name.octo" --frames "$frames" --play "$heavy" --frame-log "vr_$name.csv" --no-fallback 2> "vr_$name.log" \
        || { grep -v '^LOG\|^	' "vr_$name.log" >&2; exit 1; }
    grep '^octopaint:' "vr_$name.log" >&2
}
run one_tree "$repo/traces/scene.jsonl" heavy.jsonl
run four_layers scene_layers.jsonl heavy_layers.jsonl
"$py" "$here/window_engine.py" report "$out" vr_

#!/usr/bin/env bash
# The desktop window through the real-time engine (docs/benchmarks.md, "The
# window through the engine"): frame intervals while the view orbits with
# nothing else happening, while heavy strokes paint (the paper's limitation
# case, its 8.3) and while the document saves, for the scene as one tree
# and as a document of four layers; stroke-to-display latency from the
# engine's ledger.
#
#   painter/bench/window_engine.sh OUT
#
# For each document: the scene trace imported (painter/bench/window_engine.py
# makes the traces), then `octopaint window DOC --play HEAVY` on a virtual X
# server (Xvfb), 800x600, while xdotool orbits the view the whole time (a
# right drag); the trace waits 3 s, then paints its heavy strokes; Ctrl+S
# saves twice after them; Ctrl+Q closes. The frame log (OUT/<run>.csv) marks
# what the stroke thread was doing as each frame began; window_engine.py
# prints the table. Needs Xvfb, xdotool and a built painter (make painter).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$(dirname "$here")")"
out="$1"
octopaint="$repo/painter/target/release/octopaint"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
py="$repo/.venv/bin/python"; [ -x "$py" ] || py=python3
"$py" "$here/window_engine.py" traces "$out"
. "$here/xvfb.sh"

run() { # name scene-trace heavy-trace
    local name=$1 scene=$2 heavy=$3
    local doc="$out/$name.octo"
    rm -f "$doc" "$doc".* "$out/$name.csv"
    "$octopaint" import "$scene" "$doc" >/dev/null
    XDG_RUNTIME_DIR="$runtime" "$octopaint" window "$doc" --size 800x600 --play "$heavy" --frame-log "$out/$name.csv" 2>"$out/$name.log" &
    local win=$! id=""
    for _ in $(seq 600); do
        id="$(xdotool search --onlyvisible --name octopaint 2>/dev/null | head -1 || true)"
        [ -n "$id" ] && break
        sleep 0.1
    done
    [ -n "$id" ] || { echo "no window for $name" >&2; cat "$out/$name.log" >&2; exit 1; }
    # The first frame (the ray caster compiled): the trace starts playing.
    for _ in $(seq 1200); do [ "$(cat "$out/$name.csv" 2>/dev/null | wc -l)" -ge 2 ] && break; sleep 0.1; done
    xdotool windowfocus "$id"
    # Orbit the whole time: 14 s of a slow right drag.
    xdotool mousemove --window "$id" 450 300 mousedown 3
    for i in $(seq 1 350); do
        xdotool mousemove --window "$id" $(( 450 + (i % 100) )) 300
        sleep 0.04
        case $i in 250|300) xdotool key ctrl+s ;; esac
    done
    xdotool mouseup 3
    sleep 1
    xdotool key ctrl+q
    wait "$win"
}
run one_tree "$repo/traces/scene.jsonl" "$out/heavy.jsonl"
run four_layers "$out/scene_layers.jsonl" "$out/heavy_layers.jsonl"
"$py" "$here/window_engine.py" report "$out"

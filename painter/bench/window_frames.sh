#!/usr/bin/env bash
# The desktop window's dynamic resolution over a scripted session
# (docs/desktop.md, "Dynamic resolution"):
#
#   painter/bench/window_frames.sh OUT [TRACE]     # default trace: traces/scene.jsonl
#
# Imports TRACE as a document, then runs `octopaint window` twice on a
# virtual X server (Xvfb), once with dynamic resolution and once with
# --fixed-resolution, each through the same script of real X input
# (xdotool): 2 s still, 4 s orbiting (right drag), 2 s still, a 2 s
# stroke (left drag), 2 s still. Each run writes its frame log
# (OUT/dynamic.csv, OUT/fixed.csv); painter/bench/window_frames.py prints
# the table and plots OUT/frames.png. Needs Xvfb, xdotool and a built
# painter (make painter).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$(dirname "$here")")"
out="$1"
trace="${2:-$repo/traces/scene.jsonl}"
octopaint="$repo/painter/target/release/octopaint"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
. "$here/xvfb.sh"

drag() { # button x0 y0 dx dy seconds
    local b=$1 x=$2 y=$3 dx=$4 dy=$5 n=$(( $6 * 25 ))
    xdotool mousemove --window "$id" "$x" "$y" mousedown "$b"
    for i in $(seq 1 "$n"); do
        xdotool mousemove --window "$id" $(( x + dx * i / n )) $(( y + dy * i / n ))
        sleep 0.04
    done
    xdotool mouseup "$b"
}

for mode in dynamic fixed; do
    doc="$out/$mode.octo"
    rm -f "$doc" "$doc".*
    "$octopaint" import "$trace" "$doc" >/dev/null
    flags=()
    [ "$mode" = fixed ] && flags=(--fixed-resolution)
    XDG_RUNTIME_DIR="$runtime" "$octopaint" window "$doc" --size 800x600 --frame-log "$out/$mode.csv" "${flags[@]}" 2>"$out/$mode.log" &
    win=$!
    id=""
    for _ in $(seq 600); do
        id="$(xdotool search --onlyvisible --name octopaint 2>/dev/null | head -1 || true)"
        [ -n "$id" ] && break
        sleep 0.1
    done
    [ -n "$id" ] || { echo "no window for $mode" >&2; cat "$out/$mode.log" >&2; exit 1; }
    xdotool windowfocus "$id"
    sleep 2
    drag 3 500 300 240 60 4
    sleep 2
    drag 1 450 320 200 -60 2
    sleep 2
    xdotool key ctrl+q
    wait "$win"
done
py="$repo/.venv/bin/python"; [ -x "$py" ] || py=python3   # the plot needs matplotlib (make setup puts it in .venv)
"$py" "$here/window_frames.py" "$out"

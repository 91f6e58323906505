#!/usr/bin/env bash
# The painter core's flame graphs (docs/benchmarks.md, "Where the time goes"):
#
#   painter/bench/flamegraphs.sh [OUT]     # default: docs/flamegraphs
#
# OUT/bench_tree_r10.svg: `octopaint bench tree --radius 10 --threads 1`, the
#     painting alone (stacks below Painting::add_sample and end_stroke; the
#     benchmark's set-up and digest left out).
# OUT/scene_replay.svg: `octopaint replay --renderer none traces/scene.jsonl`
#     on one rayon thread, the whole process (every thread: parsing,
#     painting, the dumps and their writer).
# Needs perf (Debian's linux-perf) and the release build, which keeps its
# debuginfo, so the stacks unwind through DWARF. Samples at 999 Hz.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
out="${1:-$root/docs/flamegraphs}"
mkdir -p "$out"
command -v perf >/dev/null || { echo "flamegraphs.sh: perf is missing (apt-get install linux-perf)" >&2; exit 2; }
cargo build --quiet --release --locked --manifest-path "$root/painter/Cargo.toml" -p octopaint-app
octopaint="$root/painter/target/release/octopaint"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

record() { perf record --quiet --call-graph dwarf,65528 -F 999 -o "$tmp/perf.data" "$@" > /dev/null; }
fold() { perf script -i "$tmp/perf.data" --no-inline 2>/dev/null | python3 "$here/flamegraph.py" "$@"; }

NODEVICE_SELECT=1 record "$octopaint" bench tree --radius 10 --threads 1
fold --title "octopaint bench tree --radius 10 --threads 1: the painting" \
    --below 'Painting::(add_sample|end_stroke)$' > "$out/bench_tree_r10.svg"

RAYON_NUM_THREADS=1 record "$octopaint" replay --renderer none --quiet --out "$tmp/scene" "$root/traces/scene.jsonl"
fold --title "octopaint replay --renderer none traces/scene.jsonl (one rayon thread): every thread" > "$out/scene_replay.svg"
ls -l "$out"/*.svg

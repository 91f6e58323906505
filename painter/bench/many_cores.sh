#!/usr/bin/env bash
# The painter core on every core of a many-core machine (issue 15,
# docs/benchmarks.md "On 16 cores"): how octopaint and OpenVDB scale with
# threads on the same strokes, how the scene's replay scales, and the stroke
# thread's paint time per sample while a GPU draws beside it. The summary
# grows as each part ends, the OpenVDB comparison (the longest) last.
#
#   painter/bench/many_cores.sh OUT [RADII...]      # default radii: 4 10 32
#
# Environment (all optional):
#   THREADS="1 2 4 8 16"  thread counts (default: 1, the powers of two
#                         below nproc, and nproc; 1 is always run)
#   OCTOPAINT=PATH        a prebuilt octopaint (default: cargo's build)
#   OPENVDB_STAMP=PATH    a prebuilt openvdb_stamp (default: g++'s build)
#   SCENE_RUNS=3          replays of traces/scene.jsonl per thread count
#   REALTIME=0            leave out `bench realtime` (it needs a GPU
#                         adapter: lavapipe or a real one)
#   REALTIME_SIZE=WxH     the realtime image (default 2880x1600, both eyes
#                         of a 1440x1600 headset)
#
# Writes OUT/summary.md (every table) and OUT/files.tar.gz (the JSON behind
# them); the summary is printed last.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
[ $# -ge 1 ] || { echo "usage: many_cores.sh OUT [RADII...]" >&2; exit 2; }
mkdir -p "$1"
out="$(cd "$1" && pwd)"
shift
radii=("$@")
[ ${#radii[@]} -eq 0 ] && radii=(4 10 32)
cores=$(nproc)
if [ -z "${THREADS:-}" ]; then
    THREADS=1
    for ((t = 2; t < cores; t *= 2)); do THREADS="$THREADS $t"; done
    [ "$cores" -gt 1 ] && THREADS="$THREADS $cores"
fi
# shellcheck source=thread_counts.sh
. "$here/thread_counts.sh"
thread_counts "$THREADS"
export THREADS="${threads[*]}"

if [ -z "${OCTOPAINT:-}" ]; then
    cargo build --quiet --release --locked --manifest-path "$root/painter/Cargo.toml" -p octopaint-app
    OCTOPAINT="$root/painter/target/release/octopaint"
fi
export OCTOPAINT
work="$out/files"
rm -rf "$work"
mkdir -p "$work"
summary="$out/summary.md"

{
    echo "# The painter core on many cores"
    echo
    echo "- host: $(uname -n), $cores cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')), $(awk '/MemTotal/ {printf "%.0f GiB", $2 / 2^20}' /proc/meminfo)"
    echo "- octopaint: $("$OCTOPAINT" --version)"
    echo "- threads: ${threads[*]}"
} > "$summary"

# The scene's replay per thread count: the same dumps at every count, the
# median wall time of SCENE_RUNS runs (taken in turns across the counts so
# a slow minute of the machine falls on all of them alike).
runs="${SCENE_RUNS:-3}"
declare -A times
for ((i = 0; i < runs; i++)); do
    for t in "${threads[@]}"; do
        dir="$work/scene_$t"
        rm -rf "$dir"
        start=$(date +%s.%N)
        RAYON_NUM_THREADS=$t "$OCTOPAINT" replay --renderer none --quiet --out "$dir" "$root/traces/scene.jsonl"
        end=$(date +%s.%N)
        times[$t]="${times[$t]:-} $(awk -v a="$start" -v b="$end" 'BEGIN {printf "%.4f", b - a}')"
        if [ "$t" != "${threads[0]}" ]; then
            for f in "$work/scene_${threads[0]}"/*.npz; do
                cmp -s "$f" "$dir/$(basename "$f")" || { echo "scene: $t threads wrote a different $(basename "$f")" >&2; exit 1; }
            done
        fi
    done
done
{
    echo
    echo "## traces/scene.jsonl, replay --renderer none (median of $runs, seconds; dumps equal at every count)"
    echo
    echo "| threads | median (s) | runs (s) | one thread over this |"
    echo "| ---: | ---: | --- | ---: |"
    one=""
    for t in "${threads[@]}"; do
        med=$(printf '%s\n' ${times[$t]} | sort -n | awk '{a[NR] = $1} END {print a[int((NR + 1) / 2)]}')
        [ -n "$one" ] || one=$med
        printf '| %s | %.3f | %s | %.2fx |\n' "$t" "$med" "$(printf '%.3f ' ${times[$t]})" "$(awk -v a="$one" -v b="$med" 'BEGIN {print a / b}')"
    done
} >> "$summary"

if [ "${REALTIME:-1}" != 0 ]; then
    size="${REALTIME_SIZE:-2880x1600}"
    {
        echo
        echo "## The stroke thread's paint time per sample (bench realtime, $size, scene stroke 2, 300 samples)"
        echo
        echo "| brush radius (finest cells) | adapter | paint ms p50 | paint ms p99 | frame ms p50 | frame ms p99 |"
        echo "| ---: | --- | ---: | ---: | ---: | ---: |"
    } >> "$summary"
    for r in 10 32; do
        if ! "$OCTOPAINT" bench realtime "$root/traces/scene.jsonl" --stroke 2 --samples 300 --default-only \
            --radius-cells "$r" --size "$size" --out "$work/realtime_$r" > "$work/realtime_$r.log" 2>&1; then
            echo "| $r | failed: $(tail -n 1 "$work/realtime_$r.log") | | | | |" >> "$summary"
            continue
        fi
        python3 "$here/many_cores_realtime.py" "$work/realtime_$r/results.json" "$r" >> "$summary"
    done
fi

{
    echo
    echo "## Equal work against OpenVDB (painter/bench/tree_vs_openvdb.sh)"
    echo
} >> "$summary"
CONTEXT=0 BUILD="$work/tree" bash "$here/tree_vs_openvdb.sh" "${radii[@]}" >> "$summary"

tar -czf "$out/files.tar.gz" -C "$out" files
cat "$summary"

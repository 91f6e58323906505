#!/usr/bin/env bash
# The GPU campaign (docs/benchmarks-gpu.md): every GPU figure
# of the painter and of the reference's JAX ray caster in one run, written
# as JSON plus OUT/summary.md.
#
#   painter/bench/gpu_campaign.sh OUT            # headset sizes, a 134 M-cell canvas
#   painter/bench/gpu_campaign.sh OUT --small    # the same steps at toy sizes (lavapipe, CI)
#
# Runs from the repository root with the release binary ($OCTOPAINT, else
# painter/target/release/octopaint) and a Python that has JAX ($PYTHON, else
# .venv/bin/python, else python3). On the device machine the Vulkan loader
# comes as .deb files in .gl/ (the device tool's README): they are unpacked
# first, and NVIDIA's ICD is named when it is there. The reference's images
# for the comparison are taken from .gpuref/ when present (rendered there
# beforehand by `octopaint-ref replay`, the same on every machine), else
# rendered here.
#
# Each step has its own time limit, and with CAMPAIGN_SECONDS set no step
# starts once that many seconds have passed; CAMPAIGN_STEPS="scene big"
# runs only the steps whose names start with one of those words; a step that fails or times out
# is recorded in OUT/steps.txt and the summary, and the others still run.
# Exit status: 0 when every step ran and every image was within tolerance.
set -u
out=${1:?usage: gpu_campaign.sh OUT [--small]}
size=${2:-full}
mkdir -p "$out"
out=$(cd "$out" && pwd)
cd "$(dirname "$0")/../.."
bin=${OCTOPAINT:-painter/target/release/octopaint}
if [ -n "${PYTHON:-}" ]; then py=$PYTHON; elif [ -x .venv/bin/python ]; then py=.venv/bin/python; else py=python3; fi
export NODEVICE_SELECT=1 PYTHONUNBUFFERED=1 XLA_PYTHON_CLIENT_PREALLOCATE=false PYTHONPATH=$PWD/reference${PYTHONPATH:+:$PYTHONPATH}

if [ -d .gl ] && ls .gl/*.deb >/dev/null 2>&1; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
fi
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -e "$icd" ] && [ -z "${VK_DRIVER_FILES:-}" ]; then export VK_DRIVER_FILES=$icd; fi

: >"$out/steps.txt"
start=$(date +%s)
failed=0
# step NAME LIMIT_SECONDS COMMAND...: run it with its output in the log.
step() {
    local name=$1 limit=$2
    shift 2
    local now left t0 rc w
    if [ -n "${CAMPAIGN_STEPS:-}" ]; then
        for w in $CAMPAIGN_STEPS; do
            case "$name" in "$w"*) break ;; esac
            w=
        done
        [ -n "$w" ] || return 0
    fi
    now=$(date +%s)
    if [ -n "${CAMPAIGN_SECONDS:-}" ]; then
        left=$((CAMPAIGN_SECONDS - (now - start)))
        if [ "$left" -lt 20 ]; then
            echo "$name skipped 0 (the campaign's time was spent)" >>"$out/steps.txt"
            failed=1
            return
        fi
        [ "$left" -lt "$limit" ] && limit=$left
    fi
    echo "== $name (limit ${limit} s): $*"
    t0=$(date +%s.%N)
    timeout --kill-after=5 "$limit" "$@"
    rc=$?
    echo "$name $rc $(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')" >>"$out/steps.txt"
    [ "$rc" = 0 ] || failed=1
}

{
    echo "date: $(date -u +%FT%TZ)"
    echo "host: $(uname -srm), $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo)"
    echo "commit: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
    echo "binary: $("$bin" --version 2>&1)"
    if command -v nvidia-smi >/dev/null; then
        nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm,clocks.max.mem,pcie.link.gen.max,pcie.link.width.max --format=csv
    fi
} >"$out/env.txt" 2>&1
cat "$out/env.txt"
if command -v nvidia-smi >/dev/null; then
    nvidia-smi --query-gpu=timestamp,memory.used,utilization.gpu --format=csv,noheader -lms 250 >"$out/gpumem.csv" 2>/dev/null &
    sampler=$!
    trap 'kill "$sampler" 2>/dev/null' EXIT
fi

traces="traces/single_stamp.jsonl traces/shapes_modes.jsonl traces/scene.jsonl traces/lit.jsonl traces/mirror.jsonl traces/layers.jsonl traces/imports.jsonl"
if [ "$size" = --small ]; then
    mono="--width 64 --height 36"; heads="vive=40x44,quest3=48x52"; runs=2; grow=2000000
    rt_sizes="48x27"; rt_full="--quick --samples 40 --size 48x27"; rt_samples="--samples 60"
    jax_size=24; jax_trace=traces/single_stamp.jsonl; rays=4096; probe="--size 16 --exact-rays 4"; traces="traces/single_stamp.jsonl traces/shapes_modes.jsonl"
else
    mono="--width 1280 --height 720"; heads="vive=1440x1600,quest3=2064x2208"; runs=5; grow=134400000
    rt_sizes="2880x1600 4128x2208"; rt_full="--samples 300 --size 2880x1600"; rt_samples=""
    jax_size=256; jax_trace=traces/scene.jsonl; rays=262144; probe="--size 256 --exact-rays 64"
fi

# 0. With CAMPAIGN_ADAPTER set (e.g. NVIDIA), stop at once unless wgpu's
#    adapter names it: a campaign on the wrong adapter is time wasted.
if [ -n "${CAMPAIGN_ADAPTER:-}" ]; then
    adapter=$("$bin" bench gpu traces/single_stamp.jsonl --width 8 --height 8 --runs 1 --short 2>&1 | grep '^adapter:')
    echo "$adapter"
    case "$adapter" in
        *"$CAMPAIGN_ADAPTER"*) ;;
        *) echo "adapter 2 0 (not $CAMPAIGN_ADAPTER: ${adapter:-none found})" >>"$out/steps.txt"; "$py" painter/bench/gpu_campaign_report.py "$out" >"$out/summary.md"; exit 2 ;;
    esac
fi
# 1. The scene: staging and copy bandwidth, g3, ray casting from the km
#    haze (camera 1), the close view (camera 0), the depth-21 brush work
#    (stroke 2) and the depth-25 stroke (stroke 6), mono and stereo, each
#    at full depth and at level of detail 1 (docs/spec.md 7).
step scene 240 "$bin" bench gpu traces/scene.jsonl $mono --runs $runs --headsets "$heads" \
    --trace-cameras 0,1 --frame-strokes 2,6 --lod 0,1 --json "$out/gpu_scene.json"
# 2. Latency and frame time with painting under way, the default pipeline,
#    one image holding both eyes' pixels (2 x W x H).
k=0
for s in $rt_sizes; do
    step "realtime_$s" 120 "$bin" bench realtime traces/scene.jsonl --default-only --size "$s" $rt_samples --out "$out/rt$k"
    [ -e "$out/rt$k/results.json" ] && mv "$out/rt$k/results.json" "$out/realtime_$s.json" && rmdir "$out/rt$k"
    k=$((k + 1))
done
# 3. The painter's images here against the reference's.
ref=.gpuref
if [ ! -d "$ref" ]; then ref=$out/reference; fi
step images 200 "$py" painter/bench/gpu_images.py --painter "$bin" --reference "$ref" --make-reference \
    --json "$out/images.json" $traces
# 4. The reference's JAX ray caster on this machine's devices: rays/s, and
#    the precision study emulated and native.
step jax_raycast 200 "$py" -m octopaint_ref.bench_raycast --trace $jax_trace --size $jax_size --precisions f32,f16,f32-native,f16-native \
    --json "$out/jax_raycast.json"
for p in f16 f32; do
    for a in emulated native; do
        step "precision_${p}_$a" 120 "$py" -m octopaint_ref.cli precision --rays $rays --precision $p --arith $a \
            --quiet --out "$out/precision_${p}_$a.json"
    done
done
# The painter's own ray caster ray by ray on this GPU against the bound,
# the emulation and mpmath (docs/precision.md, "The GPU ray by ray").
step gpu_probe 240 "$py" -m octopaint_ref.cli gpu-probe --painter "$bin" --out "$out/gpu_probe" $probe
# 5. The canvas grown to the paper's 2.15 GB of cells (16 bytes each).
step big 330 "$bin" bench gpu traces/scene.jsonl $mono --runs 3 --short --grow $grow --headsets "$heads" \
    --trace-cameras 0,1 --lod 0,1 --json "$out/gpu_big.json"
# 6. The paper's Table 1, Fig. 8 and Fig. 9 at the Vive's pixel count; only
#    the strategies (Fig. 9) when less than 160 s are left.
if [ -n "${CAMPAIGN_SECONDS:-}" ] && [ $((CAMPAIGN_SECONDS - ($(date +%s) - start))) -lt 160 ]; then
    rt_full="--quick ${rt_full#--quick }"
fi
step realtime_all 300 "$bin" bench realtime traces/scene.jsonl $rt_full --out "$out/rtall"
[ -e "$out/rtall/results.json" ] && mv "$out/rtall/results.json" "$out/realtime_all.json" && rmdir "$out/rtall"

[ -n "${sampler:-}" ] && kill "$sampler" 2>/dev/null
"$py" painter/bench/gpu_campaign_report.py "$out" | tee "$out/summary.md"
rm -rf "$out/reference"
exit $failed

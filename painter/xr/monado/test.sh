#!/usr/bin/env bash
# The VR session against Monado's simulated headset (docs/vr.md), checked:
# `octopaint xr-info` must find Monado's runtime and headset; `octopaint vr`
# must show a painted document for 30 frames paced by the runtime, and the
# last frame, read back from the runtime's swapchain, must show the
# painting in both eyes with the parallax of two eyes. Needs root and, the
# first time, network (run.sh makes the Debian 13 chroot).
#
#   painter/xr/monado/test.sh [PYTHON]     # PYTHON: one with Pillow (default .venv/bin/python)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$(dirname "$(dirname "$here")")")"
py="${1:-$repo/.venv/bin/python}"
octopaint="$repo/painter/target/release/octopaint"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"

"$octopaint" import "$repo/traces/shapes_modes.jsonl" painting.octo 2>/dev/null

"$here/run.sh" xr-info > info.txt 2>/dev/null
cat info.txt
grep -q '^runtime    Monado' info.txt || { echo "FAIL: xr-info did not find Monado" >&2; exit 1; }
grep -q 'XR_KHR_vulkan_enable2' info.txt || { echo "FAIL: no Vulkan binding" >&2; exit 1; }

"$here/run.sh" vr painting.octo --frames 30 --capture eyes.png --no-fallback 2> vr.log || { grep -v '^LOG\|^	' vr.log >&2; echo "FAIL: octopaint vr" >&2; exit 1; }
grep '^octopaint:' vr.log
grep -q '^octopaint: 30 frame(s) in the headset' vr.log || { echo "FAIL: not 30 frames" >&2; exit 1; }

"$py" - eyes.png <<'EOF'
import sys
from PIL import Image
im = Image.open(sys.argv[1]).convert("RGB")
w, h = im.size
assert w == 2 * (w // 2), im.size
bg = im.getpixel((0, 0))
def painted(x0):
    n, sx = 0, 0
    for y in range(h):
        for x in range(x0, x0 + w // 2):
            p = im.getpixel((x, y))
            if sum(abs(a - b) for a, b in zip(p, bg)) > 60:
                n += 1
                sx += x - x0
    return n, (sx / n if n else None)
(nl, cl), (nr, cr) = painted(0), painted(w // 2)
print(f"painted pixels: left eye {nl}, right eye {nr}; mean column {cl:.1f} vs {cr:.1f}")
assert nl > 200 and nr > 200, "the painting is not in both eyes"
assert 0.5 < nl / nr < 2.0, "the eyes disagree on the painting's size"
# Parallax: the painting 1 m away sits further right in the left eye.
assert cl > cr + 0.5, "no parallax between the eyes"
print("ok")
EOF
echo "VR test passed"

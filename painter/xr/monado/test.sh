#!/usr/bin/env bash
# The VR session against Monado's simulated headset (docs/vr.md), checked:
# `octopaint xr-info` must find Monado's runtime and headset; `octopaint vr`
# must show a painted document for 30 frames paced by the runtime, and the
# last frame, read back from the runtime's swapchain, must show the
# painting in both eyes with the parallax of two eyes; a stroke painted
# from scripted controller input must reach the document, and the recorded
# session must replay to the same tree. Needs root and, the first time,
# network (run.sh makes the Debian 13 chroot).
#
#   painter/xr/monado/test.sh [PYTHON]     # PYTHON: one with Pillow (default .venv/bin/python)
#
# OCTOPAINT_KEEP_VR_TEST=1 keeps the work folder (captures, logs) and says where.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$(dirname "$(dirname "$here")")")"
py="$(realpath -s "${1:-$repo/.venv/bin/python}")"   # absolute: the test runs elsewhere
octopaint="$repo/painter/target/release/octopaint"
work="$(mktemp -d)"; [ -n "${OCTOPAINT_KEEP_VR_TEST:-}" ] && echo "work folder: $work"
trap '[ -n "${OCTOPAINT_KEEP_VR_TEST:-}" ] || rm -rf "$work"' EXIT
cd "$work"

"$octopaint" import "$repo/traces/shapes_modes.jsonl" painting.octo 2>/dev/null

"$here/run.sh" xr-info > info.txt 2>/dev/null
cat info.txt
grep -q '^runtime    Monado' info.txt || { echo "FAIL: xr-info did not find Monado" >&2; exit 1; }
grep -q 'XR_KHR_vulkan_enable2' info.txt || { echo "FAIL: no Vulkan binding" >&2; exit 1; }

"$here/run.sh" vr painting.octo --frames 30 --capture eyes.png --no-fallback 2> vr.log || { grep -v '^LOG\|^	' vr.log >&2; echo "FAIL: octopaint vr" >&2; exit 1; }
grep '^octopaint:' vr.log
grep -q '^octopaint: 30 frame(s) in the headset' vr.log || { echo "FAIL: not 30 frames" >&2; exit 1; }
# Dynamic resolution: Monado's simulated head keeps moving, so the eyes are
# cast below full size, never below a quarter.
mean="$(sed -n 's/^octopaint: dynamic resolution: eyes cast at \([0-9]*\)% of their size on average.*/\1/p' vr.log)"
[ -n "$mean" ] && [ "$mean" -ge 25 ] && [ "$mean" -le 100 ] || { echo "FAIL: dynamic resolution: '$mean'" >&2; exit 1; }

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
            if y < h // 6 and x - x0 < w // 4:
                continue  # the HUD (indicators and palette), the same in both eyes
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
# Painting from scripted controller input: the right hand sweeps 30 cm
# across the painting with the trigger held (frames 3 to 23), lets go, and
# moves 35 cm right of the head, beside the painting, where the last frame
# must show the brush's ghost in both eyes.
"$py" - > stroke.jsonl <<'EOF'
print('{"frame": 0, "hand": "right", "pose": [-0.15, 0.0, -0.9, 0, 0, 0, 1], "trigger": 0}')
for i in range(3, 24):
    x, y = -0.15 + 0.3 * (i - 3) / 20, 0.05 * (i - 3) / 20
    print('{"frame": %d, "hand": "right", "pose": [%.4f, %.4f, -0.9, 0, 0, 0, 1], "trigger": 0.9}' % (i, x, y))
print('{"frame": 25, "hand": "right", "trigger": 0}')
print('{"frame": 26, "hand": "right", "pose": [0.35, 0.0, -0.9, 0, 0, 0, 1]}')
EOF
before="$("$octopaint" info painting.octo | grep '^undo')"
"$here/run.sh" vr painting.octo --frames 30 --script stroke.jsonl --capture eyes2.png --no-fallback 2> vr2.log || { grep -v '^LOG\|^	' vr2.log >&2; echo "FAIL: octopaint vr --script" >&2; exit 1; }
grep '^octopaint:' vr2.log
grep -q '1 stroke(s) painted, saved' vr2.log || { echo "FAIL: the scripted stroke was not painted" >&2; exit 1; }
# The brush cursor: pixels of the brush's orange (the palette's first
# colour, 235, 114, 38, blended over the background) in both eyes, none
# before the hand came, further right in the left eye. Matched by the
# colour's proportions, so the painting's own colours do not count; the
# HUD's corner (its swatch is that orange) is left out.
"$py" - eyes.png eyes2.png <<'EOF'
import sys
from PIL import Image
def ring(path):
    im = Image.open(path).convert("RGB")
    w, h = im.size
    e = w // 2
    out = []
    for x0 in (0, e):
        bg = im.getpixel((x0 + e - 1, h - 1))
        n, sx = 0, 0
        for y in range(h):
            for x in range(x0, x0 + e):
                if y < h // 3 and x - x0 < e // 2:
                    continue
                d = [a - b for a, b in zip(im.getpixel((x, y)), bg)]
                if d[0] > 110 and abs(d[1] - 0.485 * d[0]) < 15 and abs(d[2] - 0.162 * d[0]) < 15:
                    n += 1
                    sx += x - x0
        out.append((n, sx / n if n else None))
    return out
before, after = ring(sys.argv[1]), ring(sys.argv[2])
print(f"brush cursor pixels: before {before[0][0]}, {before[1][0]}; after {after[0][0]} (column {after[0][1]}), {after[1][0]} (column {after[1][1]})")
assert before[0][0] <= 5 and before[1][0] <= 5, "the cursor's orange before the hand came"
assert after[0][0] >= 12 and after[1][0] >= 12, "no brush cursor in both eyes"
assert after[0][1] > after[1][1], "no parallax between the eyes' cursors"
print("ok")
EOF
after="$("$octopaint" info painting.octo | grep '^undo')"
echo "before: $before"; echo "after:  $after"
[ "$before" != "$after" ] || { echo "FAIL: the document did not change" >&2; exit 1; }
# The session, recorded as a trace, replays to the document's tree.
"$octopaint" record painting.octo --out session.jsonl 2>/dev/null
printf '{"ev": "snapshot", "t": 1e9, "name": "end"}\n' >> session.jsonl
"$octopaint" replay session.jsonl --out replayed --renderer none --quiet 2>/dev/null
"$octopaint" dump painting.octo document.npz
cmp replayed/end.npz document.npz || { echo "FAIL: the recorded session does not replay to the document's tree" >&2; exit 1; }
echo "the recorded session replays to the document's tree, byte for byte"
# The palette: the left hand held in view, its thumbstick flicked right
# (next colour); the palette must be drawn at the hand in both eyes, with
# the parallax of a hand half a metre away.
cat > palette.jsonl <<'EOF'
{"frame": 0, "hand": "left", "pose": [-0.12, -0.08, -0.5, 0, 0, 0, 1]}
{"frame": 4, "hand": "left", "stick": [1, 0]}
{"frame": 6, "hand": "left", "stick": [0, 0]}
EOF
"$here/run.sh" vr painting.octo --frames 10 --capture palette.png --script palette.jsonl --no-fallback 2> vr3.log || { grep -v '^LOG\|^	' vr3.log >&2; echo "FAIL: octopaint vr (palette)" >&2; exit 1; }
"$py" - palette.png <<'EOF'
import sys
from PIL import Image
im = Image.open(sys.argv[1]).convert("RGB")
w, h = im.size
# The purple swatch (0.55, 0.3, 0.75) of the palette, in each eye.
want = (140, 76, 191)
def swatch(x0):
    xs = [x - x0 for y in range(h) for x in range(x0, x0 + w // 2)
          if sum(abs(a - b) for a, b in zip(im.getpixel((x, y)), want)) < 30]
    return len(xs), (sum(xs) / len(xs) if xs else None)
(nl, cl), (nr, cr) = swatch(0), swatch(w // 2)
print(f"palette swatch pixels: left eye {nl}, right eye {nr}; mean column {cl} vs {cr}")
assert nl > 8 and nr > 8, "the palette is not at the hand in both eyes"  # a swatch is about 5x5 px at 320x240
assert cl > cr + 5, "the palette has no parallax: it is not at the hand's depth"
print("ok")
EOF
# Framing the painting: the left hand grabs the canvas and carries it 2 m
# to the right, out of view; without more the last frame shows no painting,
# and with X pressed while the grip is held the painting is back in front
# of the head in both eyes.
"$py" - > carry.jsonl <<'EOF'
print('{"frame": 0, "hand": "left", "pose": [-0.2, 0.0, -0.5, 0, 0, 0, 1]}')
print('{"frame": 2, "hand": "left", "grip": 0.9}')
for i in range(3, 11):
    print('{"frame": %d, "hand": "left", "pose": [%.3f, 0.0, -0.5, 0, 0, 0, 1]}' % (i, -0.2 + 2.0 * (i - 2) / 8))
EOF
{ cat carry.jsonl; echo '{"frame": 13, "hand": "left", "primary": true}'; echo '{"frame": 14, "hand": "left", "primary": false, "grip": 0}'; } > reframe.jsonl
for run in carry reframe; do
    "$here/run.sh" vr painting.octo --frames 20 --capture "$run.png" --script "$run.jsonl" --no-fallback 2> "vr-$run.log" || { grep -v '^LOG\|^	' "vr-$run.log" >&2; echo "FAIL: octopaint vr ($run)" >&2; exit 1; }
done
"$py" - carry.png reframe.png <<'EOF'
import sys
from PIL import Image
def painted(path):
    im = Image.open(path).convert("RGB")
    w, h = im.size
    bg = im.getpixel((w // 2 - 1, h - 1))
    out = []
    for x0 in (0, w // 2):
        n = 0
        for y in range(h):
            for x in range(x0, x0 + w // 2):
                if y < h // 3 and x - x0 < w // 4:
                    continue  # the HUD
                if sum(abs(a - b) for a, b in zip(im.getpixel((x, y)), bg)) > 60:
                    n += 1
        out.append(n)
    return out
carried, framed = painted(sys.argv[1]), painted(sys.argv[2])
print(f"painted pixels: carried away {carried}, framed again {framed}")
assert max(carried) < 20, "the grab did not carry the painting out of view"
assert min(framed) > 200, "X with the grip held did not frame the painting"
print("ok")
EOF
# A document of layers in the headset (docs/vr.md "Layers and mirror"):
# every visible layer drawn; the palette's layer page (left trigger) adds a
# layer (Y), a stroke paints it, the mirror page (trigger again) turns the
# x plane on (X) and a second stroke paints with its copy; the session
# records those events and replays to the document's layers.
"$octopaint" import "$repo/traces/layers.jsonl" layers.octo 2>/dev/null
"$py" - > layers.jsonl <<'EOF'
print('{"frame": 0, "hand": "left", "pose": [-0.12, -0.08, -0.5, 0, 0, 0, 1]}')
print('{"frame": 0, "hand": "right", "pose": [-0.1, 0.0, -0.9, 0, 0, 0, 1], "trigger": 0}')
print('{"frame": 2, "hand": "left", "trigger": 0.9}')
print('{"frame": 3, "hand": "left", "trigger": 0}')
print('{"frame": 4, "hand": "left", "secondary": true}')
print('{"frame": 5, "hand": "left", "secondary": false}')
for i in range(6, 14):
    print('{"frame": %d, "hand": "right", "pose": [%.4f, 0.02, -0.9, 0, 0, 0, 1], "trigger": 0.9}' % (i, -0.1 + 0.08 * (i - 6) / 7))
print('{"frame": 14, "hand": "right", "trigger": 0}')
print('{"frame": 15, "hand": "left", "trigger": 0.9}')
print('{"frame": 16, "hand": "left", "trigger": 0}')
print('{"frame": 17, "hand": "left", "primary": true}')
print('{"frame": 18, "hand": "left", "primary": false}')
for i in range(19, 26):
    print('{"frame": %d, "hand": "right", "pose": [%.4f, -0.03, -0.9, 0, 0, 0, 1], "trigger": 0.9}' % (i, 0.05 + 0.04 * (i - 19) / 6))
print('{"frame": 26, "hand": "right", "trigger": 0}')
EOF
"$here/run.sh" vr layers.octo --frames 30 --script layers.jsonl --capture layers.png --no-fallback 2> vr-layers.log || { grep -v '^LOG\|^	' vr-layers.log >&2; echo "FAIL: octopaint vr (layers)" >&2; exit 1; }
grep '^octopaint:' vr-layers.log
grep -q '2 stroke(s) painted, saved' vr-layers.log || { echo "FAIL: the two scripted strokes were not painted" >&2; exit 1; }
"$octopaint" info layers.octo > layers-info.txt
grep -q '"Layer 4"' layers-info.txt || { cat layers-info.txt >&2; echo "FAIL: Y on the layer page did not add a layer" >&2; exit 1; }
"$octopaint" record layers.octo --out layers-session.jsonl 2>/dev/null
grep '"op":"add"' layers-session.jsonl | grep -q '"name":"Layer 4"' || { echo "FAIL: no layer event recorded" >&2; exit 1; }
grep -q '"axes":\[true,false,false\]' layers-session.jsonl || { echo "FAIL: no mirror event recorded" >&2; exit 1; }
printf '{"ev": "snapshot", "t": 1e9, "name": "end"}\n' >> layers-session.jsonl
"$octopaint" replay layers-session.jsonl --out layers-replayed --renderer none --quiet 2>/dev/null
"$octopaint" dump layers.octo layers-document.npz
cmp layers-replayed/end.npz layers-document.npz || { echo "FAIL: the recorded session does not replay to the document's layers" >&2; exit 1; }
"$py" - layers.png <<'EOF'
import sys
from PIL import Image
im = Image.open(sys.argv[1]).convert("RGB")
w, h = im.size
bg = im.getpixel((w // 2 - 1, h - 1))
def painted(x0):
    return sum(1 for y in range(h) for x in range(x0, x0 + w // 2)
               if not (y < h // 3 and x - x0 < w // 4) and sum(abs(a - b) for a, b in zip(im.getpixel((x, y)), bg)) > 60)
nl, nr = painted(0), painted(w // 2)
print(f"painted pixels of the layers: left eye {nl}, right eye {nr}")
assert nl > 200 and nr > 200, "the layers are not drawn in both eyes"
print("ok")
EOF
echo "the headset painted a new layer and a mirrored stroke; the session replays to the document's layers"

# The headset through the engine, with the stroke thread held at a gate for
# the whole session: a trace played into it (--play) queues its jobs while
# the headset goes on submitting its 30 frames (no frame waits for
# painting); the hold lets go as the session ends, the stroke thread paints
# them and saves, and the document equals the trace imported.
cp "$repo/traces/undo_redo.jsonl" played.jsonl   # in the work folder: the chroot sees it
"$octopaint" new played.octo --like played.jsonl >/dev/null
touch hold
"$here/run.sh" vr played.octo --frames 30 --play played.jsonl --hold-painting hold --frame-log played.csv --no-fallback 2> vr-played.log || { grep -v '^LOG\|^	' vr-played.log >&2; echo "FAIL: octopaint vr --play" >&2; exit 1; }
grep '^octopaint:' vr-played.log
# --frames counts on until the trace is queued: 30 frames or more.
played_frames="$(sed -n 's/^octopaint: \([0-9]*\) frame(s) in the headset.*/\1/p' vr-played.log)"
[ -n "$played_frames" ] && [ "$played_frames" -ge 30 ] || { echo "FAIL: $played_frames frames with painting held, not 30 or more" >&2; exit 1; }
# The frame log: a line a frame drawn, and the frames drawn while the
# stroke thread sat in a sample (its engine column 1) are most of them.
"$py" - played.csv "$played_frames" <<'EOF'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
frames = int(sys.argv[2])
assert len(rows) == frames, f"{len(rows)} lines in the frame log for {frames} frames"
held = sum(r["engine"] == "1" for r in rows)
assert held >= frames - 5, f"only {held} of {frames} frames were drawn while the stroke thread painted"
assert rows[0]["cast"] == "1", "the first frame cast nothing"
print(f"frame log: {len(rows)} frames, {held} drawn while the stroke thread was held in a sample")
EOF
"$octopaint" import played.jsonl imported.octo >/dev/null
"$octopaint" dump played.octo played.npz
"$octopaint" dump imported.octo imported.npz
cmp played.npz imported.npz || { echo "FAIL: the played document differs from the trace imported" >&2; exit 1; }
echo "$played_frames frames with painting held; the played trace painted once released, as imported"

echo "VR test passed"

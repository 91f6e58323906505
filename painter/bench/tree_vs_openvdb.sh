#!/usr/bin/env bash
# The painter core against OpenVDB 10 on the same strokes (docs/benchmarks.md).
#
#   painter/bench/tree_vs_openvdb.sh [RADII...]     # default: 4 10 32 finest cells
#
# For each brush radius: `octopaint bench tree` paints the deterministic
# stroke set (200 strokes x 50 sphere samples) and writes it out;
# openvdb_stamp paints the same file with OpenVDB (ValueAccessor stamping
# into a per-stroke grid, tools::compMax into the canvas). Both run
# single-threaded in this one script, one after the other, and the table
# gives every figure with its ratio. Installs libopenvdb-dev and boost
# headers with apt-get when they are missing (needs root), builds the peer
# with g++ and the painter with cargo.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
painter_dir="$(dirname "$here")"
build="$painter_dir/target/bench"
mkdir -p "$build"
radii=("$@")
[ ${#radii[@]} -eq 0 ] && radii=(4 10 32)

if ! [ -e /usr/include/openvdb/openvdb.h ] || ! [ -e /usr/include/boost/version.hpp ]; then
    echo "installing libopenvdb-dev and libboost-dev" >&2
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q libopenvdb-dev libboost-dev >/dev/null
fi
if ! [ "$build/openvdb_stamp" -nt "$here/openvdb_stamp.cpp" ]; then
    g++ -O2 -std=c++17 "$here/openvdb_stamp.cpp" -o "$build/openvdb_stamp" -lopenvdb -ltbb -lImath-3_1
fi
cargo build --quiet --release --locked --manifest-path "$painter_dir/Cargo.toml" -p octopaint-app
octopaint="$painter_dir/target/release/octopaint"

for r in "${radii[@]}"; do
    "$octopaint" bench tree --radius "$r" --write-strokes "$build/strokes_$r.txt" > "$build/octopaint_$r.json"
    # TBB may start worker threads, but nothing here asks it for parallel work.
    "$build/openvdb_stamp" "$build/strokes_$r.txt" > "$build/openvdb_$r.json"
done

python3 - "$build" "${radii[@]}" <<'PY'
import json, sys
build, radii = sys.argv[1], sys.argv[2:]
rows = []
for r in radii:
    o = json.load(open(f"{build}/octopaint_{r}.json"))
    v = json.load(open(f"{build}/openvdb_{r}.json"))
    rows.append((r, o, v))
def fmt(x):
    return f"{x / 1e6:.2f} M" if x >= 1e5 else f"{x:,.0f}"
print(f"{'radius':>6} | {'octopaint s':>11} {'openvdb s':>10} {'time ratio':>10} | "
      f"{'updates/s':>10} {'writes/s':>10} {'ratio':>6} | {'stamp upd/s':>11} {'stamp wr/s':>11} {'ratio':>6} | "
      f"{'cells':>9} {'voxels':>9} {'ratio':>6} | {'B/cell':>6} {'B/voxel':>7}")
for r, o, v in rows:
    updates = o["cell_updates"] / o["seconds"]
    writes = v["voxel_writes"] / v["seconds"]
    stamp_u = o["cell_updates_per_s"]
    stamp_w = v["voxel_writes"] / v["stamp_seconds"]
    print(f"{r:>6} | {o['seconds']:>11.2f} {v['seconds']:>10.2f} {v['seconds'] / o['seconds']:>9.2f}x | "
          f"{fmt(updates):>10} {fmt(writes):>10} {updates / writes:>5.2f}x | {fmt(stamp_u):>11} {fmt(stamp_w):>11} {stamp_u / stamp_w:>5.2f}x | "
          f"{fmt(o['leaves']):>9} {fmt(v['active_voxels']):>9} {v['active_voxels'] / o['leaves']:>5.2f}x | "
          f"{o['bytes_per_cell_allocated']:>6.1f} {v['bytes_per_voxel']:>7.1f}")
print()
print("time ratio: OpenVDB's time over octopaint's for the same strokes (higher: octopaint faster)")
print("updates/s: octopaint's leaves updated by paint passes per second of the whole run; writes/s: OpenVDB's voxel writes")
print("(voxels with coverage > 0 per segment) per second of the whole run, per-stroke compMax included")
print("stamp: the same, per second of stamping alone (octopaint's paint passes; OpenVDB's accessor loop)")
print("cells: octopaint's leaves after the last stroke; voxels: OpenVDB's active voxels")
print("octopaint also creates cells by refinement: " + ", ".join(f"r={r}: {o['cells_created'] / 1e6:.1f} M at {o['cells_created_per_s'] / 1e6:.2f} M/s" for r, o, _ in rows))
PY

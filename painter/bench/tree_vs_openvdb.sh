#!/usr/bin/env bash
# The painter core against OpenVDB 10 on the same strokes (docs/benchmarks.md).
#
#   painter/bench/tree_vs_openvdb.sh [RADII...]     # default: 4 10 32 finest cells
#
# For each brush radius: `octopaint bench tree` paints the deterministic
# stroke set (200 strokes x 50 sphere samples) and writes it out;
# openvdb_stamp paints the same file with OpenVDB (ValueAccessor stamping
# into a per-stroke grid), merging each stroke into the canvas twice over:
# with tools::compMax (the idiom the benchmark was specified with) and by
# visiting the stroke's active voxels (the faster idiom). All runs
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
    "$build/openvdb_stamp" "$build/strokes_$r.txt" --merge compmax > "$build/openvdb_compmax_$r.json"
    "$build/openvdb_stamp" "$build/strokes_$r.txt" --merge voxels > "$build/openvdb_voxels_$r.json"
done

python3 "$here/tree_vs_openvdb_table.py" "$build" "${radii[@]}"

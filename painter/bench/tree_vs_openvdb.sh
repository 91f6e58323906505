#!/usr/bin/env bash
# The painter core against OpenVDB 10 on the same strokes (docs/benchmarks.md).
#
#   painter/bench/tree_vs_openvdb.sh [RADII...]     # default: 4 10 32 finest cells
#
# For each brush radius: `octopaint bench tree` paints the deterministic
# stroke set (200 strokes x 50 sphere samples) and writes it out;
# openvdb_stamp paints the same file with OpenVDB three ways:
#   equal    octopaint's work: colour and density, the per-stroke maximum in
#            a scratch grid, octopaint's paint blend at the merge; at 1
#            thread and at all cores (TBB's LeafManager for the merge);
#   compmax  density only, merged with tools::compMax (context);
#   voxels   density only, merged voxel by voxel (context).
# Octopaint runs at 1 thread and at all cores (`--threads`); the table
# checks that both painted the same tree and undo steps (tree_digest).
# Everything runs in this one script, one after the other, and the tables
# give every figure with its ratio. Installs libopenvdb-dev and boost
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

cores=$(nproc)
for r in "${radii[@]}"; do
    "$octopaint" bench tree --radius "$r" --threads 1 --write-strokes "$build/strokes_$r.txt" > "$build/octopaint_1_$r.json"
    "$octopaint" bench tree --radius "$r" --threads "$cores" > "$build/octopaint_all_$r.json"
    "$build/openvdb_stamp" "$build/strokes_$r.txt" --merge equal --threads 1 > "$build/openvdb_equal_1_$r.json"
    "$build/openvdb_stamp" "$build/strokes_$r.txt" --merge equal --threads "$cores" > "$build/openvdb_equal_all_$r.json"
    # TBB capped at one thread: the density-only rows are single-threaded.
    "$build/openvdb_stamp" "$build/strokes_$r.txt" --merge compmax > "$build/openvdb_compmax_$r.json"
    "$build/openvdb_stamp" "$build/strokes_$r.txt" --merge voxels > "$build/openvdb_voxels_$r.json"
done

python3 "$here/tree_vs_openvdb_table.py" "$build" "$cores" "${radii[@]}"

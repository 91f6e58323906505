#!/usr/bin/env bash
# The painter core against OpenVDB 10 on the same strokes (docs/benchmarks.md).
#
#   painter/bench/tree_vs_openvdb.sh [RADII...]     # default: 4 10 32 finest cells
#
# Environment (all optional):
#   THREADS="1 4 16"   thread counts for both programs' equal-work runs
#                      (default: "1 N" with N = nproc; 1 is always run)
#   CONTEXT=0          leave out the density-only rows (compmax, voxels)
#   OCTOPAINT=PATH     a prebuilt octopaint instead of cargo's build
#   OPENVDB_STAMP=PATH a prebuilt openvdb_stamp instead of g++'s build
#   BUILD=DIR          where the strokes and JSON files go
#                      (default painter/target/bench)
# With both binaries given nothing is installed or built, so the script runs
# on a machine without OpenVDB's headers or cargo (docs/benchmarks.md).
#
# For each brush radius: `octopaint bench tree` paints the deterministic
# stroke set (200 strokes x 50 sphere samples) and writes it out;
# openvdb_stamp paints the same file with OpenVDB three ways:
#   equal    octopaint's work: colour and density, the per-stroke maximum in
#            a scratch grid, octopaint's paint blend at the merge; at each
#            thread count (TBB's LeafManager for the merge);
#   compmax  density only, merged with tools::compMax (context);
#   voxels   density only, merged voxel by voxel (context).
# Octopaint runs at the same thread counts (`--threads`); the table checks
# that every count painted the same tree and undo steps (tree_digest), and
# OpenVDB the same sums.
# Everything runs in this one script, one after the other, and the tables
# give every figure with its ratio. Installs libopenvdb-dev and boost
# headers with apt-get when they are missing (needs root), builds the peer
# with g++ and the painter with cargo.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
painter_dir="$(dirname "$here")"
build="${BUILD:-$painter_dir/target/bench}"
mkdir -p "$build"
radii=("$@")
[ ${#radii[@]} -eq 0 ] && radii=(4 10 32)
cores=$(nproc)
# shellcheck source=thread_counts.sh
. "$here/thread_counts.sh"
thread_counts "${THREADS:-1 $cores}"
context="${CONTEXT:-1}"

stamp="${OPENVDB_STAMP:-}"
if [ -z "$stamp" ]; then
    if ! [ -e /usr/include/openvdb/openvdb.h ] || ! [ -e /usr/include/boost/version.hpp ]; then
        echo "installing libopenvdb-dev and libboost-dev" >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -q libopenvdb-dev libboost-dev >/dev/null
    fi
    stamp="$painter_dir/target/bench/openvdb_stamp"
    mkdir -p "$(dirname "$stamp")"
    if ! [ "$stamp" -nt "$here/openvdb_stamp.cpp" ]; then
        g++ -O2 -std=c++17 "$here/openvdb_stamp.cpp" -o "$stamp" -lopenvdb -ltbb -lImath-3_1
    fi
fi
octopaint="${OCTOPAINT:-}"
if [ -z "$octopaint" ]; then
    cargo build --quiet --release --locked --manifest-path "$painter_dir/Cargo.toml" -p octopaint-app
    octopaint="$painter_dir/target/release/octopaint"
fi

for r in "${radii[@]}"; do
    "$octopaint" bench tree --radius "$r" --threads 1 --write-strokes "$build/strokes_$r.txt" > "$build/octopaint_1_$r.json"
    for t in "${threads[@]}"; do
        [ "$t" = 1 ] || "$octopaint" bench tree --radius "$r" --threads "$t" > "$build/octopaint_${t}_$r.json"
        "$stamp" "$build/strokes_$r.txt" --merge equal --threads "$t" > "$build/openvdb_equal_${t}_$r.json"
    done
    if [ "$context" != 0 ]; then
        # TBB capped at one thread: the density-only rows are single-threaded.
        "$stamp" "$build/strokes_$r.txt" --merge compmax > "$build/openvdb_compmax_$r.json"
        "$stamp" "$build/strokes_$r.txt" --merge voxels > "$build/openvdb_voxels_$r.json"
    fi
done

python3 "$here/tree_vs_openvdb_table.py" "$build" "$(IFS=,; echo "${threads[*]}")" "$context" "${radii[@]}"

"""The table of painter/bench/tree_vs_openvdb.sh: octopaint against both
OpenVDB merges, every figure with its ratio (docs/benchmarks.md)."""

import json
import sys

build, radii = sys.argv[1], sys.argv[2:]


def load(name, r):
    with open(f"{build}/{name}_{r}.json") as f:
        return json.load(f)


def m(x):
    return f"{x / 1e6:.1f} M"


print("| radius (cells) | implementation | time (s) | updates or writes | per s, whole run | per s, stamping | cells or voxels kept | bytes each |")
print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
for r in radii:
    o = load("octopaint", r)
    # Bytes per kept cell: the pools' allocation over the leaves (internal cells included).
    rows = [("octopaint", o["seconds"], o["cell_updates"], o["paint_pass_seconds"], o["leaves"],
             o["bytes_per_cell_allocated"] * o["cells_used"] / o["leaves"])]
    for merge in ("compmax", "voxels"):
        v = load(f"openvdb_{merge}", r)
        rows.append((f"OpenVDB, {merge} merge", v["seconds"], v["voxel_writes"], v["stamp_seconds"], v["active_voxels"], v["bytes_per_voxel"]))
    for name, sec, n, stamp_s, kept, b in rows:
        print(f"| {r} | {name} | {sec:.2f} | {m(n)} | {m(n / sec)} | {m(n / stamp_s)} | {m(kept)} | {b:.1f} |")
print()
print("Ratios, octopaint over OpenVDB (above 1: octopaint better):")
print()
print("| radius | merge | time | updates/s, whole run | updates/s, stamping | kept (voxels/cells) | bytes kept |")
print("| ---: | --- | ---: | ---: | ---: | ---: | ---: |")
for r in radii:
    o = load("octopaint", r)
    for merge in ("compmax", "voxels"):
        v = load(f"openvdb_{merge}", r)
        print(
            f"| {r} | {merge} | {v['seconds'] / o['seconds']:.2f}x | "
            f"{(o['cell_updates'] / o['seconds']) / (v['voxel_writes'] / v['seconds']):.2f}x | "
            f"{o['cell_updates_per_s'] / (v['voxel_writes'] / v['stamp_seconds']):.2f}x | "
            f"{v['active_voxels'] / o['leaves']:.2f}x | "
            f"{(v['active_voxels'] * v['bytes_per_voxel']) / (o['cells_used'] * o['bytes_per_cell_allocated']):.2f}x |"
        )
print()
print("octopaint also refines: " + "; ".join(
    f"r={r}: {load('octopaint', r)['cells_created'] / 1e6:.1f} M cells created at {load('octopaint', r)['cells_created_per_s'] / 1e6:.2f} M/s, "
    f"{load('octopaint', r)['stroke_end_seconds']:.2f} s cleaning and undo bookkeeping" for r in radii))

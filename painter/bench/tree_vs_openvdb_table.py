"""The table of painter/bench/tree_vs_openvdb.sh: octopaint against both
OpenVDB merges, every figure with its ratio (docs/benchmarks.md)."""

import json
import sys

# ARGS: BUILD THREADS CONTEXT RADII..., THREADS a comma-separated list
# starting with 1, CONTEXT 0 where the density-only runs were left out.
build, threads, context, radii = sys.argv[1], sys.argv[2].split(","), sys.argv[3] != "0", sys.argv[4:]
assert threads[0] == "1", "the thread counts start with 1"


def load(name, r):
    with open(f"{build}/{name}_{r}.json") as f:
        return json.load(f)


def m(x):
    return f"{x / 1e6:.1f} M"


def mib(x):
    return f"{x / 2**20:.1f}"


# Every thread count must have painted what one thread painted before any
# figure is printed.
for r in radii:
    for t in threads[1:]:
        a, b = load("openvdb_equal_1", r), load(f"openvdb_equal_{t}", r)
        assert (a["sigma_sum"], a["rgb_sum"], a["active_voxels"]) == (b["sigma_sum"], b["rgb_sum"], b["active_voxels"]), (
            f"r={r}: OpenVDB painted differently on 1 and {t} threads"
        )
        a, b = load("octopaint_1", r), load(f"octopaint_{t}", r)
        assert a["tree_digest"] == b["tree_digest"], f"r={r}: octopaint painted differently on 1 and {t} threads"

# Equal work: octopaint against OpenVDB doing octopaint's work.
print(f"Equal work (colour and density, per-stroke maximum, octopaint's blend); threads {', '.join(threads)}.")
print("Updates are the cells each program evaluated: octopaint does not revisit the half ball behind")
print("each sample (open capsule starts, spec 8.3), so for the same result it makes fewer; compare times.")
print()
print("| radius | program | threads | time (s) | updates/s, whole run | cells or voxels kept | MiB kept | MiB allocated | peak RSS MiB |")
print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for r in radii:
    for t in threads:
        o = load(f"octopaint_{t}", r)
        kept = o["cells_used"] * o["bytes_per_cell_pools"]
        alloc = o["cells_used"] * o["bytes_per_cell_allocated"]
        print(f"| {r} | octopaint | {t} | {o['seconds']:.2f} | {m(o['cell_updates'] / o['seconds'])} | "
              f"{m(o['leaves'])} leaves ({m(o['cells_used'])} cells) | {mib(kept)} | {mib(alloc)} (+{mib(o['history_bytes_per_cell'] * o['cells_used'])} undo) | {o['peak_rss_mib']:.0f} |")
    for t in threads:
        v = load(f"openvdb_equal_{t}", r)
        print(f"| {r} | OpenVDB {v['version']} | {t} | {v['seconds']:.2f} | {m(v['voxel_writes'] / v['seconds'])} | "
              f"{m(v['active_voxels'])} voxels | {mib(v['mem_bytes'])} | {mib(v['mem_bytes'])} | {v['peak_rss_mib']:.0f} |")
print()
print("Ratios at equal work, octopaint over OpenVDB on as many threads (above 1: octopaint better):")
print()
print("| radius | threads | time | updates/s, whole run | kept (voxels/cells) | bytes kept | peak RSS |")
print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for r in radii:
    for t in threads:
        o = load(f"octopaint_{t}", r)
        v = load(f"openvdb_equal_{t}", r)
        print(
            f"| {r} | {t} | {v['seconds'] / o['seconds']:.2f}x | "
            f"{(o['cell_updates'] / o['seconds']) / (v['voxel_writes'] / v['seconds']):.2f}x | "
            f"{v['active_voxels'] / o['leaves']:.2f}x | "
            f"{v['mem_bytes'] / (o['cells_used'] * o['bytes_per_cell_pools']):.2f}x | "
            f"{v['peak_rss_mib'] / o['peak_rss_mib']:.2f}x |"
        )
print()
print("Scaling, time on one thread over time on N (the same program, the same strokes):")
print()
print("| radius | program | " + " | ".join(f"{t} threads" for t in threads) + " |")
print("| ---: | --- | " + " | ".join("---:" for _ in threads) + " |")
for r in radii:
    for name, prefix in (("octopaint", "octopaint"), ("OpenVDB", "openvdb_equal")):
        one = load(f"{prefix}_1", r)["seconds"]
        print(f"| {r} | {name} | " + " | ".join(f"{one / load(f'{prefix}_{t}', r)['seconds']:.2f}x" for t in threads) + " |")
print()
print("octopaint also refines: " + "; ".join(
    f"r={r}: {load('octopaint_1', r)['cells_created'] / 1e6:.1f} M cells created at {load('octopaint_1', r)['cells_created_per_s'] / 1e6:.2f} M/s, "
    f"{load('octopaint_1', r)['stroke_end_seconds']:.2f} s cleaning and undo bookkeeping" for r in radii))
if not context:
    sys.exit(0)
print()
print("Density only (OpenVDB paints no colour; the earlier rows, kept for context; octopaint on one thread):")
print()
print("| radius (cells) | implementation | time (s) | updates or writes | per s, whole run | per s, stamping | cells or voxels kept | bytes each |")
print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
for r in radii:
    o = load("octopaint_1", r)
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
    o = load("octopaint_1", r)
    for merge in ("compmax", "voxels"):
        v = load(f"openvdb_{merge}", r)
        print(
            f"| {r} | {merge} | {v['seconds'] / o['seconds']:.2f}x | "
            f"{(o['cell_updates'] / o['seconds']) / (v['voxel_writes'] / v['seconds']):.2f}x | "
            f"{o['cell_updates_per_s'] / (v['voxel_writes'] / v['stamp_seconds']):.2f}x | "
            f"{v['active_voxels'] / o['leaves']:.2f}x | "
            f"{(v['active_voxels'] * v['bytes_per_voxel']) / (o['cells_used'] * o['bytes_per_cell_allocated']):.2f}x |"
        )

"""Exports timed against OpenVDB writing the same grids (docs/benchmarks.md).

    /usr/bin/python3 painter/bench/export_vs_openvdb.py [--octopaint PATH]

Run with Debian's python3 (it imports python3-openvdb). For each case the
script runs `octopaint export` (replay, resampling, VDB writing: the
painter's own timings, parsed from its output, plus the wall clock of the
whole command), then reads the file back with OpenVDB and writes the same
grids with OpenVDB's own writer (its default compression: active-mask
compression plus zip or blosc as built) in this same process, and prints
both writers' times and sizes with their ratio. Meshes: triangles, the
time to extract them, and the glTF size. Cases are the scene trace whole
(at the default depth under a 1 GiB cap) and its detail region at three
depths.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

import pyopenvdb as vdb

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SCENE = os.path.join(REPO, "traces", "scene.jsonl")
DETAIL = "19999.6,19999.7,19999.5,20000.6,20000.5,20000.3"

CASES = [
    ("scene, whole canvas, default depth", []),
    ("scene detail, depth 19", ["--region", DETAIL, "--depth", "19"]),
    ("scene detail, depth 21", ["--region", DETAIL, "--depth", "21"]),
    ("scene detail, default depth", ["--region", DETAIL]),
]


def run_case(octopaint, args, out):
    vdb_path = os.path.join(out, "x.vdb")
    glb_path = os.path.join(out, "x.glb")
    t = time.perf_counter()
    r = subprocess.run([octopaint, "export", SCENE, "--vdb", vdb_path, "--gltf", glb_path] + args, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    log = r.stderr
    replay_s = float(re.search(r"deepest depth \d+ \(([\d.]+) s\)", log).group(1))
    surf = re.search(r"(\d+) vertices, (\d+) triangles \(([\d.]+) s\)", log)
    vox = re.search(r"depth (\d+), voxel ([\d.e-]+) file units, (\d+) active voxels, .* \(([\d.]+) s: resampling ([\d.]+) s, writing ([\d.]+) s\)", log)
    ours_bytes = os.path.getsize(vdb_path)

    t = time.perf_counter()
    grids, meta = vdb.readAll(vdb_path)
    read_s = time.perf_counter() - t
    peer_path = os.path.join(out, "peer.vdb")
    t = time.perf_counter()
    vdb.write(peer_path, grids=grids)
    peer_s = time.perf_counter() - t
    peer_bytes = os.path.getsize(peer_path)
    return {
        "depth": int(vox.group(1)),
        "voxel": float(vox.group(2)),
        "active": int(vox.group(3)),
        "ours_s": float(vox.group(4)),
        "resample_s": float(vox.group(5)),
        "write_s": float(vox.group(6)),
        "ours_mib": ours_bytes / 2**20,
        "peer_s": peer_s,
        "peer_mib": peer_bytes / 2**20,
        "read_s": read_s,
        "replay_s": replay_s,
        "triangles": int(surf.group(2)),
        "mesh_s": float(surf.group(3)),
        "glb_mib": os.path.getsize(glb_path) / 2**20,
        "wall_s": wall,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--octopaint", default=os.path.join(REPO, "painter", "target", "release", "octopaint"))
    a = ap.parse_args()
    print(f"OpenVDB {vdb.LIBRARY_VERSION}; octopaint {a.octopaint}")
    print(
        "| case | depth | voxel | active voxels | octopaint resample s | octopaint write s | OpenVDB write s | ratio | octopaint MiB | OpenVDB MiB "
        "| OpenVDB read s | triangles | mesh s | glb MiB | replay s | whole command s |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    with tempfile.TemporaryDirectory() as out:
        for name, args in CASES:
            c = run_case(a.octopaint, args, out)
            print(
                f"| {name} | {c['depth']} | {c['voxel']:.3g} | {c['active']:.3g} | {c['resample_s']:.2f} | {c['write_s']:.2f} "
                f"| {c['peer_s']:.2f} | {c['peer_s'] / max(c['write_s'], 1e-3):.2f}x | {c['ours_mib']:.1f} | {c['peer_mib']:.1f} | {c['read_s']:.2f} "
                f"| {c['triangles']:,} | {c['mesh_s']:.2f} | {c['glb_mib']:.1f} | {c['replay_s']:.2f} | {c['wall_s']:.2f} |",
                flush=True,
            )
    print("ratio: OpenVDB's write time over octopaint's (above 1: octopaint writes faster); both write the same grids.")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""What OpenVDB itself reads from a .vdb file, written out as an .npz for
the export tests (conformance/tests/test_export.py).

Runs under Debian's /usr/bin/python3 with python3-openvdb (OpenVDB 10's
own Python module: the file is parsed by libopenvdb, not by us):

    /usr/bin/python3 conformance/vdb_probe.py IN.vdb OUT.npz

For every grid `G` the archive holds `G.items_min`, `G.items_max`
(inclusive index bounds of every active voxel or tile, as OpenVDB's value
iterator yields them), `G.items_value`, `G.meta` (JSON: name, value type,
class, metadata, active voxel count as a decimal string, bounding box,
voxel size, index-to-world of a few points), plus `file_meta` (JSON).
"""

from __future__ import annotations

import json
import sys

import numpy as np
import pyopenvdb as vdb


def probe(path: str) -> dict:
    grids, file_meta = vdb.readAll(path)
    out = {"file_meta": np.array(json.dumps(file_meta, default=str)), "grid_names": np.array(json.dumps([g.name for g in grids]))}
    for g in grids:
        lo, hi, vals = [], [], []
        for item in g.citerOnValues():
            lo.append(item.min)
            hi.append(item.max)
            vals.append(item.value)
        t = g.transform
        points = [(0, 0, 0), (1, 2, 3), (-5, 7, 11)]
        meta = {
            "name": g.name,
            "value_type": g.valueTypeName,
            "class": g.gridClass,
            "metadata": {k: (list(v) if isinstance(v, tuple) else v) for k, v in g.metadata.items()},
            "active_voxels": str(g.activeVoxelCount()),
            "bbox": [list(b) for b in g.evalActiveVoxelBoundingBox()],
            "voxel_size": list(t.voxelSize()),
            "index_to_world": {str(p): list(t.indexToWorld(p)) for p in points},
            "background": g.background if not isinstance(g.background, tuple) else list(g.background),
        }
        out[f"{g.name}.meta"] = np.array(json.dumps(meta, default=str))
        out[f"{g.name}.items_min"] = np.array(lo, np.int64).reshape(-1, 3)
        out[f"{g.name}.items_max"] = np.array(hi, np.int64).reshape(-1, 3)
        out[f"{g.name}.items_value"] = np.array(vals, np.float32)
    return out


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print("usage: vdb_probe.py IN.vdb OUT.npz", file=sys.stderr)
        return 2
    try:
        arrays = probe(argv[1])
    except Exception as e:  # OpenVDB raises IOError, ValueError, RuntimeError...
        print(f"vdb_probe: {argv[1]}: OpenVDB cannot read it: {e}", file=sys.stderr)
        return 1
    np.savez(argv[2], **arrays)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

"""Test data for painter/export/tests/vdb_read.rs, written by OpenVDB itself.

Runs under Debian's /usr/bin/python3 with python3-openvdb (OpenVDB 10):

    /usr/bin/python3 vdb_read_openvdb.py OUT_DIR

writes OUT_DIR/*.vdb with OpenVDB's own writer (its default compression:
the test reads the flags back), then opens each file again with OpenVDB and
prints, as JSON on stdout, what OpenVDB reads: for every grid its type,
class, background, transform at a few points and every active item of
`citerOnValues` (voxels and tiles: min corner, edge, value). It also prints
blosc chunks made by libblosc (the library OpenVDB links) through ctypes,
for the blosc decoder's own test.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import json
import math
import os
import random
import sys

import pyopenvdb as vdb


def scattered_float(name: str) -> vdb.FloatGrid:
    """Scattered voxels, a fill (tiles of 128 and 8, partial leaves) and
    nodes whose inactive values take every value-table mode."""
    g = vdb.FloatGrid(background=0.0)
    g.name = name
    g.gridClass = vdb.GridClass.FOG_VOLUME
    rng = random.Random(7)
    acc = g.getAccessor()
    for _ in range(3000):
        ijk = (rng.randint(-300, 300), rng.randint(-40, 900), rng.randint(-1000, 1000))
        acc.setValueOn(ijk, rng.uniform(0.001, 10.0))
    # A fill that makes a 128³ tile, 8³ tiles and partial leaves.
    g.fill((256, 0, 0), (256 + 135, 129, 127), 0.75, True)
    g.transform = vdb.createLinearTransform(voxelSize=0.25)
    return g


def modes(name: str) -> vdb.FloatGrid:
    """Background 2: leaves whose inactive values are +bg, -bg, one other
    value, -bg and +bg mixed, bg and one other, two others, three others:
    io::writeCompressedValues picks modes 0 to 6 for them."""
    g = vdb.FloatGrid(background=2.0)
    g.name = name
    acc = g.getAccessor()
    cases = [[], [-2.0], [5.0], [-2.0, 2.0], [2.0, 5.0], [5.0, 6.0], [5.0, 6.0, 7.0]]
    for k, inactive in enumerate(cases):
        base = (64 * k, 8, -16)
        # Every voxel of the leaf touched, so its values are what we set.
        for i in range(8):
            for j in range(8):
                for l in range(8):
                    ijk = (base[0] + i, base[1] + j, base[2] + l)
                    n = i * 64 + j * 8 + l
                    if n % 3 == 0:
                        acc.setValueOn(ijk, 0.5 + n)
                    elif inactive:
                        acc.setValueOff(ijk, inactive[n % len(inactive)])
    # A leaf with no active value at all (it only holds inactive values).
    for i in range(8):
        acc.setValueOff((800 + i, 0, 0), 9.0)
    # Internal-node tables with active tiles next to inactive ones.
    g.fill((-4096, 0, 0), (-4096 + 127, 127, 127), 3.5, True)
    g.fill((-4096 + 256, 0, 0), (-4096 + 263, 7, 7), 4.5, True)
    t = vdb.createLinearTransform(voxelSize=0.5)
    t.translate((1.0, -2.0, 3.5))
    g.transform = t
    return g


def colours(name: str, half: bool) -> vdb.Vec3SGrid:
    g = vdb.Vec3SGrid()
    g.name = name
    rng = random.Random(11)
    acc = g.getAccessor()
    for _ in range(2000):
        ijk = (rng.randint(-100, 100), rng.randint(-100, 100), rng.randint(-100, 100))
        acc.setValueOn(ijk, (rng.uniform(0, 1), rng.uniform(-5, 5), rng.uniform(100, 3000)))
    g.fill((0, 0, 0), (15, 15, 15), (0.25, 0.5, 0.125), True)
    g.saveFloatAsHalf = half
    g.transform = vdb.createLinearTransform(voxelSize=0.1)
    return g


def items(g) -> list:
    out = []
    for it in g.citerOnValues():
        lo, hi = it.min, it.max
        edge = hi[0] - lo[0] + 1
        v = it.value
        out.append(list(lo) + [edge] + (list(v) if isinstance(v, tuple) else [v]))
    return out


def report(path: str) -> dict:
    grids, _meta = vdb.readAll(path)
    out = {}
    for g in grids:
        t = g.transform
        pts = [(0, 0, 0), (1, 2, 3), (-5, 7, 11)]
        bg = g.background
        out[g.name] = {
            "value_type": g.valueTypeName,
            "class": g.gridClass,
            "half": bool(g.saveFloatAsHalf),
            "background": list(bg) if isinstance(bg, tuple) else [bg],
            "index_to_world": [[list(p), list(t.indexToWorld(p))] for p in pts],
            "items": items(g),
        }
    return out


def blosc_chunks() -> list:
    """Chunks from libblosc: compressor × shuffle × type size × sizes."""
    lib = ctypes.CDLL(ctypes.util.find_library("blosc") or "libblosc.so.1")
    lib.blosc_compress_ctx.restype = ctypes.c_int
    lib.blosc_compress_ctx.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_size_t, ctypes.c_size_t,
                                       ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_char_p,
                                       ctypes.c_size_t, ctypes.c_int]
    rng = random.Random(3)
    datas = {
        "floats": b"".join(int(1000 * math.sin(i * 0.01)).to_bytes(4, "little", signed=True) for i in range(4096)),
        "sparse": bytes(rng.choice([0, 0, 0, 0, 7, 200]) for _ in range(6000)),
        "random": bytes(rng.randrange(256) for _ in range(3000)),
        "runs": bytes([1] * 300 + [2] * 7000 + list(range(256)) * 8),
        "tiny": b"abc",
        "empty": b"",
    }
    chunks = []
    for comp in ["blosclz", "lz4", "lz4hc", "zlib", "zstd"]:
        for name, data in datas.items():
            for shuffle in [0, 1, 2]:
                for typesize in [1, 4, 12]:
                    for blocksize in [0, 256, len(data)]:
                        for clevel in [1, 9]:
                            src = ctypes.create_string_buffer(data, len(data))
                            dest = ctypes.create_string_buffer(len(data) + 16 + 64)
                            n = lib.blosc_compress_ctx(clevel, shuffle, typesize, len(data), src, dest, len(dest),
                                                       comp.encode(), blocksize, 1)
                            if n <= 0:
                                continue
                            chunks.append({"compressor": comp, "data": name, "shuffle": shuffle,
                                           "typesize": typesize, "blocksize": blocksize, "clevel": clevel,
                                           "chunk": dest.raw[:n].hex()})
    return {"data": {k: v.hex() for k, v in datas.items()}, "chunks": chunks}


def main(argv: list[str]) -> int:
    out_dir = argv[1]
    files = {}

    path = os.path.join(out_dir, "float.vdb")
    vdb.write(path, grids=[scattered_float("density")], metadata={"creator": "vdb_read test"})
    files["float.vdb"] = path

    path = os.path.join(out_dir, "modes.vdb")
    vdb.write(path, grids=[modes("modes")])
    files["modes.vdb"] = path

    half_float = scattered_float("density")
    half_float.saveFloatAsHalf = True
    path = os.path.join(out_dir, "half.vdb")
    m = modes("modes_half")
    m.saveFloatAsHalf = True
    vdb.write(path, grids=[half_float, colours("color", True), m])
    files["half.vdb"] = path

    # A vec3 grid, a bool grid (skipped by the reader) and an instance
    # (a shallow copy shares the tree: OpenVDB writes it as an instance).
    c = colours("color", False)
    inst = c.copy()
    inst.name = "color_instance"
    inst.transform = vdb.createLinearTransform(voxelSize=2.0)
    b = vdb.BoolGrid()
    b.name = "mask"
    b.getAccessor().setValueOn((1, 2, 3), True)
    f = scattered_float("density")
    path = os.path.join(out_dir, "vec3.vdb")
    vdb.write(path, grids=[c, b, f, inst])
    files["vec3.vdb"] = path

    # A root tile (4096³) and nothing else.
    g = vdb.FloatGrid()
    g.name = "big"
    g.fill((-4096, 0, 0), (-1, 4095, 4095), 1.5, True)
    path = os.path.join(out_dir, "root_tile.vdb")
    vdb.write(path, grids=[g])
    files["root_tile.vdb"] = path

    # A rotated transform (an AffineMap): refused.
    g = vdb.FloatGrid()
    g.name = "turned"
    g.getAccessor().setValueOn((0, 0, 0), 1.0)
    t = vdb.createLinearTransform(voxelSize=1.0)
    t.rotate(0.5, vdb.Axis.Y)
    g.transform = t
    path = os.path.join(out_dir, "affine.vdb")
    vdb.write(path, grids=[g])
    files["affine.vdb"] = path

    # One small grid, for the truncation and corruption sweeps.
    g = vdb.FloatGrid()
    g.name = "small"
    acc = g.getAccessor()
    for k in range(40):
        acc.setValueOn((k * 3, k % 7, -k), 0.1 * k + 0.05)
    g.fill((64, 0, 0), (79, 7, 7), 2.0, True)
    h = vdb.Vec3SGrid()
    h.name = "small_color"
    h.getAccessor().setValueOn((5, 5, 5), (1.0, 2.0, 3.0))
    h.saveFloatAsHalf = True
    path = os.path.join(out_dir, "small.vdb")
    vdb.write(path, grids=[g, h])
    files["small.vdb"] = path

    report_all = {name: report(p) for name, p in files.items() if name != "affine.vdb"}
    print(json.dumps({"library": list(vdb.LIBRARY_VERSION), "files": report_all, "blosc": blosc_chunks()}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

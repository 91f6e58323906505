"""Exports read by their own ecosystems' readers.

- OpenVDB: the painter's .vdb files are opened by OpenVDB 10 itself
  (Debian's python3-openvdb, run under /usr/bin/python3 by
  conformance/vdb_probe.py) and every active voxel and tile it reports is
  compared with the regions the reference exports from the same tree
  (`octopaint-ref export`, an independent numpy implementation).
- glTF and OBJ: read by trimesh (its own glTF and OBJ loaders), which must
  find a watertight, consistently wound mesh with positive volume and the
  vertex colours written.
- USD: the painter's .usda stage is opened by Pixar's own library
  (usd-core's `pxr`): units, up axis, the Volume's fields pointing at the
  grids of the .vdb beside it (OpenVDB lists them), the Mesh's points,
  faces, normals and displayColor against the OBJ of the same export.
- Refusals: exit status 2, a message that says what to do, and no file
  written or changed.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO

SYSTEM_PYTHON = "/usr/bin/python3"
PROBE = os.path.join(REPO, "conformance", "vdb_probe.py")
TRACES = os.path.join(REPO, "traces")
REF = [sys.executable, "-m", "octopaint_ref.cli"]

# VDB's tile edges, in voxels, from the root down: a region of edge 2^k is
# written as tiles of the largest edge not above it.
TILE_LOG2 = (12, 7, 3, 0)


def run(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


@pytest.fixture(scope="module")
def openvdb():
    """Debian's OpenVDB module; `make setup` installs python3-openvdb."""
    r = run([SYSTEM_PYTHON, "-c", "import pyopenvdb, numpy; print(pyopenvdb.LIBRARY_VERSION)"])
    if r.returncode != 0:
        raise RuntimeError(f"python3-openvdb is missing (make system installs it): {r.stderr.strip()}")
    return r.stdout.strip()


@pytest.fixture(scope="module")
def dumps(painter, tmp_path_factory):
    """name -> (trace, what the reference exports from): the painter's tree
    dump at the trace's last snapshot (byte-identical to the reference's by
    the conformance suite) where that is the final tree, else the trace
    (edges.jsonl ends inside a stroke, which the replay then ends)."""
    out = tmp_path_factory.mktemp("dumps")
    found = {}
    for name in ("shapes_modes", "edges", "scene"):
        trace = os.path.join(TRACES, f"{name}.jsonl")
        r = run([painter, "replay", trace, "--out", str(out / name), "--renderer", "none", "--quiet"])
        assert r.returncode == 0, r.stderr
        last = None
        with open(trace) as f:
            for line in f:
                if '"snapshot"' in line:
                    last = json.loads(line)["name"]
        found[name] = (trace, trace if name == "edges" else str(out / name / f"{last}.npz"))
    return found


def probe(vdb_path, tmp_path):
    out = tmp_path / "probe.npz"
    r = run([SYSTEM_PYTHON, PROBE, str(vdb_path), str(out)])
    assert r.returncode == 0, r.stderr
    a = np.load(out)
    grids = {}
    for name in json.loads(str(a["grid_names"])):
        grids[name] = {
            "meta": json.loads(str(a[f"{name}.meta"])),
            "min": a[f"{name}.items_min"],
            "max": a[f"{name}.items_max"],
            "value": a[f"{name}.items_value"],
        }
    return json.loads(str(a["file_meta"])), grids


def reference_regions(dump, depth, colour, tmp_path):
    out = tmp_path / "regions.npz"
    r = run(REF + ["export", dump, "--voxels", str(out), "--depth", str(depth), "--colour", colour, "--quiet"])
    assert r.returncode == 0, r.stderr
    return dict(np.load(out))


def tiles(origin, log2_edge, values, z_up=False, shift=(0, 0, 0)):
    """Regions cut into VDB's tiles and voxels: (min corner, edge, value)
    per piece, with the indices moved by `shift` and the z-up turn (i, j, k)
    -> (i, -1-k-(edge-1), j) of the region applied before cutting."""
    mins, edges, vals = [], [], []
    for k in np.unique(log2_edge):
        sel = log2_edge == k
        o = origin[sel].astype(np.int64) - np.array(shift, np.int64)
        edge = 1 << int(k)
        if z_up:
            o = np.stack([o[:, 0], -(o[:, 2] + edge), o[:, 1]], axis=1)
        step = next(t for t in TILE_LOG2 if t <= k)
        n = 1 << (int(k) - step)
        g = np.arange(n, dtype=np.int64) << step
        off = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
        mins.append((o[:, None, :] + off[None, :, :]).reshape(-1, 3))
        edges.append(np.full(len(o) * len(off), 1 << step, np.int64))
        vals.append(np.repeat(values[sel], len(off), axis=0))
    return np.concatenate(mins), np.concatenate(edges), np.concatenate(vals)


def sort_by_corner(mins, *rest):
    order = np.lexsort((mins[:, 2], mins[:, 1], mins[:, 0]))
    return (mins[order],) + tuple(r[order] for r in rest)


CASES = [
    # (trace, depth, extra options) — depths finer, equal and coarser than
    # the leaves (coarser ones aggregate), both colour spaces, the z-up turn
    # and a scale.
    ("shapes_modes", 7, []),
    ("shapes_modes", 4, ["--colour", "srgb"]),
    ("edges", 8, ["--up", "z", "--scale", "2.5", "--origin", "0.25,0.5,0.75"]),
    ("edges", 5, []),
    ("scene", 12, []),
]


@pytest.mark.parametrize("name,depth,extra", CASES, ids=[f"{c[0]}-{c[1]}{''.join(c[2][::2])}" for c in CASES])
def test_openvdb_reads_the_reference_regions(openvdb, painter, dumps, tmp_path, name, depth, extra):
    trace, dump = dumps[name]
    vdb_path = tmp_path / f"{name}.vdb"
    r = run([painter, "export", trace, "--vdb", str(vdb_path), "--depth", str(depth), "--quiet"] + extra)
    assert r.returncode == 0, r.stderr
    assert oct(os.stat(vdb_path).st_mode & 0o777) == "0o644"
    colour = extra[extra.index("--colour") + 1] if "--colour" in extra else "linear"
    scale = float(extra[extra.index("--scale") + 1]) if "--scale" in extra else 1.0
    z_up = "--up" in extra
    origin = [float(v) for v in extra[extra.index("--origin") + 1].split(",")] if "--origin" in extra else [0.0] * 3
    ref = reference_regions(dump, depth, colour, tmp_path)
    file_meta, grids = probe(vdb_path, tmp_path)
    assert set(grids) == {"density", "color"}
    assert file_meta["creator"].startswith("octopaint")

    h_canvas = float(ref["voxel_size"])
    h = h_canvas * scale
    # Indices move by whole 4096-voxel nodes toward the origin; the rest of
    # the origin is the transform's translation, turned and scaled.
    shift = [int(np.floor(o / h_canvas / 4096)) * 4096 for o in origin]
    rest = [(shift[a] * h_canvas - origin[a]) * scale for a in range(3)]
    translation = [rest[0], -rest[2], rest[1]] if z_up else rest
    expected_voxels = int(sum(8 ** int(k) for k in ref["log2_edge"]))
    for g, value_type, cls in (("density", "float", "fog volume"), ("color", "vec3s", "unknown")):
        m = grids[g]["meta"]
        assert m["value_type"] == value_type and m["class"] == cls
        assert int(m["active_voxels"]) == expected_voxels
        assert m["voxel_size"] == pytest.approx([h] * 3, rel=1e-15)
        # Index i is the centre of the voxel covering [i, i+1)·h.
        for p, w in m["index_to_world"].items():
            ijk = [int(v) for v in p.strip("()").split(",")]
            want = [(c + 0.5) * h + t for c, t in zip(ijk, translation)]
            assert w == pytest.approx(want, rel=1e-14, abs=1e-14 * h)
    assert grids["color"]["meta"]["metadata"]["vector_type"] == "invariant"

    # Every piece OpenVDB reports is a reference region's piece, same value.
    dens = ref["density"] / np.float32(scale) if scale != 1.0 else ref["density"]
    mins, edges, dvals = tiles(ref["origin"], ref["log2_edge"], dens, z_up, shift)
    _, _, cvals = tiles(ref["origin"], ref["log2_edge"], ref["color"], z_up, shift)
    mins, edges, dvals, cvals = sort_by_corner(mins, edges, dvals, cvals)
    for g, want in (("density", dvals), ("color", cvals)):
        got = grids[g]
        gmin, gedge, gval = sort_by_corner(got["min"], got["max"][:, 0] - got["min"][:, 0] + 1, got["value"])
        assert len(gmin) == len(mins), f"{g}: OpenVDB sees {len(gmin)} voxels and tiles, the reference {len(mins)}"
        np.testing.assert_array_equal(gmin, mins)
        np.testing.assert_array_equal(gedge, edges)
        if g == "density" and scale == 1.0:
            # Aggregates are summed in the same order on both sides (the
            # reference follows the painter's walk): bit-equal.
            np.testing.assert_array_equal(gval, want)
        else:
            # Linear colours: numpy's ** and Rust's powf may round the last
            # f64 bit differently, a rare 1-ulp f32 difference; scaled
            # densities divide in f64 (painter) versus f32 (here).
            np.testing.assert_allclose(gval, want, rtol=2.5e-7, atol=0)


def test_the_default_depth_fits_the_cap(openvdb, painter, dumps, tmp_path):
    trace, _ = dumps["scene"]
    plan = run([painter, "export", trace, "--plan", "--max-mib", "64"])
    assert plan.returncode == 0, plan.stderr
    rows = [line.split() for line in plan.stdout.splitlines()[1:]]
    chosen = [int(r[0]) for r in rows if "<-" in r]
    assert len(chosen) == 1
    assert chosen[0] == max(int(r[0]) for r in rows if r[5] != "over")
    out = tmp_path / "scene.vdb"
    r = run([painter, "export", trace, "--vdb", str(out), "--max-mib", "64"])
    assert r.returncode == 0, r.stderr
    assert f"depth {chosen[0]}," in r.stderr
    _, grids = probe(out, tmp_path)
    assert len(grids["density"]["min"]) > 0


def mesh_check(path):
    import trimesh

    # process=False: the vertices as written (they are shared already).
    loaded = trimesh.load(str(path), process=False)
    if isinstance(loaded, trimesh.Scene):
        # glTF: one node carrying the translation, one mesh.
        (node,) = loaded.graph.nodes_geometry
        transform, name = loaded.graph[node]
        m = loaded.geometry[name]
        visual = m.visual
        m = m.copy()
        m.apply_transform(transform)
    else:
        visual = loaded.visual
        m = loaded
    assert len(m.faces) > 0
    assert m.is_watertight, f"{path}: trimesh finds holes"
    assert m.is_winding_consistent, f"{path}: inconsistent winding"
    assert m.volume > 0, f"{path}: normals point in (volume {m.volume})"
    # trimesh keeps COLOR_0 beside a material as a vertex attribute.
    colours = visual.vertex_colors if hasattr(visual, "vertex_colors") else visual.vertex_attributes["color"]
    colours = np.asarray(colours)
    assert colours.shape[0] == len(m.vertices) and len(np.unique(colours[:, :3], axis=0)) > 1
    return m


@pytest.mark.parametrize("name,extra", [("shapes_modes", []), ("edges", ["--iso", "0.05"]), ("scene", ["--region", "19999.6,19999.7,19999.5,20000.6,20000.5,20000.3"])])
def test_meshes_read_back_closed(painter, dumps, tmp_path, name, extra):
    trace, _ = dumps[name]
    glb, obj = tmp_path / f"{name}.glb", tmp_path / f"{name}.obj"
    r = run([painter, "export", trace, "--gltf", str(glb), "--obj", str(obj)] + extra)
    assert r.returncode == 0, r.stderr
    g = mesh_check(glb)
    o = mesh_check(obj)
    # Same surface through both formats: same volume and bounds, to f32.
    assert g.volume == pytest.approx(o.volume, rel=1e-4)
    np.testing.assert_allclose(g.bounds, o.bounds, rtol=1e-5, atol=1e-5 * np.abs(o.bounds).max())
    # The glb is valid glTF for a second reader: its JSON chunk parses, the
    # sizes add up, COLOR_0 is float VEC3 (linear, as glTF defines).
    data = glb.read_bytes()
    assert data[:4] == b"glTF" and int.from_bytes(data[8:12], "little") == len(data)
    jlen = int.from_bytes(data[12:16], "little")
    doc = json.loads(data[20 : 20 + jlen])
    prim = doc["meshes"][0]["primitives"][0]
    col = doc["accessors"][prim["attributes"]["COLOR_0"]]
    assert col["type"] == "VEC3" and col["componentType"] == 5126
    assert doc["asset"]["version"] == "2.0"


def test_usd_stages_open_in_pixars_library(openvdb, painter, dumps, tmp_path):
    from pxr import Usd, UsdGeom, UsdVol

    trace, _ = dumps["shapes_modes"]
    stage_path, obj = tmp_path / "p.usda", tmp_path / "p.obj"
    r = run([painter, "export", trace, "--usd", str(stage_path), "--usd-mesh", "--obj", str(obj), "--up", "z", "--scale", "100", "--quiet"])
    assert r.returncode == 0, r.stderr
    vdb = tmp_path / "p.vdb"
    assert vdb.is_file(), "the stage's VDB is written beside it"
    stage = Usd.Stage.Open(str(stage_path))
    assert stage.GetDefaultPrim().GetPath() == "/Painting"
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)  # --scale 100: centimetres
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    volume = UsdVol.Volume(stage.GetPrimAtPath("/Painting/Volume"))
    assert volume, "no Volume prim"
    fields = volume.GetFieldPaths()
    assert sorted(fields) == ["color", "density"]
    for name, path in fields.items():
        asset = UsdVol.OpenVDBAsset(stage.GetPrimAtPath(path))
        assert asset, f"{path} is not an OpenVDBAsset"
        assert asset.GetFieldNameAttr().Get() == name
        assert os.path.samefile(asset.GetFilePathAttr().Get().resolvedPath, vdb)
    # OpenVDB itself finds those grids in the file.
    r = run([SYSTEM_PYTHON, "-c", "import sys, pyopenvdb; print(' '.join(sorted(g.name for g in pyopenvdb.readAllGridMetadata(sys.argv[1]))))", str(vdb)])
    assert r.returncode == 0 and r.stdout.split() == ["color", "density"], r.stderr
    # The surface: the OBJ's vertices and triangles, one colour and normal
    # per vertex, inside the volume's extent.
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Painting/Surface"))
    points = np.asarray(mesh.GetPointsAttr().Get())
    lines = obj.read_text().splitlines()
    obj_v = np.array([[float(x) for x in l.split()[1:4]] for l in lines if l.startswith("v ")])
    n_faces = sum(1 for l in lines if l.startswith("f "))
    assert points.shape == obj_v.shape and np.allclose(points, obj_v, rtol=1e-6, atol=1e-6 * np.abs(obj_v).max())
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    assert len(counts) == n_faces and np.all(counts == 3)
    assert len(mesh.GetFaceVertexIndicesAttr().Get()) == 3 * n_faces
    assert len(mesh.GetNormalsAttr().Get()) == len(points) and mesh.GetNormalsInterpolation() == UsdGeom.Tokens.vertex
    colour = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor")
    values = np.asarray(colour.Get())
    assert colour.GetInterpolation() == UsdGeom.Tokens.vertex and values.shape == points.shape
    assert values.min() >= 0 and values.max() <= 1 and len(np.unique(values, axis=0)) > 1
    computed = np.asarray(UsdGeom.Boundable.ComputeExtentFromPlugins(mesh, Usd.TimeCode.Default()))
    assert np.allclose(np.asarray(mesh.GetExtentAttr().Get()), computed)
    box = np.asarray(volume.GetExtentAttr().Get())
    assert np.all(box[0] <= computed[0] + 1e-3) and np.all(computed[1] <= box[1] + 1e-3), (box, computed)


def test_refusals_write_nothing(painter, tmp_path):
    trace = os.path.join(TRACES, "shapes_modes.jsonl")
    keep = tmp_path / "keep.vdb"
    keep.write_bytes(b"previous export")
    cases = [
        (["--vdb", str(keep), "--depth", "99"], "export depth 99 is out of range: this canvas goes from depth 0 to 7"),
        (["--vdb", str(keep), "--depth", "7", "--max-mib", "1"], "--depth"),
        (["--vdb", str(keep), "--gltf", str(tmp_path / "m.glb"), "--max-triangles", "10"], "more than 10 triangles"),
        (["--gltf", str(tmp_path / "m.glb"), "--iso", "nan"], "--iso NaN must be a positive extinction"),
        (["--gltf", str(tmp_path / "m.glb"), "--iso", "-1"], "--iso -1 must be a positive extinction"),
        (["--vdb", str(keep), "--region", "1,2,3"], "expected 6 numbers"),
        (["--vdb", str(keep), "--region", "5,5,5,6,6,6"], "--region misses the canvas"),
        (["--vdb", str(keep), "--scale", "inf"], "--scale inf is not in"),
        (["--vdb", str(keep), "--origin", "5,5,5"], "--origin 5,5,5 is off the canvas"),
        (["--vdb", str(keep), "--origin", "1,nan,1"], "the point must be finite"),
        (["--vdb", str(keep), "--obj", str(keep)], "is given as two outputs"),
        ([], "nothing to write"),
        (["--vdb", str(tmp_path)], "is a folder"),
        (["--gltf", str(tmp_path / "m.glb"), "--depth", "3"], "--depth is the VDB's voxel depth"),
        (["--usd", str(tmp_path / "s.usdc")], "only USD's text format is written (.usda)"),
        (["--usd", str(tmp_path / "s.txt")], "a USD stage is written as .usda"),
        (["--usd", str(tmp_path / "s.usda"), "--vdb", str(tmp_path / "sub" / "s.vdb")], "is not in the folder of --usd"),
        (["--usd", str(tmp_path / "keep.usda"), "--obj", str(tmp_path / "keep.vdb")], "is given as two outputs"),
        (["--usd-mesh", "--obj", str(tmp_path / "m.obj")], "--usd"),
    ]
    for args, message in cases:
        r = run([painter, "export", trace] + args)
        assert r.returncode == 2, (args, r.returncode, r.stderr)
        assert message in r.stderr, (args, r.stderr)
        assert "octopaint: export: " in r.stderr or "error:" in r.stderr, r.stderr
    assert keep.read_bytes() == b"previous export"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.vdb"]
    # A malformed trace: the reader's message, exit 2, nothing written.
    bad = tmp_path / "bad.jsonl"
    first = sorted(f for f in os.listdir(os.path.join(TRACES, "malformed")) if f.endswith(".jsonl"))[0]
    shutil.copy(os.path.join(TRACES, "malformed", first), bad)
    r = run([painter, "export", str(bad), "--vdb", str(keep)])
    assert r.returncode == 2 and str(bad) in r.stderr, r.stderr
    assert keep.read_bytes() == b"previous export"
    # An unwritable folder: exit 1, the reason.
    r = run([painter, "export", trace, "--vdb", str(tmp_path / "missing" / "x.vdb")])
    assert r.returncode == 1 and "cannot write" in r.stderr, r.stderr


def test_a_document_exports_one_pair_of_grids_node_and_prim_per_layer(openvdb, painter, tmp_path):
    """A trace of layers (spec 14): each visible layer becomes the grids
    `NAME.density` and `NAME.color` (its density scaled by its opacity),
    equal voxel for voxel to the reference's export of that layer's tree;
    one glTF node, one OBJ object and one USD Xform (with its Volume and
    Surface) per layer; --layers picks layers by name."""
    from octopaint_ref.dump import dump_bytes, layer_trees, load_dump
    from pxr import Usd, UsdVol

    trace = os.path.join(TRACES, "layers.jsonl")
    r = run([painter, "replay", trace, "--out", str(tmp_path / "replay"), "--renderer", "none", "--quiet"])
    assert r.returncode == 0, r.stderr
    doc = load_dump(str(tmp_path / "replay" / "layers.npz"))  # the last snapshot: the final document
    names = [bytes(row[row != 0]).decode() for row in doc["layer_names"]]
    shown = [n for n, v, o in zip(names, doc["layer_visible"], doc["layer_opacity"]) if v and o > 0]
    assert shown == ["ground haze", "Layer 1"]
    out = {k: tmp_path / f"d.{k}" for k in ("vdb", "glb", "obj", "usda")}
    r = run([painter, "export", trace, "--vdb", str(out["vdb"]), "--depth", "7", "--gltf", str(out["glb"]), "--obj", str(out["obj"]), "--quiet"])
    assert r.returncode == 0, r.stderr
    _, grids = probe(out["vdb"], tmp_path)
    assert set(grids) == {f"{n}.{g}" for n in shown for g in ("density", "color")}
    trees = layer_trees(doc)
    for name in shown:
        k = names.index(name)
        single = tmp_path / f"layer{k}.npz"
        single.write_bytes(dump_bytes(trees[k]))
        ref = reference_regions(str(single), 7, "linear", tmp_path)
        opacity = np.float64(doc["layer_opacity"][k])
        dens = (ref["density"].astype(np.float64) * opacity).astype(np.float32) if opacity != 1.0 else ref["density"]
        mins, edges, dvals = tiles(ref["origin"], ref["log2_edge"], dens, False, [0, 0, 0])
        _, _, cvals = tiles(ref["origin"], ref["log2_edge"], ref["color"], False, [0, 0, 0])
        mins, edges, dvals, cvals = sort_by_corner(mins, edges, dvals, cvals)
        for g, want in (("density", dvals), ("color", cvals)):
            got = grids[f"{name}.{g}"]
            gmin, gedge, gval = sort_by_corner(got["min"], got["max"][:, 0] - got["min"][:, 0] + 1, got["value"])
            np.testing.assert_array_equal(gmin, mins)
            np.testing.assert_array_equal(gedge, edges)
            np.testing.assert_allclose(gval, want, rtol=2.5e-7, atol=0)
    # glTF: a node and a mesh per layer, named after it; OBJ: an object per layer.
    data = out["glb"].read_bytes()
    jlen = int.from_bytes(data[12:16], "little")
    gl = json.loads(data[20 : 20 + jlen])
    assert [n["name"] for n in gl["nodes"]] == shown and len(gl["meshes"]) == 2
    objects = [l[2:] for l in out["obj"].read_text().splitlines() if l.startswith("o ")]
    assert objects == shown
    # USD, with --layers choosing one layer (a hidden one may be named).
    r = run([painter, "export", trace, "--usd", str(out["usda"]), "--usd-mesh", "--layers", "Layer 1,detail copy", "--quiet"])
    assert r.returncode == 0, r.stderr
    stage = Usd.Stage.Open(str(out["usda"]))
    kids = [p.GetName() for p in stage.GetPrimAtPath("/Painting").GetChildren()]
    assert kids == ["Layer_1", "detail_copy"]
    for prim, name in (("Layer_1", "Layer 1"), ("detail_copy", "detail copy")):
        volume = UsdVol.Volume(stage.GetPrimAtPath(f"/Painting/{prim}/Volume"))
        assert volume and stage.GetPrimAtPath(f"/Painting/{prim}/Surface").IsValid()
        fields = volume.GetFieldPaths()
        for field, path in fields.items():
            asset = UsdVol.OpenVDBAsset(stage.GetPrimAtPath(path))
            assert asset.GetFieldNameAttr().Get() == f"{name}.{field}"
    # Names that are not layers, and --layers on a painting, are refused.
    for extra, what in ((["--layers", "nope"], "no layer named"), (["--layers", "Layer 1,Layer 1"], "twice")):
        r = run([painter, "export", trace, "--vdb", str(tmp_path / "x.vdb")] + extra)
        assert r.returncode == 2 and what in r.stderr, r.stderr
    r = run([painter, "export", os.path.join(TRACES, "single_stamp.jsonl"), "--vdb", str(tmp_path / "x.vdb"), "--layers", "a"])
    assert r.returncode == 2 and "not a document of layers" in r.stderr, r.stderr
    assert not (tmp_path / "x.vdb").exists()

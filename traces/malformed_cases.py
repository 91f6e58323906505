"""The malformed traces (traces/malformed/): each file's lines and the line
and kind of error both readers must give (docs/spec.md 12.2), and the bad
voxel sets some of them name. Used by generate.py, which writes them and
malformed/expected.json."""

from __future__ import annotations

import hashlib
import json

from voxel_files import voxel_set

H = '{"format": "ddo-trace", "version": 1, "canvas": {"roots": [1, 1, 1], "max_depth": 6, "root_size": 1.0, "capacity": 4096}}'
BR = '{"ev": "brush", "t": 0, "shape": "sphere", "mode": "paint", "radius": 0.1, "color": [1, 0, 0], "opacity": 1, "hardness": 0.5}'
SB = '{"ev": "stroke_begin", "t": 0}'
SE = '{"ev": "stroke_end", "t": 0}'
SA = '{"ev": "sample", "t": 0, "p": [0.5, 0.5, 0.5]}'
CAM = '{"ev": "camera", "t": 0, "eye": [0.5, 0.5, 2], "q": [0, 0, 0, 1], "fov": [-0.5, 0.5, 0.4, -0.4], "size": [64, 48]}'


H2 = H.replace('"version": 1', '"version": 2')


def _layer(**kw):
    return json.dumps({"ev": "layer", "t": 0, **kw})


def _brush(**over):
    b = json.loads(BR)
    b.update(over)
    return json.dumps(b)


def _cam(**over):
    c = json.loads(CAM)
    c.update(over)
    return json.dumps(c)


def _hdr(**canvas):
    h = json.loads(H)
    h["canvas"].update(canvas)
    return json.dumps(h)


# name: (lines, the line and the kind of error both readers must give: spec 12.2)
MALFORMED = {
    "empty": ([], 1, "header"),
    "not_json": ([H, '{"ev": "brush", "t": 0,'], 2, "json"),
    "not_object": ([H, "[1, 2, 3]"], 2, "type"),
    "no_header": ([BR], 1, "header"),
    "wrong_version": ([H.replace('"version": 1', '"version": 1.5')], 1, "header"),
    "max_depth_too_deep": ([_hdr(max_depth=29)], 1, "range"),
    "lattice_overflow": ([_hdr(roots=[32, 1, 1], max_depth=28)], 1, "range"),
    "capacity_below_roots": ([_hdr(roots=[4, 4, 4], capacity=32)], 1, "budget"),
    "too_many_roots": ([_hdr(roots=[1024, 1024, 32], max_depth=6, capacity=40000000)], 1, "budget"),
    "canvas_missing_roots": (['{"format": "ddo-trace", "version": 1, "canvas": {"max_depth": 6, "root_size": 1.0, "capacity": 4096}}'],
                             1, "missing"),
    "huge_integer": ([H, '{"ev": "undo", "t": 1' + "0" * 400 + '}'], 2, "json"),
    "unknown_event": ([H, '{"ev": "paint", "t": 0}'], 2, "event"),
    "missing_t": ([H, '{"ev": "undo"}'], 2, "missing"),
    "time_backwards": ([H, BR.replace('"t": 0', '"t": 2'), SB.replace('"t": 0', '"t": 1')], 3, "event-order"),
    "unknown_shape": ([H, _brush(shape="star")], 2, "range"),
    "unknown_mode": ([H, _brush(mode="smudge")], 2, "range"),
    "radius_zero": ([H, _brush(radius=0)], 2, "range"),
    "radius_string": ([H, _brush(radius="big")], 2, "type"),
    "color_out_of_range": ([H, _brush(color=[1.5, 0, 0])], 2, "range"),
    "color_short": ([H, _brush(color=[1, 0])], 2, "type"),
    "opacity_out_of_range": ([H, _brush(opacity=-0.1)], 2, "range"),
    "spacing_absurd": ([H, _brush(spacing=1e-9)], 2, "range"),
    "noise_octaves": ([H, _brush(shape="noise", noise={"octaves": 40})], 2, "range"),
    "nan_sample": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [NaN, 0, 0]}'], 4, "json"),
    "infinite_sample": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 1e999, 0]}'], 4, "json"),
    "zero_quaternion": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 0, 0], "q": [0, 0, 0, 0]}'], 4, "range"),
    "pressure_out_of_range": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 0, 0], "pressure": 2}'], 4, "range"),
    "sample_missing_p": ([H, BR, SB, '{"ev": "sample", "t": 0}'], 4, "missing"),
    "sample_outside_stroke": ([H, BR, SA], 3, "event-order"),
    "stroke_in_stroke": ([H, BR, SB, SA, SB], 5, "event-order"),
    "stroke_without_brush": ([H, SB], 2, "event-order"),
    "brush_in_stroke": ([H, BR, SB, BR], 4, "event-order"),
    "end_outside_stroke": ([H, SE], 2, "event-order"),
    "absurd_segment": ([H, _brush(shape="box", radius=1e-6), SB, SA, '{"ev": "sample", "t": 0, "p": [0.9, 0.5, 0.5]}'],
                       5, "budget"),
    "undo_nothing": ([H, '{"ev": "undo", "t": 0}'], 2, "event-order"),
    "redo_nothing": ([H, BR, SB, SA, SE, '{"ev": "redo", "t": 0}'], 6, "event-order"),
    "undo_in_stroke": ([H, BR, SB, '{"ev": "undo", "t": 0}'], 4, "event-order"),
    "fov_unordered": ([H, _cam(fov=[0.5, -0.5, 0.4, -0.4])], 2, "range"),
    "fov_too_wide": ([H, _cam(fov=[-2.0, 0.5, 0.4, -0.4])], 2, "range"),
    "size_zero": ([H, _cam(size=[0, 48])], 2, "range"),
    "size_huge": ([H, _cam(size=[64, 100000])], 2, "range"),
    "render_before_camera": ([H, '{"ev": "render", "t": 0, "name": "x"}'], 2, "event-order"),
    "name_traversal": ([H, '{"ev": "snapshot", "t": 0, "name": "../../etc/passwd"}'],
                       2, "name"),
    "name_dotdot": ([H, '{"ev": "snapshot", "t": 0, "name": ".."}'], 2, "name"),
    "name_duplicate": ([H, '{"ev": "snapshot", "t": 0, "name": "a"}', '{"ev": "snapshot", "t": 0, "name": "a"}'],
                       3, "name"),
    "name_newline": ([H, '{"ev": "snapshot", "t": 0, "name": "a\\n"}'], 2, "name"),
    "deep_nesting": ([H, '{"ev": "undo", "t": 0, "x": ' + "[" * 65 + "]" * 65 + "}"],
                     2, "json"),
    "long_integer": ([H, '{"ev": "undo", "t": ' + "1" * 4301 + "}"],
                     2, "json"),
    "overflowing_segment": ([H, _brush(shape="cone", radius=1e-300), SB, '{"ev": "sample", "t": 0, "p": [1e308, 0, 0]}',
                             '{"ev": "sample", "t": 0, "p": [-1e308, 0, 0]}'],
                            5, "budget"),
    "integral_float_too_big": ([_hdr(max_depth=1e300)],
                               1, "range"),
    "version_string": ([H.replace('"version": 1', '"version": "1"')], 1, "header"),
    "lone_surrogate_event": ([H, '{"ev": "\\ud800", "t": 0}'], 2, "json"),
    "infinity_literal": ([H, '{"ev": "undo", "t": Infinity}'], 2, "json"),
    "integer_beyond_f64": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 0, 2' + "0" * 308 + ']}'], 4, "json"),
    "float_beyond_f64": ([H, BR, SB, '{"ev": "sample", "t": 0, "p": [0, 0, 1.8e308]}'], 4, "json"),
    "lone_surrogate_key": ([H, '{"ev": "undo", "t": 0, "\\udc00": 1}'], 2, "json"),
    "bom": (["\ufeff" + H], 1, "json"),
    "light_dir_zero": ([H, '{"ev": "light", "t": 0, "dir": [0, 0, 0]}'], 2, "range"),
    "light_missing_dir": ([H, '{"ev": "light", "t": 0, "intensity": 1}'], 2, "missing"),
    "light_on_string": ([H, '{"ev": "light", "t": 0, "on": "yes", "dir": [0, 1, 0]}'], 2, "type"),
    "light_intensity_absurd": ([H, '{"ev": "light", "t": 0, "dir": [0, 1, 0], "intensity": 1e9}'], 2, "range"),
    "light_shadows_number": ([H, '{"ev": "light", "t": 0, "dir": [0, 1, 0], "shadows": 1}'], 2, "type"),
    "mirror_in_stroke": ([H, BR, SB, SA, '{"ev": "mirror", "t": 0, "axes": [true, false, false], "centre": [0, 0, 0]}'], 5, "event-order"),
    "mirror_axes_short": ([H, '{"ev": "mirror", "t": 0, "axes": [true, false], "centre": [0, 0, 0]}'], 2, "type"),
    "mirror_axes_number": ([H, '{"ev": "mirror", "t": 0, "axes": [1, 0, 0], "centre": [0, 0, 0]}'], 2, "type"),
    "mirror_missing_centre": ([H, '{"ev": "mirror", "t": 0, "axes": [true, false, false]}'], 2, "missing"),
    "mirror_missing_axes": ([H, '{"ev": "mirror", "t": 0, "centre": [0, 0, 0]}'], 2, "missing"),
    "light_dir_overflow": ([H, '{"ev": "light", "t": 0, "dir": [1e200, 1e200, 0]}'], 2, "range"),
    "version_three": ([H.replace('"version": 1', '"version": 3')], 1, "header"),
    "layer_in_version_1": ([H, _layer(op="add", name="a")], 2, "event"),
    "layer_unknown": ([H2, _layer(op="select", layer="nope")], 2, "layer"),
    "layer_delete_only": ([H2, _layer(op="delete", layer="Layer 1")], 2, "layer"),
    "layer_paint_locked": ([H2, _layer(op="set", layer="Layer 1", locked=True), BR, SB, SA, SE], 4, "layer"),
    "layer_name_taken": ([H2, _layer(op="add", name="Layer 1")], 2, "layer"),
    "layer_name_control": ([H2, _layer(op="add", name="a\u0001b")], 2, "range"),
    "layer_name_empty": ([H2, _layer(op="add", name="")], 2, "range"),
    "layer_name_long": ([H2, _layer(op="add", name="x" * 65)], 2, "range"),
    "layer_name_number": ([H2, _layer(op="add", name=7)], 2, "type"),
    "layer_op_unknown": ([H2, _layer(op="flip", layer="Layer 1")], 2, "range"),
    "layer_op_number": ([H2, _layer(op=3)], 2, "type"),
    "layer_op_missing": ([H2, _layer(layer="Layer 1")], 2, "missing"),
    "layer_merge_bottom": ([H2, _layer(op="merge_down", layer="Layer 1")], 2, "layer"),
    "layer_merge_locked": ([H2, _layer(op="add", name="a"), _layer(op="set", layer="Layer 1", locked=True),
                            _layer(op="merge_down", layer="a")], 4, "layer"),
    "layer_move_past": ([H2, _layer(op="move", layer="Layer 1", to=1)], 2, "layer"),
    "layer_move_negative": ([H2, _layer(op="move", layer="Layer 1", to=-1)], 2, "range"),
    "layer_set_nothing": ([H2, _layer(op="set", layer="Layer 1")], 2, "missing"),
    "layer_opacity_range": ([H2, _layer(op="set", layer="Layer 1", opacity=2)], 2, "range"),
    "layer_visible_number": ([H2, _layer(op="set", layer="Layer 1", visible=1)], 2, "type"),
    "layer_in_stroke": ([H2, BR, SB, _layer(op="add", name="a")], 4, "event-order"),
    "layer_seventeen": ([H2] + [_layer(op="add", name=f"n{i}") for i in range(16)], 17, "layer"),
    "layer_after_undo": ([H2, _layer(op="add", name="a"), '{"ev": "undo", "t": 0}', _layer(op="select", layer="a")], 4, "layer"),
    "layer_redo_rename": ([H2, _layer(op="rename", layer="Layer 1", name="b"), '{"ev": "undo", "t": 0}',
                           '{"ev": "redo", "t": 0}', _layer(op="select", layer="Layer 1")], 5, "layer"),
    "layer_undo_select": ([H2, _layer(op="select", layer="Layer 1"), '{"ev": "undo", "t": 0}'], 3, "event-order"),
}

# Malformed imports: the voxel files live in traces/malformed/imports/.
_GOOD = voxel_set(2, [(1, 1, 1, 200, 10, 10, 3.0), (2, 1, 1, 10, 200, 10, 3.0)])
MALFORMED_FILES = {
    "imports/good.npz": _GOOD,
    "imports/deep.npz": voxel_set(7, [(1, 1, 1, 200, 10, 10, 3.0)]),
    "imports/outside.npz": voxel_set(2, [(4, 0, 0, 200, 10, 10, 3.0)]),
    "imports/twice.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, 3.0), (0, 0, 0, 1, 2, 3, 1.0), (1, 1, 1, 1, 2, 3, 1.0)]),
    "imports/nan.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, float("nan"))]),
    "imports/minus_zero.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, -0.0)]),
    "imports/negative.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, -1.0)]),
    "imports/compressed.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, 3.0)], compress=True),
    "imports/wide.npz": voxel_set(2, [(1, 1, 1, 200, 10, 10, 3.0)], ijk_descr="<i8"),
    "imports/not_zip.npz": b"ijk rgb sigma\n",
}


def _import(file="imports/good.npz", sha=None, **kw):
    data = MALFORMED_FILES.get(file, b"")
    return json.dumps({"ev": "import", "t": 0, "file": file, "sha256": sha or hashlib.sha256(data).hexdigest(), **kw})


MALFORMED.update({
    "import_missing_file": ([H, _import("imports/absent.npz", sha="0" * 64)], 2, "import"),
    "import_wrong_sha": ([H, _import(sha="a" * 64)], 2, "import"),
    "import_in_stroke": ([H, BR, SB, SA, _import()], 5, "event-order"),
    "import_path_up": ([H, _import("../imports/good.npz")], 2, "name"),
    "import_path_absolute": ([H, _import("/etc/passwd")], 2, "name"),
    "import_sha_short": ([H, _import(sha="abc")], 2, "range"),
    "import_sha_upper": ([H, _import(sha=hashlib.sha256(_GOOD).hexdigest().upper())], 2, "range"),
    "import_file_number": ([H, '{"ev": "import", "t": 0, "file": 3, "sha256": "%s"}' % ("0" * 64)], 2, "type"),
    "import_missing_sha": ([H, '{"ev": "import", "t": 0, "file": "imports/good.npz"}'], 2, "missing"),
    "import_name_empty": ([H, _import(name="")], 2, "range"),
    "import_locked": ([H2, _layer(op="set", layer="Layer 1", locked=True), _import()], 3, "layer"),
    "import_too_deep": ([H, _import("imports/deep.npz")], 2, "import"),
    "import_outside": ([H, _import("imports/outside.npz")], 2, "import"),
    "import_twice": ([H, _import("imports/twice.npz")], 2, "import"),
    "import_nan": ([H, _import("imports/nan.npz")], 2, "import"),
    "import_minus_zero": ([H, _import("imports/minus_zero.npz")], 2, "import"),
    "import_negative": ([H, _import("imports/negative.npz")], 2, "import"),
    "import_compressed": ([H, _import("imports/compressed.npz")], 2, "import"),
    "import_wide": ([H, _import("imports/wide.npz")], 2, "import"),
    "import_not_zip": ([H, _import("imports/not_zip.npz")], 2, "import"),
    "import_undo": ([H, _import(), '{"ev": "undo", "t": 0}', '{"ev": "undo", "t": 0}'], 4, "event-order"),
})

"""The GPU's ray caster ray by ray (octopaint_ref.gpu_probe; docs/precision.md,
"The GPU's f16"): `octopaint probe` traces a camera's rays through the
precision study's depth-24 tree with the WGSL ray caster on the adapter it
finds (lavapipe here), and every ray must end within the study's bound;
with the eye inside the canvas, lavapipe's f16 and f32 traversals must
match the reference's correctly rounded emulation bit for bit (another
driver may contract or flush and is then only held to the bound). Bad
inputs to `octopaint probe` are refused with a message and exit status 2.
"""

from __future__ import annotations

import json
import os
import subprocess

import numpy as np
import pytest
from octopaint_ref import gpu_probe as G
from octopaint_ref import precision as P
from octopaint_ref.dump import dump_bytes, load_dump, write_atomic
from octopaint_ref.raycast import device_tree


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """The study's graded depth-24 tree with hashed leaf values (fast)."""
    path = str(tmp_path_factory.mktemp("probe") / "scene.npz")
    write_atomic(path, dump_bytes(P.build_scene(paint=False)))
    arrays = load_dump(path)
    return path, arrays, device_tree(arrays)


@pytest.mark.parametrize("precision", ["f16", "f32"])
@pytest.mark.parametrize("camera", ["near", "far"])
def test_every_gpu_ray_is_within_the_bound(painter, scene, tmp_path, precision, camera):
    path, arrays, device = scene
    cam = P.near_camera((32, 32)) if camera == "near" else P.far_camera((32, 32))
    probe = G.run_probe(painter, path, cam, precision, str(tmp_path / "rays.npz"))
    assert len(probe["status"]) == 32 * 32
    r = G.compare(arrays, cam, probe, precision, device, exact_rays=4 if camera == "near" else 0)
    s = r["summary"]
    assert s["traced"] == s["rays"], s
    assert s["within_bound"] == s["rays"], s
    # Each ray ends where the emulation's does: the same cell after the
    # same steps for the same reason.
    assert s["same_path"] == s["rays"], s
    if camera == "near":
        assert s["exact_same_cell"] == s["exact_sampled"] == 4, s
        if "llvmpipe" in s["adapter"]:
            assert s["same_bits"] == s["rays"], s


def test_probe_refuses_bad_input(painter, scene, tmp_path):
    path, _, _ = scene
    cam = G.camera_json(P.near_camera((8, 8)))
    out = tmp_path / "rays.npz"

    def probe(*args):
        return subprocess.run([painter, "probe", *map(str, args), "--out", str(out)], capture_output=True, text=True, env=dict(os.environ, NODEVICE_SELECT="1"))

    not_npz = tmp_path / "not.npz"
    not_npz.write_text("hello")
    r = probe(not_npz, "--camera", cam)
    assert r.returncode == 2 and "not an .npz" in r.stderr, r.stderr
    # A dump whose tree is broken: a child that does not point back.
    arrays = dict(np.load(path))
    arrays["parent"] = arrays["parent"].copy()
    arrays["parent"][np.nonzero(arrays["depth"] == 1)[0][0]] = 0xFFFF_FFFF
    broken = tmp_path / "broken.npz"
    write_atomic(str(broken), dump_bytes(arrays))
    r = probe(broken, "--camera", cam)
    assert r.returncode == 2 and "not a valid tree" in r.stderr, r.stderr
    # A dump without sigma.
    del arrays["sigma"]
    np.savez(tmp_path / "short.npz", **arrays)
    r = probe(tmp_path / "short.npz", "--camera", cam)
    assert r.returncode == 2 and "sigma.npy" in r.stderr, r.stderr
    # Cameras: not JSON, NaN in the eye, fov out of range.
    for bad, says in (("{", "--camera"), (json.dumps({**json.loads(cam), "eye": [1, "x", 2]}), "eye"), (json.dumps({**json.loads(cam), "fov": [-2, 2, 1, -1]}), "fov")):
        r = probe(path, "--camera", bad)
        assert r.returncode == 2 and says in r.stderr, r.stderr
    assert not out.exists()

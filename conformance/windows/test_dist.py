"""The release packages (make dist) work from an empty folder: each is
unpacked where nothing else is, and its binary (the Windows one under Wine)
starts, opens the example documents, exports one, and for VR finds the
loader it ships (Windows) and says that no runtime is running."""

from __future__ import annotations

import os
import re
import tarfile
import zipfile

from conftest import REPO, WINE, Program

with open(os.path.join(REPO, "painter", "Cargo.toml")) as f:
    VERSION = re.search(r'^version = "([^"]+)"$', f.read(), re.M).group(1)
DIST = os.path.join(REPO, "dist")
EXAMPLES = ["examples/scene.octo", "examples/shapes-and-modes.octo"]


def unpacked(archive: str, into) -> str:
    path = os.path.join(DIST, archive)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path} is missing: run `make dist`")
    if archive.endswith(".zip"):
        with zipfile.ZipFile(path) as z:
            z.extractall(into)
    else:
        with tarfile.open(path) as t:
            # The "tar" filter where this Python has extraction filters
            # (3.11.4 and later; Debian 12's 3.11.2 has none).
            t.extractall(into, **({"filter": "tar"} if hasattr(tarfile, "tar_filter") else {}))
    (top,) = os.listdir(into)
    assert top == archive.rsplit(".", 2 if archive.endswith(".tar.gz") else 1)[0]
    return os.path.join(into, top)


def common_contents(folder: str, readme: str):
    names = set(os.listdir(folder))
    assert {readme, "LICENSE.txt", "THIRD-PARTY-LICENSES.txt", "examples"} <= names, names
    with open(os.path.join(folder, readme), newline="") as f:
        text = f.read()
    assert f"Octopaint {VERSION}" in text and "SteamVR" in text and "journal" in text
    with open(os.path.join(folder, "THIRD-PARTY-LICENSES.txt")) as f:
        licences = f.read()
    # Generated from Cargo's metadata: the crates the binary is built from.
    for crate in ("wgpu", "openxr", "egui", "winit", "glam"):
        assert re.search(rf"\b{crate} \d", licences), crate
    return text


def test_the_linux_package_runs_from_an_empty_folder(tmp_path):
    folder = unpacked(f"octopaint-{VERSION}-linux-x86_64.tar.gz", tmp_path / "pkg")
    common_contents(folder, "README.md")
    exe = os.path.join(folder, "octopaint")
    assert os.access(exe, os.X_OK)
    env = dict(os.environ, XR_RUNTIME_JSON=str(tmp_path / "none.json"))
    p = Program([exe], env)
    assert p.run("--version", cwd=folder).stdout.strip() == f"octopaint {VERSION}"
    for doc in EXAMPLES:
        assert "events" in p.run("info", doc, cwd=folder).stdout
    p.run("export", EXAMPLES[1], "--gltf", tmp_path / "s.glb", "--quiet", cwd=folder)
    r = p.run("xr-info", ok=False, cwd=folder)
    assert r.returncode == 3 and "no VR here: no OpenXR" in r.stderr, r.stderr


def test_the_windows_package_runs_from_an_empty_folder_under_wine(linux, windows, tmp_path):
    folder = unpacked(f"octopaint-{VERSION}-windows-x86_64.zip", tmp_path / "pkg")
    text = common_contents(folder, "README.txt")
    assert "\r\n" in text and "\n" not in text.replace("\r\n", ""), "README.txt has CRLF line ends for Notepad"
    assert {"octopaint.exe", "openxr_loader.dll", "openxr-sdk"} <= set(os.listdir(folder))
    with open(os.path.join(folder, "openxr-sdk", "LICENSE")) as f:
        assert "Apache License" in f.read()
    # The packaged exe, not the build's: run from the package folder.
    p = Program([WINE, os.path.join(folder, "octopaint.exe")], windows.env)
    assert p.run("--version", cwd=folder).stdout.strip() == f"octopaint {VERSION}"
    for doc in EXAMPLES:
        out = p.run("info", doc, cwd=folder).stdout
        assert "events" in out and out == linux.run("info", doc, cwd=folder).stdout
    # An export from the package equals the Linux build's.
    p.run("export", EXAMPLES[1], "--gltf", tmp_path / "w.glb", "--quiet", cwd=folder)
    linux.run("export", EXAMPLES[1], "--gltf", tmp_path / "l.glb", "--quiet", cwd=folder)
    assert (tmp_path / "w.glb").read_bytes() == (tmp_path / "l.glb").read_bytes()
    # The shipped loader is found beside the exe: what is missing is the
    # runtime, and the message says which to start.
    r = p.run("xr-info", ok=False, cwd=folder)
    assert r.returncode == 3, (r.stdout, r.stderr)
    assert "no VR here: no OpenXR runtime is running or installed (start SteamVR" in r.stderr, r.stderr
    r = p.run("vr", EXAMPLES[1], "--no-fallback", ok=False, cwd=folder)
    assert r.returncode == 3 and "no OpenXR runtime" in r.stderr, r.stderr

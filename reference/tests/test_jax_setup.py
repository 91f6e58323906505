"""The package sets no global JAX configuration on import (jax_setup.py):
a program that imports it keeps JAX as it was, the ray caster refuses to
run in float32 with a clear error, and the entry points turn 64-bit mode
on themselves."""

import os
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

PROBE = """
import jax
import octopaint_ref.arith, octopaint_ref.brush, octopaint_ref.diffpaint, octopaint_ref.diffrender, octopaint_ref.paint, octopaint_ref.raycast, octopaint_ref.replay
print("x64", jax.config.jax_enable_x64)
print("cache", jax.config.jax_compilation_cache_dir)
from octopaint_ref.precision import build_scene
try:
    octopaint_ref.raycast.device_tree(build_scene(paint=False, depth=4))
except RuntimeError as e:
    print("refused", "configure()" in str(e))
from octopaint_ref.jax_setup import configure
configure()
print("x64", jax.config.jax_enable_x64)
octopaint_ref.raycast.device_tree(build_scene(paint=False, depth=4))
print("ran")
"""


def test_importing_the_package_changes_no_jax_setting():
    env = {k: v for k, v in os.environ.items() if k != "JAX_ENABLE_X64"}
    p = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    assert p.stdout.split("\n")[:5] == ["x64 False", "cache None", "refused True", "x64 True", "ran"], p.stdout


def test_the_command_line_configures_jax_itself(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "JAX_ENABLE_X64"}
    trace = os.path.join(REPO, "traces", "single_stamp.jsonl")
    p = subprocess.run([sys.executable, "-m", "octopaint_ref.cli", "replay", trace, "--out", str(tmp_path), "--quiet"],
                       capture_output=True, text=True, env=env, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    assert any(f.endswith(".png") for f in os.listdir(tmp_path)) and any(f.endswith(".npz") for f in os.listdir(tmp_path))

"""What the reference asks of JAX, set by whoever runs it, never on import.

The reference computes in float64 under JAX (the f16 and f32 of the
precision study are carried in f64 and rounded per operation, arith.py), so
JAX's 64-bit mode must be on before the first array is made. Importing a
module of this package changes no global JAX setting: a program that imports
it (a notebook, a test suite, another library) decides. The package's own
entry points (`octopaint-ref`, `python -m octopaint_ref.*`, the examples)
call `configure()` first, and the test suites do in their conftest.py;
`require_x64()` stops the ray caster and the differentiable paths with a
clear error when nobody has.
"""

from __future__ import annotations

import os

import jax


def configure(cache: bool = True) -> None:
    """Turn on JAX's 64-bit mode and (unless `cache` is false or
    OCTOPAINT_JAX_CACHE=off) the on-disk cache of compiled kernels, so that
    every run after the first skips XLA's compilation (a few seconds).
    Idempotent; call it before the first JAX array."""
    jax.config.update("jax_enable_x64", True)
    where = os.environ.get("OCTOPAINT_JAX_CACHE", os.path.expanduser("~/.cache/octopaint_ref/jax"))
    if cache and where != "off":
        jax.config.update("jax_compilation_cache_dir", where)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)


def require_x64() -> None:
    """Refuse to compute when JAX's 64-bit mode is off: the results would
    silently be float32."""
    if not jax.config.jax_enable_x64:
        raise RuntimeError(
            "octopaint_ref computes in float64 under JAX: call octopaint_ref.jax_setup.configure() "
            "(or set JAX_ENABLE_X64=1) before the first JAX array"
        )

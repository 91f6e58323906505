"""The tree as the ray caster reads it (spec 7): the pools padded with free
cells to a power of two, so that a replay compiles once per size class, and
the static description of the root array. raycast.py, shading.py and
march.py read it."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .g3 import g3_from_links
from .jax_setup import require_x64

NONE = 0xFFFF_FFFF


class Canvas(NamedTuple):
    """The static description of the root array (hashable: a jit key)."""

    roots: tuple
    max_depth: int
    root_size: float


class DeviceTree(NamedTuple):
    """The pools the ray caster reads, padded with free cells to a power of
    two so that a replay compiles once per size class.

    parent, first_child u32 [N]; depth i32 [N] (255 = free); g3 u32 [N, 3];
    rgb f64 [N, 3] in [0, 1] (stored u8 / 255); sigma f64 [N] (per canvas unit).
    """

    parent: jax.Array
    first_child: jax.Array
    depth: jax.Array
    g3: jax.Array
    rgb: jax.Array
    sigma: jax.Array


def _bucket(n: int) -> int:
    b = 1024
    while b < n:
        b *= 2
    return b


def device_tree(arrays: dict) -> tuple[DeviceTree, Canvas]:
    """From tree-dump arrays (dump.tree_arrays or a loaded .npz; g3 is
    recomputed from the links when absent)."""
    require_x64()
    parent = np.asarray(arrays["parent"], np.uint32)
    first_child = np.asarray(arrays["first_child"], np.uint32)
    depth = np.asarray(arrays["depth"], np.uint8)
    roots = tuple(int(r) for r in np.asarray(arrays["roots"]).reshape(-1))
    g3 = arrays.get("g3")
    if g3 is None:
        g3 = g3_from_links(parent, first_child, depth, roots)
    n = len(parent)
    m = _bucket(n)

    def pad(a, fill):
        out = np.full((m,) + a.shape[1:], fill, a.dtype)
        out[:n] = a
        return out

    tree = DeviceTree(
        parent=jnp.asarray(pad(parent, np.uint32(NONE))),
        first_child=jnp.asarray(pad(first_child, np.uint32(NONE))),
        depth=jnp.asarray(pad(depth.astype(np.int32), 255)),
        g3=jnp.asarray(pad(np.asarray(g3, np.uint32), np.uint32(NONE))),
        rgb=jnp.asarray(pad(np.asarray(arrays["rgb"], np.uint8).astype(np.float64) / 255.0, 0.0)),
        sigma=jnp.asarray(pad(np.asarray(arrays["sigma"], np.float32).astype(np.float64), 0.0)),
    )
    canvas = Canvas(roots, int(np.asarray(arrays["max_depth"])), float(np.asarray(arrays["root_size"])))
    return tree, canvas

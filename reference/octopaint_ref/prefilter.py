"""Interior values: every cell with children holds the prefilter of its 8
children (spec 4.4). Painter twin: painter/octree/src/prefilter.rs, which
keeps them current as cells change; here they are computed whole, from the
leaves up, when a dump reads them (the values are a function of the leaves
and the topology alone, so both give the same bits).

    sigma(P) = f32(W * 0.125)      W = ((s0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7))
    rgb(P)   = clamp(floor(M / W + 0.5), 0, 255) per channel, M the same sum of s_k * rgb_k
               octant 0's rgb when W == 0 (all eight children empty)

in exact f64, s_k the children's stored sigma, rgb_k their stored bytes.
"""

from __future__ import annotations

import numpy as np

from .g3 import FREE, NONE


def pair_sum(x):
    """The sum over axis 1 (8 octants) in the spec's order: pairs, then pairs
    of pairs (numpy or JAX arrays)."""
    return ((x[:, 0] + x[:, 1]) + (x[:, 2] + x[:, 3])) + ((x[:, 4] + x[:, 5]) + (x[:, 6] + x[:, 7]))


def unit_value(rgb: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The prefiltered (rgb u8 [m, 3], sigma f32 [m]) of m units of children
    (rgb u8 [m, 8, 3], sigma f32 [m, 8], in octant order)."""
    s = sigma.astype(np.float64)
    w = pair_sum(s)
    out_sigma = (w * 0.125).astype(np.float32)  # round to nearest, ties to even
    out_rgb = rgb[:, 0, :].copy()
    pos = w > 0
    if pos.any():
        num = pair_sum(s[pos][:, :, None] * rgb[pos].astype(np.float64))
        out_rgb[pos] = np.clip(np.floor(num / w[pos, None] + 0.5), 0, 255).astype(np.uint8)
    return out_rgb, out_sigma


def inner_units(first_child: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The live cells with children [m] and their children [m, 8]."""
    inner = np.nonzero((first_child != NONE) & (depth != FREE))[0]
    return inner, first_child[inner].astype(np.int64)[:, None] + np.arange(8)


def prefiltered(first_child: np.ndarray, depth: np.ndarray, rgb: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Copies of the pools' rgb [N, 3] and sigma [N] with every live cell
    that has children given its prefiltered value, deepest cells first (a
    parent reads its children's values after they were computed)."""
    rgb, sigma = rgb.copy(), sigma.copy()
    inner, kids = inner_units(first_child, depth)
    if not len(inner):
        return rgb, sigma
    d_inner = depth[inner]
    for d in range(int(d_inner.max()), -1, -1):
        at = d_inner == d
        if at.any():
            rgb[inner[at]], sigma[inner[at]] = unit_value(rgb[kids[at]], sigma[kids[at]])
    return rgb, sigma


def stale_cells(first_child: np.ndarray, depth: np.ndarray, rgb: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Mask [N] of the cells with children whose stored value is not the
    prefilter of their children's stored values (sigma by its bits)."""
    inner, kids = inner_units(first_child, depth)
    bad = np.zeros(len(depth), bool)
    if len(inner):
        want_rgb, want_sigma = unit_value(rgb[kids], sigma[kids])
        bad[inner] = np.any(rgb[inner] != want_rgb, axis=1) | (sigma[inner].view(np.uint32) != want_sigma.view(np.uint32))
    return bad

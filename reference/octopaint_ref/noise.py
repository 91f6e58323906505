"""Improved Perlin noise (Perlin 2002) with a permutation built from a seed by
hashing indices, so that Python, JAX and Rust produce identical values
(spec 8.6; painter twin: painter/paint/src/noise.rs).

Functions take `xp` (numpy or jax.numpy) so the same source serves the exact
host code and the differentiable JAX stamping.
"""

from __future__ import annotations

import numpy as np

MASK32 = 0xFFFF_FFFF
GOLDEN32 = 0x9E37_79B9


def hash32(x: int) -> int:
    """lowbias32 (Chris Wellons): a 32-bit integer hash with good avalanche."""
    x &= MASK32
    x ^= x >> 16
    x = (x * 0x7FEB_352D) & MASK32
    x ^= x >> 15
    x = (x * 0x846C_A68B) & MASK32
    x ^= x >> 16
    return x


def permutation(seed: int) -> np.ndarray:
    """The 512-entry permutation table for `seed`: a Fisher-Yates shuffle of
    0..255 driven by hash32(seed + i * GOLDEN32), repeated twice."""
    p = list(range(256))
    for i in range(255, 0, -1):
        j = hash32((seed + i * GOLDEN32) & MASK32) % (i + 1)
        p[i], p[j] = p[j], p[i]
    return np.array(p + p, dtype=np.int64)


def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _lerp(t, a, b):
    return a + t * (b - a)


def _grad(xp, h, x, y, z):
    h = h & 15
    u = xp.where(h < 8, x, y)
    v = xp.where(h < 4, y, xp.where((h == 12) | (h == 14), x, z))
    return xp.where((h & 1) == 0, u, -u) + xp.where((h & 2) == 0, v, -v)


def perlin(xp, perm, p):
    """Improved Perlin noise at points p [..., 3] (f64), in about [-1, 1]."""
    fl = xp.floor(p)
    # floor(p) mod 256, exact for every finite p (spec 8.6); a non-finite
    # p (absurd scales) gives NaN, read as 0, where the noise is NaN anyway.
    m = fl - 256.0 * xp.floor(fl / 256.0)
    i = xp.where(m == m, m, 0.0).astype(xp.int64)
    f = p - fl
    X, Y, Z = i[..., 0], i[..., 1], i[..., 2]
    x, y, z = f[..., 0], f[..., 1], f[..., 2]
    u, v, w = _fade(x), _fade(y), _fade(z)
    A = perm[X] + Y
    AA = perm[A] + Z
    AB = perm[A + 1] + Z
    B = perm[X + 1] + Y
    BA = perm[B] + Z
    BB = perm[B + 1] + Z
    g = lambda h, a, b, c: _grad(xp, perm[h], a, b, c)
    return _lerp(
        w,
        _lerp(v, _lerp(u, g(AA, x, y, z), g(BA, x - 1, y, z)), _lerp(u, g(AB, x, y - 1, z), g(BB, x - 1, y - 1, z))),
        _lerp(
            v,
            _lerp(u, g(AA + 1, x, y, z - 1), g(BA + 1, x - 1, y, z - 1)),
            _lerp(u, g(AB + 1, x, y - 1, z - 1), g(BB + 1, x - 1, y - 1, z - 1)),
        ),
    )


def fbm(xp, perm, p, scale, octaves: int, gain):
    """Normalised fractional Brownian motion: sum over octaves o of
    gain^o * perlin(p * (scale * 2^o)), divided by the sum of gain^o."""
    total = 0.0
    norm = 0.0
    amp = 1.0
    for o in range(octaves):
        total = total + amp * perlin(xp, perm, p * (scale * float(2**o)))
        norm = norm + amp
        amp = amp * gain
    return total / norm

"""Brush geometry, coverage and the five blend modes (spec section 8).

Every function takes `xp` (numpy or jax.numpy). The host calls the numpy
versions for topology decisions (reach, target depth), which must be exact
f64 and identical to the painter's (painter/paint/src/brush.rs); the stroke
code calls the jitted JAX versions (`jax_*` below) for coverage and blending,
which are pure functions of brush parameters, sample positions and cell
values, and so differentiable with respect to colour, opacity, radius and
sample positions.

Shapes of arrays: n cells, k primitives (capsules or stamps).
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from . import noise

HALF_DIAG = 0.8660254037844386  # sqrt(3)/2 as f64: a cell's half-diagonal per unit edge
CELLS_PER_RADIUS = 10.0
RADIUS_PRESSURE_FLOOR = 0.25  # r = radius * (0.25 + 0.75 * pressure)
OPACITY_CLAMP = 0.999
# Smallest normal f64. XLA on CPU flushes subnormal results to zero and numpy
# and Rust do not, so the rules flush at the points where a subnormal could
# change a result: the stroke maximum a and the mix weight (spec 8.9).
TINY = 2.2250738585072014e-308
STAMP_SHAPES = ("cylinder", "box", "cone", "noise")


# ---------------------------------------------------------------- geometry
def capsule_geometry(xp, x, p0, p1, r0, r1):
    """Tapered capsule between (p0, r0) and (p1, r1) (spec 8.3).

    x [n, 3]; p0, p1 [k, 3]; r0, r1 [k]. Returns (dist [n, k], u [n, k],
    r [n, k]): distance from x to the axis point at the clamped projection
    parameter u, and the radius lerp(r0, r1, u) there. The brush's signed
    distance is dist - r.
    """
    return capsule_projection(xp, x, p0, p1, r0, r1)[:3]


def capsule_t(xp, x, p0, p1):
    """t [n, k] = (x - p0) . (p1 - p0), summed x, y, z in order: the
    projection before the division and clamping, whose sign an open start
    tests (spec 8.3)."""
    d = p1 - p0
    w = x[:, None, :] - p0[None, :, :]
    return w[..., 0] * d[None, :, 0] + w[..., 1] * d[None, :, 1] + w[..., 2] * d[None, :, 2]


def capsule_projection(xp, x, p0, p1, r0, r1):
    """capsule_geometry with t of capsule_t: (dist, u, r, t), each [n, k]."""
    d = p1 - p0
    dd = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
    wd = capsule_t(xp, x, p0, p1)
    # A segment shorter than sqrt(TINY) is a sphere at p0 (spec 8.3).
    long = dd >= TINY
    safe_dd = xp.where(long, dd, 1.0)
    u = xp.where(long[None, :], xp.clip(wd / safe_dd[None, :], 0.0, 1.0), 0.0)
    c = p0[None, :, :] + u[..., None] * d[None, :, :]
    e = x[:, None, :] - c
    s = e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1] + e[..., 2] * e[..., 2]
    dist = xp.where(s > 0, xp.sqrt(xp.where(s > 0, s, 1.0)), 0.0)
    r = r0[None, :] + (r1 - r0)[None, :] * u
    return dist, u, r, wd


def capsule_slack(p0, p1, r0, r1) -> float:
    """Lipschitz constant K of the tapered capsule's distance dist - r(u):
    1 + |r1 - r0| / |p1 - p0| (1 for a sphere). The reach test scales the
    cell's half-diagonal by K, which makes it monotone under refinement even
    for strongly tapered segments (spec 8.7)."""
    d0, d1, d2 = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
    dd = d0 * d0 + d1 * d1 + d2 * d2
    if dd < TINY:
        return 1.0
    return 1.0 + abs(r1 - r0) / float(np.sqrt(dd))


def local_coords(xp, x, c, rot):
    """x [n, 3] in the frames of k stamps (centre c [k, 3], rotation rot
    [k, 3, 3], local-to-canvas): l_i = sum_j rot[j][i] * (x - c)_j, summed
    left to right. Returns [n, k, 3]."""
    d = x[:, None, :] - c[None, :, :]
    cols = []
    for i in range(3):
        cols.append(rot[None, :, 0, i] * d[..., 0] + rot[None, :, 1, i] * d[..., 1] + rot[None, :, 2, i] * d[..., 2])
    return xp.stack(cols, axis=-1)


def stamp_reach(xp, shape: str, x, c, r, rot, aspect, h):
    """Whether a cell of centre x [n, 3] and half-diagonal h [n] is within
    reach of each of k stamps [n, k] (spec 8.7): its bounding ball may touch
    the stamp. Exact f64 on the host; conservative for every shape."""
    if shape == "noise":
        dist, _, rr = capsule_geometry(xp, x, c, c, r, r)
        return dist - rr <= h[:, None]
    ax, ay, az = (float(v) for v in aspect)
    lc = local_coords(xp, x, c, rot)
    hh = h[:, None]
    rk = r[None, :]
    if shape == "box":
        return (
            (xp.abs(lc[..., 0]) <= ax * rk + hh)
            & (xp.abs(lc[..., 1]) <= ay * rk + hh)
            & (xp.abs(lc[..., 2]) <= az * rk + hh)
        )
    # The elliptic cross-section's gauge is Lipschitz with constant
    # 1 / (min(ax, ay) * r): a ball of radius h that touches the shape has
    # its centre at gauge <= 1 + h / (m * r). Each test is monotone under
    # refinement (a child in reach has its parent in reach).
    m = min(ax, ay)
    nx = lc[..., 0] / (ax * rk)
    ny = lc[..., 1] / (ay * rk)
    radial = _safe_sqrt(xp, nx * nx + ny * ny)
    inside = (radial <= 1.0 + hh / (m * rk)) & (xp.abs(lc[..., 2]) <= az * rk + hh)
    if shape == "cylinder":
        return inside
    if shape == "cone":
        lip = float(np.sqrt(4.0 / (m * m) + 1.0 / (az * az)))
        nz = lc[..., 2] / (az * rk)
        return inside & (2.0 * radial + nz <= 1.0 + hh * lip / rk)
    raise ValueError(f"unknown stamp shape {shape}")


def _safe_sqrt(xp, s):
    return xp.where(s > 0, xp.sqrt(xp.where(s > 0, s, 1.0)), 0.0)


def stamp_gauge(xp, shape: str, x, c, r, rot, aspect):
    """Normalised gauge rho [n, k] of an oriented stamp: rho <= 1 inside,
    homogeneous of degree 1 about the stamp centre (spec 8.2)."""
    if shape == "noise":
        d = x[:, None, :] - c[None, :, :]
        s = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
        return _safe_sqrt(xp, s) / r[None, :]
    lc = local_coords(xp, x, c, rot)
    nx = lc[..., 0] / (aspect[0] * r[None, :])
    ny = lc[..., 1] / (aspect[1] * r[None, :])
    nz = lc[..., 2] / (aspect[2] * r[None, :])
    if shape == "box":
        return xp.maximum(xp.maximum(xp.abs(nx), xp.abs(ny)), xp.abs(nz))
    radial = _safe_sqrt(xp, nx * nx + ny * ny)
    if shape == "cylinder":
        return xp.maximum(radial, xp.abs(nz))
    if shape == "cone":  # base (radius 1) at z = -1, apex at z = +1
        return xp.maximum(xp.abs(nz), 2.0 * radial + nz)
    raise ValueError(f"unknown stamp shape {shape}")


# ---------------------------------------------------------------- coverage
def coverage_profile(xp, rho, hardness):
    """1 for rho <= hardness, smoothstep down to 0 at rho = 1, 0 beyond."""
    span = 1.0 - hardness
    safe = xp.where(span > 0, span, 1.0)
    t = xp.clip((1.0 - rho) / safe, 0.0, 1.0)
    smooth = t * t * (3.0 - 2.0 * t)
    return xp.where(rho >= 1.0, 0.0, xp.where(rho <= hardness, 1.0, smooth))


def capsule_coverage(xp, x, p0, p1, r0, r1, f0, f1, hardness, open_start=None):
    """coverage * flow [n, k] of k tapered capsules at points x [n, 3].
    open_start [k] (bool, optional): a capsule with an open start covers
    nothing where t < 0, behind its start plane (spec 8.3)."""
    dist, u, r, t = capsule_projection(xp, x, p0, p1, r0, r1)
    flow = f0[None, :] + (f1 - f0)[None, :] * u
    cov = coverage_profile(xp, dist / r, hardness) * flow
    if open_start is not None:
        cov = xp.where(open_start[None, :] & (t < 0.0), 0.0, cov)
    return cov


def capsule_slacks(xp, p0, p1, r0, r1):
    """capsule_slack of k capsules at once [k] (p0, p1 [k, 3]; r0, r1 [k])."""
    d = p1 - p0
    dd = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
    long = dd >= TINY
    return xp.where(long, 1.0 + xp.abs(r1 - r0) / xp.sqrt(xp.where(long, dd, 1.0)), 1.0)


def capsule_coverage_bounds(xp, x, h, p0, p1, r0, r1, f0, f1, hardness):
    """Bounds [lo, hi] of coverage * flow [n, k] of k tapered capsules over
    the balls of radius h [n] about x [n, 3] (spec 8.7, settled leaves):
    within a ball dist moves at most h and r(u) at most h * (K - 1), the
    profile falls as dist / r grows, and the flow lies between f0 and f1."""
    dist, _, r = capsule_geometry(xp, x, p0, p1, r0, r1)
    slack = capsule_slacks(xp, p0, p1, r0, r1)
    hk = h[:, None]
    hr = hk * (slack[None, :] - 1.0)
    rho_lo = xp.maximum(dist - hk, 0.0) / (r + hr)
    r_lo = r - hr
    rho_hi = xp.where(r_lo > 0.0, (dist + hk) / xp.where(r_lo > 0.0, r_lo, 1.0), xp.inf)
    lo = coverage_profile(xp, rho_hi, hardness) * xp.minimum(f0, f1)[None, :]
    hi = coverage_profile(xp, rho_lo, hardness) * xp.maximum(f0, f1)[None, :]
    return lo, hi


def noise_factor(xp, x, perm, scale, octaves: int, gain):
    """clamp(0.5 + fbm(x), 0, 1) [n] at canvas points x [n, 3]."""
    return xp.clip(0.5 + noise.fbm(xp, perm, x, scale, octaves, gain), 0.0, 1.0)


def mirrored(x: np.ndarray, mask: int, centre) -> np.ndarray:
    """x [..., 3] mirrored through the planes of `mask` (spec 8.11): on each
    axis a of the mask, 2 * centre_a - x_a (f64, one rounding)."""
    x = np.array(x, np.float64, copy=True)
    for a in range(3):
        if mask >> a & 1:
            x[..., a] = 2.0 * centre[a] - x[..., a]
    return x


def stamp_coverage(xp, shape, x, c, r, f, rot, aspect, hardness, perm, noise_scale, octaves, gain, masks=None, centre=None):
    """coverage * flow [n, k] of k stamps at points x [n, 3]. masks [k]
    (numpy): each stamp's mirror copy (spec 8.11); a noise stamp of copy m
    takes its noise at x mirrored by m through the planes at `centre`."""
    rho = stamp_gauge(xp, shape, x, c, r, rot, aspect)
    cov = coverage_profile(xp, rho, hardness) * f[None, :]
    if shape == "noise":
        if masks is None or not np.any(masks):
            cov = cov * noise_factor(xp, x, perm, noise_scale, octaves, gain)[:, None]
        else:
            nf = xp.zeros(cov.shape)
            for m in np.unique(masks):
                nm = noise_factor(xp, x if m == 0 else mirrored(x, int(m), centre), perm, noise_scale, octaves, gain)
                nf = xp.where((masks == m)[None, :], nm[:, None], nf)
            cov = cov * nf
    return cov


def max_and_argmax(xp, cov):
    """The stroke maximum a [n] (below TINY: 0) and the first primitive
    attaining it."""
    a = xp.max(cov, axis=1)
    return xp.where(a < TINY, 0.0, a), xp.argmax(cov, axis=1)


def capsule_max(xp, x, p0, p1, r0, r1, f0, f1, hardness):
    """max_and_argmax of capsule_coverage: the stroke maximum over k capsules."""
    return max_and_argmax(xp, capsule_coverage(xp, x, p0, p1, r0, r1, f0, f1, hardness))


def stamp_max(xp, shape, x, c, r, f, rot, aspect, hardness, perm, noise_scale, octaves, gain):
    """max_and_argmax of stamp_coverage: the stroke maximum over k stamps."""
    cov = stamp_coverage(xp, shape, x, c, r, f, rot, aspect, hardness, perm, noise_scale, octaves, gain)
    return max_and_argmax(xp, cov)


# ------------------------------------------------------------------- blend
def sigma_brush(xp, opacity, radius):
    """Extinction that makes a brush radius of paint have opacity alpha."""
    alpha = xp.minimum(opacity, OPACITY_CLAMP)
    return -xp.log1p(-alpha) / radius


def sigma_brush_host(opacity: float, radius: float) -> float:
    """sigma_brush for replay, with the C library's log1p (math.log1p),
    which the painter calls too: numpy may use its own SIMD logarithm."""
    return -math.log1p(-min(float(opacity), OPACITY_CLAMP)) / float(radius)


def blend(xp, mode: str, before_rgb, before_sigma, colour, sigma_b, alpha, a, mix_ratio):
    """The value of a cell after a stroke (spec 8.5): before_rgb [n, 3] in
    [0, 1], before_sigma [n], colour [n, 3] (the brush colour of the
    primitive that gave a), a [n]. Returns (rgb [n, 3] in [0, 1] unrounded,
    sigma [n]). a = 0 leaves the cell as it was."""
    bs = before_sigma
    if mode in ("paint", "pickup"):
        # An empty cell has no colour to keep: it takes the brush colour.
        base = xp.where((bs == 0)[:, None], colour, before_rgb)
        rgb = base + (colour - base) * a[:, None]
        sigma = bs + (sigma_b - bs) * a
    elif mode == "erase":
        rgb = before_rgb
        sigma = bs * (1.0 - a * alpha)
    elif mode == "recolor":
        t = (a * alpha)[:, None]
        rgb = xp.where((bs > 0)[:, None], before_rgb + (colour - before_rgb) * t, before_rgb)
        sigma = bs
    elif mode == "mix":
        # As in paint, an empty cell has no colour of its own to mix.
        base = xp.where((bs == 0)[:, None], colour, before_rgb)
        wb = mix_ratio * a * sigma_b
        wb = xp.where(wb < TINY, 0.0, wb)
        den = bs + wb
        safe = xp.where(den > 0, den, 1.0)
        mixed = (bs[:, None] * base + wb[:, None] * colour) / safe[:, None]
        rgb = xp.where((den > 0)[:, None], mixed, base)
        sigma = bs + a * sigma_b
    else:
        raise ValueError(f"unknown mode {mode}")
    keep = a == 0
    return xp.where(keep[:, None], before_rgb, rgb), xp.where(keep, bs, sigma)


def quantize_rgb(v: np.ndarray) -> np.ndarray:
    """Store a colour in [0, 1] as u8: floor(v * 255 + 0.5), clamped."""
    return np.clip(np.floor(np.asarray(v, np.float64) * 255.0 + 0.5), 0, 255).astype(np.uint8)


F32_MAX = float(np.finfo(np.float32).max)


def quantize_sigma(s: np.ndarray) -> np.ndarray:
    """Store a density as f32: the nearest f32, at most the largest finite
    one (a tiny brush radius can give an extinction beyond f32; spec 5)."""
    return np.minimum(np.asarray(s, np.float64), F32_MAX).astype(np.float32)


# --------------------------------------------------------- jitted versions
jax_blend = jax.jit(partial(blend, jnp), static_argnums=(0,))
jax_capsule_max = jax.jit(partial(capsule_max, jnp))
jax_stamp_max = jax.jit(partial(stamp_max, jnp), static_argnums=(0, 10))


# ----------------------------------------------------------- host helpers
def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix (local to canvas) of quaternion [x, y, z, w],
    normalised first; the exact expression order of spec 8.2."""
    x, y, z, w = (float(v) for v in q)
    n = np.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
            [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
            [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
        ]
    )


def nlerp(q0, q1, u: float):
    """Normalised linear interpolation of unit quaternions along the short arc."""
    q0 = np.asarray(q0, np.float64)
    q1 = np.asarray(q1, np.float64)
    q0 = q0 / np.sqrt(q0[0] * q0[0] + q0[1] * q0[1] + q0[2] * q0[2] + q0[3] * q0[3])
    q1 = q1 / np.sqrt(q1[0] * q1[0] + q1[1] * q1[1] + q1[2] * q1[2] + q1[3] * q1[3])
    if q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0:
        q1 = -q1
    q = q0 + (q1 - q0) * u
    return q / np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


def target_depth(r, root_size: float, max_depth: int) -> np.ndarray:
    """Smallest d in [0, D] with root_size * 2^-d <= r / N (else D), exact f64."""
    t = np.asarray(r, np.float64) / CELLS_PER_RADIUS
    ascending = np.ldexp(root_size, -np.arange(max_depth, -1, -1))  # exact powers of two
    larger = max_depth + 1 - np.searchsorted(ascending, t, side="right")  # sizes > t
    return np.minimum(larger, max_depth)


def stamp_extent(shape: str, aspect) -> float:
    """Radius, in brush radii, of a ball around the stamp centre holding the
    whole stamp (for bounding boxes)."""
    ax, ay, az = aspect
    if shape == "noise":
        return 1.0
    if shape == "box":
        return float(np.sqrt(ax * ax + ay * ay + az * az))
    return float(np.sqrt(max(ax, ay) ** 2 + az * az))

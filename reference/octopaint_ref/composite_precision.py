"""Compositing in low precision (docs/precision.md, "Compositing in f16 and
bf16"): front-to-back emission-absorption (spec 6) evaluated in f16, bf16,
f32 or f64 under three formulations, against mpmath, on the rays of the
precision study's scene and on adversarial media.

A ray is a list of segments: optical depth `x_i = sigma_i * len_i` (formed
in f64 or f32 where sigma and the cell size live, and rounded once to the
compositing format; sigma alone, up to 1e5, and a depth-24 cell's length,
6e-8 canvas units, do not fit f16 separately) and a colour `c_i` in [0, 1].
Compositing stops once the transmittance falls below 1/256 (spec 6).

Formulations, all with every operation rounded to the format:
- `transmittance`: `e = exp(-x)`, `C += T (1 - e) c`, `T *= e` (the f64
  reference's order);
- `optical-depth`: `tau += x`, `T' = exp(-tau)`, `C += (T - T') c`, `T = T'`;
- `optical-depth-kahan`: the same with `tau` summed by Kahan's compensated
  summation;
- `compensated`: the colour sum `C` compensated by Kahan's summation too.

`transmittance_bound` states, per ray, how far the computed transmittance
can be from the exact one under each formulation; the tests check it on
every ray.
"""

from __future__ import annotations

import ml_dtypes
import mpmath
import numpy as np

DTYPES = {"f16": np.float16, "bf16": ml_dtypes.bfloat16, "f32": np.float32, "f64": np.float64}
# Unit roundoff (half the spacing at 1) of each format, and its smallest
# positive (subnormal) number: below the normal range a rounding errs by up
# to half of that, absolutely.
UNIT = {"f16": 2.0**-11, "bf16": 2.0**-8, "f32": 2.0**-24, "f64": 2.0**-53}
TINY = {"f16": 2.0**-24, "bf16": 2.0**-133, "f32": 2.0**-149, "f64": 2.0**-1074}
# Relative error of exp in each format: f16 and bf16 take numpy's f32 exp
# (within 2^-22) and round it once; numpy's f32 and f64 exp are not
# correctly rounded, so two units in the last place are allowed (the
# scene's rays show 1.76 u in f32).
EXP_ERROR = {"f16": 2.0**-11 + 2.0**-22, "bf16": 2.0**-8 + 2.0**-22, "f32": 2.0**-22, "f64": 2.0**-51}
# A segment's optical depth is clamped here before it is rounded: beyond
# it the segment leaves T < 1.6e-28, opaque in every format, and f16 would
# otherwise hold 1e5 (a dense cell's sigma times a root's length) as inf.
X_MAX = 64.0
FORMS = ("transmittance", "optical-depth", "optical-depth-kahan", "compensated")
T_MIN = 1.0 / 256.0


def composite(x: np.ndarray, rgb: np.ndarray, fmt: str, form: str):
    """Composite rays: `x` [R, K] optical depths (0 past a ray's end), `rgb`
    [R, K, 3] colours in [0, 1], both f64. Returns (colour [R, 3], final
    transmittance [R], end [R]) as f64, colour and transmittance as f64; a
    ray composited x[r, :end[r]] (segments of depth 0 change nothing)."""
    f = DTYPES[fmt]
    R, K = x.shape
    one = f(1.0)
    T = np.full(R, one, f)
    C = np.zeros((R, 3), f)
    tau = np.zeros(R, f)
    comp = np.zeros(R, f)
    comp_c = np.zeros((R, 3), f)
    used = np.zeros(R, np.int64)
    for k in range(K):
        live = (T >= f(T_MIN)) & (x[:, k] > 0)
        if not live.any():
            if (x[:, k:] == 0).all():
                break
            continue
        xk = np.minimum(x[:, k], X_MAX).astype(f)
        ck = rgb[:, k].astype(f)
        if form == "transmittance":
            e = np.exp(-xk)
            w = T * (one - e)
            Tn = T * e
        elif form == "optical-depth":
            tau_n = tau + xk
            Tn = np.exp(-tau_n)
            w = T - Tn
            tau = np.where(live, tau_n, tau)
        elif form in ("optical-depth-kahan", "compensated"):
            y = xk - comp
            t = tau + y
            comp_n = (t - tau) - y
            Tn = np.exp(-t)
            w = T - Tn
            tau = np.where(live, t, tau)
            comp = np.where(live, comp_n, comp)
        else:
            raise ValueError(f"unknown formulation {form!r}")
        if form == "compensated":
            yc = w[:, None] * ck - comp_c
            tc = C + yc
            comp_c = np.where(live[:, None], (tc - C) - yc, comp_c)
            C = np.where(live[:, None], tc, C)
        else:
            C = np.where(live[:, None], C + w[:, None] * ck, C)
        T = np.where(live, Tn, T)
        used = np.where(live, k + 1, used)
    return C.astype(np.float64), T.astype(np.float64), used


def exact(x: np.ndarray, rgb: np.ndarray, dps: int = 40):
    """The same compositing in mpmath (the x, clamped to X_MAX, and the
    colours as given, in f64, taken exactly): colour [R, 3], transmittance
    [R], end [R] (as composite's)."""
    R, K = x.shape
    C = np.zeros((R, 3))
    Tout = np.zeros(R)
    used = np.zeros(R, np.int64)
    with mpmath.workdps(dps):
        t_min = mpmath.mpf(1) / 256
        for r in range(R):
            T, tau = mpmath.mpf(1), mpmath.mpf(0)
            c = [mpmath.mpf(0)] * 3
            for k in range(K):
                xk = min(float(x[r, k]), X_MAX)
                if xk <= 0 or T < t_min:
                    continue
                tau += mpmath.mpf(xk)
                Tn = mpmath.exp(-tau)
                w = T - Tn
                c = [c[a] + w * mpmath.mpf(float(rgb[r, k, a])) for a in range(3)]
                T = Tn
                used[r] = k + 1
            C[r] = [float(v) for v in c]
            Tout[r] = float(T)
    return C, Tout, used


def transmittance_bound(x: np.ndarray, used: np.ndarray, fmt: str, form: str) -> np.ndarray:
    """Per ray, an upper bound on |T_computed - T_exact| after the segments
    the computed ray used (x[r, :used[r]], n of them of depth > 0), from the formulation
    and the format's unit roundoff u (exp within EXP_ERROR[fmt], v,
    relative; every other operation exact before one rounding):

    - every x_i is rounded once: a relative error of at most u;
    - transmittance: T = prod fl(fl(exp(-x_i)) * T): each factor brings
      (1 + v)(1 + u), so T_computed / T_exact is within
      exp(u tau) ((1 + u)(1 + v))^n of 1 either way;
    - optical-depth: recursive summation, |tau_computed - tau| <=
      u tau + gamma_(n-1) (1 + u) tau (gamma_m = m u / (1 - m u));
    - Kahan: |tau_computed - tau| <= u tau + (2u + 2n u^2)(1 + u) tau
      (Goldberg's bound, with its O(n u^2) term written out doubled);
    - then T = fl(exp(-tau)): |T_computed - T| <= T (expm1(dtau) +
      v exp(dtau)).
    To all of it comes the underflow of the last steps: exp(-x) or T below
    the normal range errs absolutely, by up to half the smallest subnormal
    per rounding (two count: compositing stops once T < 1/256, so only the
    last segment can drive T that low). Past n u >= 1 the summation bound is
    vacuous (infinite)."""
    u, v = UNIT[fmt], EXP_ERROR[fmt]
    eta = TINY[fmt]
    mask = np.arange(x.shape[1])[None, :] < used[:, None]
    n = (mask & (x > 0)).sum(axis=1).astype(np.float64)
    x = np.minimum(x, X_MAX)
    tau = np.where(mask, x, 0.0).sum(axis=1)
    T = np.exp(-tau)
    if form == "transmittance":
        ratio = np.exp(u * tau) * ((1.0 + u) * (1.0 + v)) ** n
        return T * np.maximum(ratio - 1.0, 1.0 - 1.0 / ratio) + 2.0 * eta
    if form == "optical-depth":
        m = np.maximum(n - 1.0, 0.0)
        gamma = np.where(m * u < 1.0, m * u / np.maximum(1.0 - m * u, 1e-300), np.inf)
        dtau = u * tau + gamma * (1.0 + u) * tau
    elif form in ("optical-depth-kahan", "compensated"):
        dtau = u * tau + (2.0 * u + 2.0 * n * u * u) * (1.0 + u) * tau
    else:
        raise ValueError(f"unknown formulation {form!r}")
    with np.errstate(over="ignore", invalid="ignore"):
        return T * (np.expm1(dtau) + v * np.exp(dtau)) + 2.0 * eta


def exact_transmittance(x: np.ndarray, used: np.ndarray) -> np.ndarray:
    """exp(-sum of x[r, :used[r]]) (each clamped to X_MAX), in mpmath."""
    out = np.zeros(len(x))
    with mpmath.workdps(40):
        for r in range(len(x)):
            out[r] = float(mpmath.exp(-mpmath.fsum(mpmath.mpf(min(float(v), X_MAX)) for v in x[r, : used[r]])))
    return out


# ------------------------------------------------------------------ media
def adversarial_media() -> dict:
    """Named sets of rays [R, K] of optical depths and colours: the extremes
    of sigma (1e-5 .. 1e5 per canvas unit) and of segment length that a
    40 km canvas with 0.3 mm cells holds."""
    rng_u = lambda i: ((np.arange(i) * 0x9E3779B9 + 0x7F4A7C15) % 2**32) / 2**32
    media = {}
    # A haze: 4,096 thin segments of the same small depth (a long ray
    # through a translucent fog of fine cells), total depth 0.41.
    n = 4096
    x = np.full((4, n), 1e-4)
    x[1] *= 0.1
    x[2] *= 10.0
    x[3] = 1e-4 * (0.5 + rng_u(n))
    c = np.broadcast_to(np.array([0.8, 0.6, 0.4]), (4, n, 3)).copy()
    media["haze"] = (x, c)
    # A thin haze in front of a wall: tiny depths, then one dense cell.
    x = np.concatenate([np.full((1, 2000), 2e-5), np.array([[30.0]])], axis=1)
    c = np.zeros((1, 2001, 3))
    c[0, :2000] = [0.2, 0.4, 0.9]
    c[0, 2000] = [1.0, 0.9, 0.1]
    media["haze_then_wall"] = (x, c)
    # Log-uniform sigma 1e-5 .. 1e5 times log-uniform lengths 1e-8 .. 1e3
    # canvas units (depth 24 cells to kilometre-wide roots), clipped to
    # what a segment can carry (f64), 64 rays of 256 segments.
    R, K = 64, 256
    i = np.arange(R * K)
    s = 10.0 ** (-5 + 10 * rng_u(R * K))
    ell = 10.0 ** (-8 + 11 * ((i * 0x85EBCA6B + 0x165667B1) % 2**32 / 2**32))
    x = np.minimum(s * ell, 1e3).reshape(R, K)
    c = np.stack([rng_u(R * K), ((i * 0x27D4EB2F) % 2**32) / 2**32, ((i * 0x165667B1) % 2**32) / 2**32], -1).reshape(R, K, 3)
    media["log_uniform"] = (x, c)
    # Very short and very long segments alternating: depth 1e-7 and 2.
    x = np.tile(np.array([1e-7, 2.0]), (1, 64))
    c = np.tile(np.array([[0.1, 0.1, 0.1], [0.9, 0.2, 0.3]]), (1, 64, 1))
    media["short_long"] = (x, c)
    return media


def study(media: dict, formats=("f16", "bf16", "f32"), forms=FORMS) -> dict:
    """Per medium, format and formulation: the largest colour error in 8-bit
    steps, the largest transmittance error, and whether every ray is within
    transmittance_bound."""
    out = {}
    for name, (x, c) in media.items():
        cx, tx, _ = exact(x, c)
        for fmt in formats:
            for form in forms:
                col, T, used = composite(x, c, fmt, form)
                te = exact_transmittance(x, used)
                b = transmittance_bound(x, used, fmt, form)
                out[(name, fmt, form)] = {
                    "max_colour_steps": float(np.abs(col - cx).max() * 255.0),
                    "max_transmittance_error": float(np.abs(T - te).max()),
                    "within_bound_pct": 100.0 * float((np.abs(T - te) <= b).mean()),
                    "max_bound": float(b.max()),
                    "rays": len(x),
                }
    return out


def scene_segments(arrays: dict, rays, capacity: int = 512):
    """The segments the f64 local ray caster composites for `rays` in a dump
    (the precision study's scene): optical depths and colours [R, K]."""
    from .raycast import cast, device_tree

    tree, canvas = device_tree(arrays)
    s, rec = cast(tree, canvas, rays, "f64", "local", max_steps=capacity, record=capacity)
    K = rec.cell.shape[1]
    valid = np.arange(K)[None, :] < s.steps[:, None]
    cell = np.where(valid, rec.cell, 0).astype(np.int64)
    edge = canvas.root_size * np.exp2(-rec.depth.astype(np.float64))
    length = np.asarray(rec.t, np.float64) * edge
    sigma = np.asarray(arrays["sigma"], np.float64)[cell]
    x = np.where(valid, sigma * length, 0.0)
    rgb = np.asarray(arrays["rgb"], np.float64)[cell] / 255.0
    return x, rgb


def steps_8bit(v: float) -> str:
    return f"{v:.2g}" if v < 10 else f"{v:.0f}"


def table(results: dict) -> str:
    """Markdown: one row per medium and format, one column per formulation
    (colour error in 8-bit steps / transmittance error / % within bound)."""
    media = list(dict.fromkeys(k[0] for k in results))
    fmts = list(dict.fromkeys(k[1] for k in results))
    lines = ["| medium | format | " + " | ".join(FORMS) + " |", "| --- | --- |" + " --- |" * len(FORMS)]
    for m in media:
        for f in fmts:
            cells = []
            for form in FORMS:
                v = results.get((m, f, form))
                cells.append("-" if v is None else f"{steps_8bit(v['max_colour_steps'])} / {v['max_transmittance_error']:.1g} / {v['within_bound_pct']:.0f}%")
            lines.append(f"| {m} ({results[(m, f, FORMS[0])]['rays']} rays) | {f} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"

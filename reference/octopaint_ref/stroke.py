"""From trace samples to brush primitives (spec 8.3-8.4).

A sphere stroke is a chain of tapered capsules, one per segment between
consecutive samples (the first sample alone is a sphere). Every other shape
is stamped along the path every `spacing * r` of arc length. Each `sample`
event produces one segment: a `Prims` batch of one capsule or of zero or more
stamps. Painter twin: painter/paint/src/stroke.rs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .brush import RADIUS_PRESSURE_FLOOR, TINY, mirrored, nlerp, quat_to_matrix, stamp_extent
from .trace import Brush, Sample


@dataclass
class Prims:
    """k primitives of one shape. For capsules (shape "sphere"): p0, p1
    [k, 3], r0, r1, f0, f1 [k], open [k] (bool: an open start, spec 8.3). For stamps: c [k, 3], r, f [k], rot [k, 3, 3].
    colour [k, 3] is the brush colour each primitive paints with; lo, hi
    [k, 3] bound the primitive (coverage is zero outside)."""

    shape: str
    arrays: dict
    colour: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def __len__(self) -> int:
        return len(self.colour)

    def take(self, idx) -> Prims:
        return Prims(self.shape, {k: v[idx] for k, v in self.arrays.items()}, self.colour[idx], self.lo[idx], self.hi[idx])



def concat(parts: list) -> Prims:
    """One batch of the primitives of `parts` (same shape), in order."""
    parts = [p for p in parts if len(p)] or parts[:1]
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    return Prims(
        first.shape,
        {n: np.concatenate([p.arrays[n] for p in parts]) for n in first.arrays},
        np.concatenate([p.colour for p in parts]),
        np.concatenate([p.lo for p in parts]),
        np.concatenate([p.hi for p in parts]),
    )


class PrimsHistory:
    """Every primitive of the stroke so far, in growable arrays (appending a
    segment is amortised O(segment), not O(stroke))."""

    def __init__(self):
        self.n = 0
        self.store: Prims | None = None

    def append(self, p: Prims) -> None:
        k = len(p)
        if k == 0:
            return
        if self.store is None:
            cap = max(64, 2 * k)
            grow = lambda a: np.zeros((cap,) + a.shape[1:], a.dtype)
            self.store = Prims(p.shape, {n: grow(a) for n, a in p.arrays.items()}, grow(p.colour), grow(p.lo), grow(p.hi))
        elif self.n + k > len(self.store.colour):
            cap = 2 * (self.n + k)

            def grown(a):
                b = np.zeros((cap,) + a.shape[1:], a.dtype)
                b[: self.n] = a[: self.n]
                return b

            s = self.store
            self.store = Prims(s.shape, {n: grown(a) for n, a in s.arrays.items()}, grown(s.colour), grown(s.lo), grown(s.hi))
        s, sl = self.store, slice(self.n, self.n + k)
        for n, a in p.arrays.items():
            s.arrays[n][sl] = a
        s.colour[sl] = p.colour
        s.lo[sl] = p.lo
        s.hi[sl] = p.hi
        self.n += k

    def view(self) -> Prims | None:
        return None if self.n == 0 else self.store.take(slice(0, self.n))


def pressure_radius(brush: Brush, pressure: float) -> float:
    return brush.radius * (RADIUS_PRESSURE_FLOOR + (1.0 - RADIUS_PRESSURE_FLOOR) * pressure)


class StrokePath:
    """Turns the samples of one stroke into segments; `mask` (spec 8.11):
    the mirrored copy of the stroke through those planes of the brush's
    mirror (0: the stroke itself)."""

    def __init__(self, brush: Brush, mask: int = 0):
        self.brush = brush
        self.mask = mask
        self.prev = None  # (p, r, f, q) of the previous sample
        self.last = None  # (r0, r1, f0, f1) of the last capsule (sphere brushes)
        self.carry = 0.0  # arc length from the previous sample to the next stamp
        self.extent = stamp_extent(brush.shape, brush.aspect)
        # Rows of each stamp's rotation negated on the mirrored axes: local
        # to canvas becomes S.R, the mirror image, exactly.
        self.flip = np.array([-1.0 if mask >> a & 1 else 1.0 for a in range(3)])

    def segment(self, sample: Sample, colour: np.ndarray) -> Prims:
        b = self.brush
        p = np.array(sample.p, np.float64)
        if self.mask:
            p = mirrored(p, self.mask, b.mirror.centre)
        r = pressure_radius(b, sample.pressure)
        f = float(sample.pressure)
        q = np.array(sample.q, np.float64)
        prev = self.prev
        self.prev = (p, r, f, q)
        if b.shape == "sphere":
            p0, r0, f0 = (p, r, f) if prev is None else prev[:3]
            # The start is open (spec 8.3) when the capsule is a segment and
            # the last one neither grows nor gains flow toward its end.
            last = self.last
            d = p - p0
            dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
            is_open = last is not None and dd >= TINY and last[0] >= last[1] and last[2] >= last[3]
            self.last = (r0, r, f0, f)
            lo = np.minimum(p0, p) - max(r0, r)
            hi = np.maximum(p0, p) + max(r0, r)
            arrays = {
                "p0": p0[None, :],
                "p1": p[None, :],
                "r0": np.array([r0]),
                "r1": np.array([r]),
                "f0": np.array([f0]),
                "f1": np.array([f]),
                "open": np.array([is_open]),
            }
            return Prims("sphere", arrays, colour[None, :], lo[None, :], hi[None, :])
        stamps = []  # (c, r, f, q)
        if prev is None:
            stamps.append((p, r, f, q))
            self.carry = b.spacing * r
        else:
            pa, ra, fa, qa = prev
            d = p - pa
            length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            if length > 0:
                s = self.carry
                while s <= length:
                    u = s / length
                    ru = ra + (r - ra) * u
                    stamps.append((pa + d * u, ru, fa + (f - fa) * u, nlerp(qa, q, u)))
                    s = s + b.spacing * ru
                self.carry = s - length
        k = len(stamps)
        c = np.array([s[0] for s in stamps], np.float64).reshape(k, 3)
        rr = np.array([s[1] for s in stamps], np.float64)
        ff = np.array([s[2] for s in stamps], np.float64)
        rot = np.array([quat_to_matrix(s[3]) for s in stamps], np.float64).reshape(k, 3, 3) * self.flip[None, :, None]
        ext = (rr * self.extent)[:, None]
        return Prims(
            b.shape,
            {"c": c, "r": rr, "f": ff, "rot": rot, "m": np.full(k, self.mask, np.int64)},
            np.repeat(colour[None, :], k, axis=0),
            c - ext,
            c + ext,
        )

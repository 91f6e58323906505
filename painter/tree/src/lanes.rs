//! The 8 children of a unit against capsules and stamps, at once in vector
//! registers: the paint pass's projection, reach test and coverage of a
//! unit whose children are all leaves, the stroke maximum of a unit's new
//! children, for capsules (sphere brushes) and for the stamps of box,
//! cylinder and cone brushes (noise stamps keep their scalar noise factor),
//! and the settled test's coverage bounds of 8 leaves.
//!
//! 8 lanes fill two AVX registers of 4; each kernel is written over the
//! 8-lane operations of `avx` (`V`, its comparison mask `M`, and `add`,
//! `select`, `bits` and the rest), so both halves go through each step
//! together. Every lane goes through the IEEE operations of the scalar
//! forms in [`crate::brush`] in the same order (a division is a division,
//! a square root a square root, nothing fused), so each lane holds the bits
//! the scalar form gives: the tests below compare them on random and
//! degenerate inputs. Processors without AVX, and other architectures, get
//! `None` and the callers take their per-cell path.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;

use crate::brush::{Capsule, Stamp, StampReach};
use crate::stroke::Prim;
use crate::trace::Shape;

/// Points a kernel takes: a unit's children.
pub const LANES: usize = 8;

/// A capsule at a unit's 8 children (the paint pass): per lane, the local
/// radius `r(u)` at the projection, whether a cell of half-diagonal `h`
/// there is within reach ([`Capsule::within_reach`]; bit k of `reach`:
/// lane k), and its coverage·flow `a` ([`Capsule::coverage_at`], 0 outside
/// the primitive's box).
#[derive(Clone, Copy, Debug)]
pub struct UnitCoverage {
    pub r: [f64; LANES],
    pub reach: u8,
    pub a: [f64; LANES],
}

/// The stroke maximum at a unit's 8 new children: per lane what
/// `stroke_maximum_with` gives (`a`, 0 or at least TINY, and the first
/// primitive `k` attaining it, any when `a` is 0), and for the segment's
/// capsule the local radius and reach (bit k: lane k), as in
/// [`UnitCoverage`].
#[derive(Clone, Copy, Debug)]
pub struct UnitMaximum {
    pub a: [f64; LANES],
    pub k: [u32; LANES],
    pub seg_r: [f64; LANES],
    pub seg_reach: u8,
}

static ENABLED: AtomicBool = AtomicBool::new(true);

/// Switch the kernels off (or on again): the callers then take their
/// per-cell path, which must give the same bytes (tests/lanes.rs checks
/// it on every trace; `octopaint bench tree --no-lanes` times it).
pub fn set_enabled(on: bool) {
    ENABLED.store(on, Ordering::Relaxed);
}

/// Whether the kernels run here (else they return `None`): switched on and
/// an x86-64 processor with AVX.
#[inline]
pub fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        ENABLED.load(Ordering::Relaxed) && std::arch::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Some of `avx::$kernel(args)` where the kernels run, else None.
macro_rules! kernel {
    ($kernel:ident($($arg:expr),* $(,)?)) => {{
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY: the processor has AVX.
            available().then(|| unsafe { avx::$kernel($($arg),*) })
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = ($($arg),*);
            None
        }
    }};
}

/// The paint pass's [`UnitCoverage`] of `cap` (the primitive `prim`) at
/// the centres `xs`, for cells of half-diagonal `h`.
#[inline]
pub fn unit_coverage(cap: &Capsule, prim: &Prim, hardness: f64, xs: &[DVec3; LANES], h: f64) -> Option<UnitCoverage> {
    kernel!(unit_coverage(cap, prim, hardness, xs, h))
}

/// A stamp of a box, cylinder or cone brush (`shape`, `aspect`, `geo`) at a
/// unit's 8 children, as [`UnitCoverage`]: per lane [`Stamp::reach`],
/// [`Stamp::gauge`] through `coverage_profile` times the stamp's flow (0
/// outside the primitive's box), and the stamp's radius. None for a noise
/// stamp (its noise factor stays scalar) and where the kernels do not run.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn unit_stamp(
    st: &Stamp,
    shape: Shape,
    aspect: [f64; 3],
    geo: &StampReach,
    prim: &Prim,
    hardness: f64,
    xs: &[DVec3; LANES],
    h: f64,
) -> Option<UnitCoverage> {
    if shape == Shape::Noise || shape == Shape::Sphere {
        return None;
    }
    kernel!(unit_stamp(st, shape, aspect, geo, prim, hardness, xs, h))
}

/// The stroke maximum over `prims` (box, cylinder or cone stamps of a
/// brush of `shape` and `aspect`, in stroke order; anything else panics)
/// at a unit's 8 centres `xs`, as the scalar stroke maximum gives it: per
/// lane `a` (0 or at least TINY) and the first primitive attaining it (any
/// when `a` is 0). None for noise brushes and where the kernels do not run.
#[inline]
pub fn unit_stamp_maximum(prims: &[Prim], shape: Shape, aspect: [f64; 3], hardness: f64, xs: &[DVec3; LANES]) -> Option<([f64; LANES], [u32; LANES])> {
    if shape == Shape::Noise || shape == Shape::Sphere {
        return None;
    }
    kernel!(unit_stamp_maximum(prims, shape, aspect, hardness, xs))
}

/// [`Capsule::within_reach`] of `cap` at the centres `xs` of cells of
/// half-diagonal `h`, as a mask (bit k: lane k within reach): the paint
/// pass's test of a unit's children that are not all leaves.
#[inline]
pub fn unit_reach(cap: &Capsule, xs: &[DVec3; LANES], h: f64) -> Option<u8> {
    kernel!(unit_reach(cap, xs, h))
}

/// The [`UnitMaximum`] over `prims` (capsules, in stroke order; a stamp
/// panics) at the centres `xs` of new cells of half-diagonal `h`; `seg` is
/// the segment's capsule, and `seg_is_last` says it is the last of `prims`
/// too (its projection then serves both).
#[inline]
pub fn unit_maximum(prims: &[Prim], hardness: f64, seg: &Capsule, seg_is_last: bool, xs: &[DVec3; LANES], h: f64) -> Option<UnitMaximum> {
    kernel!(unit_maximum(prims, hardness, seg, seg_is_last, xs, h))
}

/// The settled test's bounds of coverage·flow (spec 8.7) at 8 leaves at
/// once: lane k is the ball of radius `hs[k]` about `xs[k]`, whose bounds
/// so far are `[lo0[k], hi0[k]]` over the stroke's primitives before
/// `from[k]`. Each capsule of `caps` (with its index in the stroke,
/// ascending) from `from[k]` on whose box meets the ball raises them to
/// `Capsule::coverage_bounds` there, as `Painting::settled` folds them, a
/// lane turning NaN (and folding no more) at a negative or NaN bound. A
/// lane whose `lo0` is NaN is left as it is.
#[inline]
pub fn unit_settle_bounds(
    caps: &[(u32, Prim)],
    xs: &[DVec3; LANES],
    hs: &[f64; LANES],
    from: &[u32; LANES],
    lo0: &[f64; LANES],
    hi0: &[f64; LANES],
    hardness: f64,
) -> Option<([f64; LANES], [f64; LANES])> {
    kernel!(unit_settle_bounds(caps, xs, hs, from, lo0, hi0, hardness))
}

/// `v` is a power of two whose reciprocal is a normal number too.
#[inline]
fn power_of_two(v: f64) -> bool {
    v.is_normal() && v > 0.0 && v.to_bits() & ((1u64 << 52) - 1) == 0 && (1.0 / v).is_normal()
}

/// The centres' box, NaN coordinates left out (f64::min, unlike glam's,
/// ignores a NaN): a NaN centre holds nothing anyway.
fn centre_box(xs: &[DVec3; LANES]) -> (DVec3, DVec3) {
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for x in xs {
        lo = DVec3::new(lo.x.min(x.x), lo.y.min(x.y), lo.z.min(x.z));
        hi = DVec3::new(hi.x.max(x.x), hi.y.max(x.y), hi.z.max(x.z));
    }
    (lo, hi)
}

/// The lane operations at AVX: 8 lanes in two registers of 4, a mask a
/// vector whose lanes are all ones or all zeros.
#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;

    use glam::DVec3;

    use super::{LANES, UnitCoverage, UnitMaximum, centre_box, power_of_two};
    use crate::brush::{Capsule, Stamp, StampReach, TINY};
    use crate::stroke::{Geometry, Prim};
    use crate::trace::Shape;

    #[derive(Clone, Copy)]
    struct V([__m256d; 2]);

    type M = V;

    /// Both halves through `f`.
    #[inline(always)]
    fn each(a: V, f: impl Fn(__m256d) -> __m256d) -> V {
        V([f(a.0[0]), f(a.0[1])])
    }

    #[inline(always)]
    fn both(a: V, b: V, f: impl Fn(__m256d, __m256d) -> __m256d) -> V {
        V([f(a.0[0], b.0[0]), f(a.0[1], b.0[1])])
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn lanes(xs: &[DVec3; LANES], f: fn(&DVec3) -> f64) -> V {
        let half = |i: usize| _mm256_set_pd(f(&xs[i + 3]), f(&xs[i + 2]), f(&xs[i + 1]), f(&xs[i]));
        V([half(0), half(4)])
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn splat(v: f64) -> V {
        V([_mm256_set1_pd(v); 2])
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn zero() -> V {
        V([_mm256_setzero_pd(); 2])
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn no_lanes() -> M {
        zero()
    }

    /// Operations on both halves, one AVX instruction each.
    macro_rules! halves {
        ($($(#[$doc:meta])* fn $name:ident($a:ident: $ta:ty, $b:ident: $tb:ty) -> $out:ty = $op:expr;)*) => {$(
            $(#[$doc])*
            #[inline]
            #[target_feature(enable = "avx")]
            fn $name($a: $ta, $b: $tb) -> $out {
                both($a, $b, |a, b| $op(a, b))
            }
        )*};
    }

    halves! {
        fn add(a: V, b: V) -> V = _mm256_add_pd;
        fn sub(a: V, b: V) -> V = _mm256_sub_pd;
        fn mul(a: V, b: V) -> V = _mm256_mul_pd;
        fn div(a: V, b: V) -> V = _mm256_div_pd;
        /// `maxpd`: the second operand when either is NaN.
        fn max(a: V, b: V) -> V = _mm256_max_pd;
        fn lt(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_LT_OQ>;
        fn le(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_LE_OQ>;
        fn gt(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_GT_OQ>;
        fn ge(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_GE_OQ>;
        fn unord(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_UNORD_Q>;
        fn and(m: M, n: M) -> M = _mm256_and_pd;
        fn or(m: M, n: M) -> M = _mm256_or_pd;
        /// `n` and not `m`.
        fn and_not(m: M, n: M) -> M = _mm256_andnot_pd;
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn sqrt(a: V) -> V {
        each(a, |a| _mm256_sqrt_pd(a))
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn abs(a: V) -> V {
        each(a, |a| _mm256_and_pd(a, _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX))))
    }

    /// The sign bit flipped.
    #[inline]
    #[target_feature(enable = "avx")]
    fn neg(a: V) -> V {
        each(a, |a| _mm256_xor_pd(a, _mm256_set1_pd(-0.0)))
    }

    /// `v` where `m` is set, else +0.
    #[inline]
    #[target_feature(enable = "avx")]
    fn keep(m: M, v: V) -> V {
        and(m, v)
    }

    /// `v`, with +0 where `m` is set.
    #[inline]
    #[target_feature(enable = "avx")]
    fn zero_where(m: M, v: V) -> V {
        and_not(m, v)
    }

    /// `set` where `m` is set, else `clear`. Written with bitwise
    /// operations, not `blendv`: a comparison's lanes are all ones or all
    /// zeros, which the compiler does not see through a `blendv` under AVX
    /// without AVX2 (it tests each lane's sign with 128-bit integer
    /// compares instead, and the kernels ran 10% slower).
    #[inline]
    #[target_feature(enable = "avx")]
    fn select(m: M, set: V, clear: V) -> V {
        or(and(m, set), and_not(m, clear))
    }

    /// Bit k: lane k of `m` is set.
    #[inline]
    #[target_feature(enable = "avx")]
    fn bits(m: M) -> u8 {
        (_mm256_movemask_pd(m.0[0]) | _mm256_movemask_pd(m.0[1]) << 4) as u8
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn load(v: &[f64; LANES]) -> V {
        // SAFETY: 4 lanes at 0 and at 4 of an array of 8.
        unsafe { V([_mm256_loadu_pd(v.as_ptr()), _mm256_loadu_pd(v.as_ptr().add(4))]) }
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn store(out: &mut [f64; LANES], v: V) {
        // SAFETY: 4 lanes at 0 and at 4 of an array of 8.
        unsafe {
            _mm256_storeu_pd(out.as_mut_ptr(), v.0[0]);
            _mm256_storeu_pd(out.as_mut_ptr().add(4), v.0[1]);
        }
    }

    /// `Capsule::project` of 8 points.
    struct Projection {
        dist: V,
        u: V,
        r: V,
        t: V,
        w1: V,
    }

    /// The lanes' coordinates.
    struct Points {
        x: V,
        y: V,
        z: V,
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn points(xs: &[DVec3; LANES]) -> Points {
        Points { x: lanes(xs, |p| p.x), y: lanes(xs, |p| p.y), z: lanes(xs, |p| p.z) }
    }

    /// `v.clamp(0.0, 1.0)` as Rust computes it: below 0 gives 0, above 1
    /// gives 1, NaN stays NaN.
    #[inline]
    #[target_feature(enable = "avx")]
    fn clamp01(v: V) -> V {
        let v = zero_where(lt(v, zero()), v);
        select(gt(v, splat(1.0)), splat(1.0), v)
    }

    /// `sqrt(s)` where `s > 0`, else +0 (a NaN `s` included).
    #[inline]
    #[target_feature(enable = "avx")]
    fn sqrt_positive(s: V) -> V {
        keep(gt(s, zero()), sqrt(s))
    }

    /// `f64::max` as Rust computes it: a NaN argument gives the other.
    /// (`max` gives its second operand when either is NaN.)
    #[inline]
    #[target_feature(enable = "avx")]
    fn max_nan_ignored(a: V, b: V) -> V {
        select(unord(b, b), a, max(a, b))
    }

    /// `Capsule::project`, operation for operation.
    #[inline]
    #[target_feature(enable = "avx")]
    fn project(c: &Capsule, p: &Points) -> Projection {
        let (p0, d) = (c.p0, c.d);
        let wx = sub(p.x, splat(p0.x));
        let wy = sub(p.y, splat(p0.y));
        let wz = sub(p.z, splat(p0.z));
        let t = add(add(mul(wx, splat(d.x)), mul(wy, splat(d.y))), mul(wz, splat(d.z)));
        let u = if c.dd >= TINY { clamp01(div(t, splat(c.dd))) } else { zero() };
        let ex = sub(p.x, add(splat(p0.x), mul(splat(d.x), u)));
        let ey = sub(p.y, add(splat(p0.y), mul(splat(d.y), u)));
        let ez = sub(p.z, add(splat(p0.z), mul(splat(d.z), u)));
        let dist = sqrt_positive(add(add(mul(ex, ex), mul(ey, ey)), mul(ez, ez)));
        let r = add(splat(c.r0), mul(splat(c.r1 - c.r0), u));
        let w1 = add(add(abs(wx), abs(wy)), abs(wz));
        Projection { dist, u, r, t, w1 }
    }

    /// `Capsule::coverage_at` (with `coverage_profile`), as selects.
    #[inline]
    #[target_feature(enable = "avx")]
    fn coverage(c: &Capsule, p: &Projection, hardness: f64) -> V {
        let flow = add(splat(c.f0), mul(splat(c.f1 - c.f0), p.u));
        let cov = mul(profile(div(p.dist, p.r), hardness), flow);
        // Behind an open start: exactly 0 (spec 8.3).
        if c.open { zero_where(lt(p.t, zero()), cov) } else { cov }
    }

    /// `coverage_profile(rho, hardness)`, as selects.
    #[inline]
    #[target_feature(enable = "avx")]
    fn profile(rho: V, hardness: f64) -> V {
        let span = 1.0 - hardness;
        let safe = if span > 0.0 { span } else { 1.0 };
        let above = sub(splat(1.0), rho);
        // Dividing by a power of two is multiplying by its reciprocal, bit
        // for bit (both round the same exact quotient): hardness 0 and 0.5
        // (1 and 1/2 here) save a division a lane.
        let t = clamp01(if power_of_two(safe) { mul(above, splat(1.0 / safe)) } else { div(above, splat(safe)) });
        let smooth = mul(mul(t, t), sub(splat(3.0), mul(splat(2.0), t)));
        let profile = select(le(rho, splat(hardness)), splat(1.0), smooth);
        zero_where(ge(rho, splat(1.0)), profile)
    }

    /// `Capsule::within_reach` for cells of half-diagonal `h`: a mask.
    #[inline]
    #[target_feature(enable = "avx")]
    fn within_reach(c: &Capsule, p: &Projection, h: f64) -> M {
        let near = le(sub(p.dist, p.r), splat(h * c.slack));
        if !c.open {
            return near;
        }
        // -(h·dn + 1e-12·(w1 + h)·dn); the negation flips the sign bit.
        let margin = add(splat(h * c.dn), mul(mul(splat(1e-12), add(p.w1, splat(h))), splat(c.dn)));
        and_not(lt(p.t, neg(margin)), near)
    }

    /// `Prim::holds` of the lanes: a mask.
    #[inline]
    #[target_feature(enable = "avx")]
    fn holds(b: &Prim, p: &Points) -> M {
        let lo = and(and(le(splat(b.lo.x), p.x), le(splat(b.lo.y), p.y)), le(splat(b.lo.z), p.z));
        let hi = and(and(le(p.x, splat(b.hi.x)), le(p.y, splat(b.hi.y))), le(p.z, splat(b.hi.z)));
        and(lo, hi)
    }

    #[target_feature(enable = "avx")]
    pub(super) fn unit_coverage(cap: &Capsule, prim: &Prim, hardness: f64, xs: &[DVec3; LANES], h: f64) -> UnitCoverage {
        let pts = points(xs);
        let p = project(cap, &pts);
        let mut o = UnitCoverage { r: [0.0; LANES], reach: bits(within_reach(cap, &p, h)), a: [0.0; LANES] };
        store(&mut o.r, p.r);
        // 0 outside the primitive's box (spec 8.5): +0 where the mask is clear.
        store(&mut o.a, keep(holds(prim, &pts), coverage(cap, &p, hardness)));
        o
    }

    #[target_feature(enable = "avx")]
    pub(super) fn unit_reach(cap: &Capsule, xs: &[DVec3; LANES], h: f64) -> u8 {
        bits(within_reach(cap, &project(cap, &points(xs)), h))
    }

    /// A stamp's local coordinates and gauge at the lanes
    /// (`Stamp::local`, then `Stamp::gauge_local`): `(rho, lz, radial,
    /// cone side)`, the last three for the reach test.
    #[inline]
    #[target_feature(enable = "avx")]
    fn stamp_gauge(st: &Stamp, shape: Shape, aspect: [f64; 3], p: &Points) -> (V, [V; 3], V, V) {
        let r = st.r;
        let (arx, ary, arz) = (aspect[0] * r, aspect[1] * r, aspect[2] * r);
        // x − c, then each row's dot product, summed left to right.
        let (vx, vy, vz) = (sub(p.x, splat(st.c.x)), sub(p.y, splat(st.c.y)), sub(p.z, splat(st.c.z)));
        let dot = |m: DVec3| add(add(mul(splat(m.x), vx), mul(splat(m.y), vy)), mul(splat(m.z), vz));
        let l = [dot(st.rot.x_axis), dot(st.rot.y_axis), dot(st.rot.z_axis)];
        let (nx, ny, nz) = (div(l[0], splat(arx)), div(l[1], splat(ary)), div(l[2], splat(arz)));
        if shape == Shape::Box {
            let rho = max_nan_ignored(max_nan_ignored(abs(nx), abs(ny)), abs(nz));
            return (rho, l, zero(), zero());
        }
        let radial = sqrt_positive(add(mul(nx, nx), mul(ny, ny)));
        let cone_side = add(mul(splat(2.0), radial), nz);
        let rho = if shape == Shape::Cylinder { max_nan_ignored(radial, abs(nz)) } else { max_nan_ignored(abs(nz), cone_side) };
        (rho, l, radial, cone_side)
    }

    #[target_feature(enable = "avx")]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn unit_stamp(
        st: &Stamp,
        shape: Shape,
        aspect: [f64; 3],
        geo: &StampReach,
        prim: &Prim,
        hardness: f64,
        xs: &[DVec3; LANES],
        h: f64,
    ) -> UnitCoverage {
        let pts = points(xs);
        let r = st.r;
        let (arx, ary, arz) = (aspect[0] * r, aspect[1] * r, aspect[2] * r);
        let (rho, l, radial, cone_side) = stamp_gauge(st, shape, aspect, &pts);
        // `Stamp::reach_local`, from the same coordinates and quotients.
        let reach = if shape == Shape::Box {
            and(and(le(abs(l[0]), splat(arx + h)), le(abs(l[1]), splat(ary + h))), le(abs(l[2]), splat(arz + h)))
        } else {
            let inside = and(le(radial, splat(1.0 + h / (geo.m * r))), le(abs(l[2]), splat(arz + h)));
            if shape == Shape::Cylinder { inside } else { and(inside, le(cone_side, splat(1.0 + h * geo.lip / r))) }
        };
        let mut o = UnitCoverage { r: [r; LANES], reach: bits(reach), a: [0.0; LANES] };
        // 0 outside the primitive's box (spec 8.5): +0 where the mask is clear.
        store(&mut o.a, keep(holds(prim, &pts), mul(profile(rho, hardness), splat(st.f))));
        o
    }

    /// A stroke maximum under way at the lanes, as `stroke_maximum_with`
    /// folds it: the largest coverage so far and the index of the first
    /// primitive attaining it (a later one must exceed it), and the lanes
    /// a NaN coverage has poisoned.
    struct Maximum {
        best: V,
        best_k: V,
        nan: M,
    }

    impl Maximum {
        #[inline]
        #[target_feature(enable = "avx")]
        fn new() -> Maximum {
            Maximum { best: zero(), best_k: zero(), nan: no_lanes() }
        }

        /// Fold in primitive `i`'s coverage `cov`, in the lanes its box
        /// holds (`inside`).
        #[inline]
        #[target_feature(enable = "avx")]
        fn fold(&mut self, i: usize, cov: V, inside: M) {
            self.nan = or(self.nan, and(inside, unord(cov, cov)));
            let up = and(inside, gt(cov, self.best));
            self.best = select(up, cov, self.best);
            self.best_k = select(up, splat(i as f64), self.best_k);
        }

        /// The maximum (0 below TINY and where poisoned) and its
        /// primitive's index.
        #[inline]
        #[target_feature(enable = "avx")]
        fn finish(self) -> ([f64; LANES], [u32; LANES]) {
            let (mut a, mut k) = ([0.0; LANES], [0.0; LANES]);
            store(&mut a, zero_where(or(self.nan, lt(self.best, splat(TINY))), self.best));
            store(&mut k, self.best_k);
            (a, k.map(|v| v as u32))
        }
    }

    /// The stroke maximum over stamps (box, cylinder or cone) at a unit's
    /// 8 centres, as `stroke_maximum_with` gives it: `a` 0 or at least
    /// TINY, a NaN coverage poisoning the lane to 0, and the first stamp
    /// attaining it.
    #[target_feature(enable = "avx")]
    pub(super) fn unit_stamp_maximum(prims: &[Prim], shape: Shape, aspect: [f64; 3], hardness: f64, xs: &[DVec3; LANES]) -> ([f64; LANES], [u32; LANES]) {
        let pts = points(xs);
        let (lo, hi) = centre_box(xs);
        let mut m = Maximum::new();
        for (i, p) in prims.iter().enumerate() {
            if !p.overlaps(lo, hi) {
                continue; // its box holds none of the 8 centres
            }
            let Geometry::Stamp(st) = &p.geo else { panic!("unit_stamp_maximum takes stamps only") };
            let cov = mul(profile(stamp_gauge(st, shape, aspect, &pts).0, hardness), splat(st.f));
            m.fold(i, cov, holds(p, &pts));
        }
        m.finish()
    }

    #[target_feature(enable = "avx")]
    pub(super) fn unit_maximum(prims: &[Prim], hardness: f64, seg: &Capsule, seg_is_last: bool, xs: &[DVec3; LANES], h: f64) -> UnitMaximum {
        let pts = points(xs);
        let (lo, hi) = centre_box(xs);
        let sp = project(seg, &pts);
        let mut o = UnitMaximum { a: [0.0; LANES], k: [0; LANES], seg_r: [0.0; LANES], seg_reach: bits(within_reach(seg, &sp, h)) };
        store(&mut o.seg_r, sp.r);
        let mut m = Maximum::new();
        for (i, p) in prims.iter().enumerate() {
            if !p.overlaps(lo, hi) {
                continue; // its box holds none of the 8 centres
            }
            let Geometry::Capsule(cap) = &p.geo else { panic!("unit_maximum takes capsules only") };
            let cov = if seg_is_last && i + 1 == prims.len() { coverage(cap, &sp, hardness) } else { coverage(cap, &project(cap, &pts), hardness) };
            m.fold(i, cov, holds(p, &pts));
        }
        (o.a, o.k) = m.finish();
        o
    }

    /// `Capsule::coverage_bounds` at the projections `p`, for balls of
    /// radii `h`.
    #[inline]
    #[target_feature(enable = "avx")]
    fn coverage_bounds(c: &Capsule, p: &Projection, h: V, hardness: f64) -> (V, V) {
        let hr = mul(h, splat(c.slack - 1.0));
        // `max` gives its second operand for a NaN, as f64::max gives 0 here.
        let rho_lo = div(max(sub(p.dist, h), zero()), add(p.r, hr));
        let r_lo = sub(p.r, hr);
        let rho_hi = select(gt(r_lo, zero()), div(add(p.dist, h), r_lo), splat(f64::INFINITY));
        let lo = mul(profile(rho_hi, hardness), splat(c.f0.min(c.f1)));
        let hi = mul(profile(rho_lo, hardness), splat(c.f0.max(c.f1)));
        (lo, hi)
    }

    /// `Prim::overlaps` of the balls' boxes `x ± h`: a mask.
    #[inline]
    #[target_feature(enable = "avx")]
    fn meets_balls(b: &Prim, p: &Points, h: V) -> M {
        let lo = and(and(ge(splat(b.hi.x), sub(p.x, h)), ge(splat(b.hi.y), sub(p.y, h))), ge(splat(b.hi.z), sub(p.z, h)));
        let hi = and(and(le(splat(b.lo.x), add(p.x, h)), le(splat(b.lo.y), add(p.y, h))), le(splat(b.lo.z), add(p.z, h)));
        and(lo, hi)
    }

    #[target_feature(enable = "avx")]
    pub(super) fn unit_settle_bounds(
        caps: &[(u32, Prim)],
        xs: &[DVec3; LANES],
        hs: &[f64; LANES],
        from: &[u32; LANES],
        lo0: &[f64; LANES],
        hi0: &[f64; LANES],
        hardness: f64,
    ) -> ([f64; LANES], [f64; LANES]) {
        let pts = points(xs);
        let h = load(hs);
        let from = load(&from.map(f64::from));
        let (mut a_lo, mut a_hi) = (load(lo0), load(hi0));
        // The lanes still folding: not NaN.
        let mut live = le(a_lo, a_lo);
        // A box around the 8 balls: a capsule whose box misses it meets
        // none of them.
        let (centres_lo, centres_hi) = centre_box(xs);
        let h_max = hs.iter().copied().fold(0.0, f64::max);
        let (lo, hi) = (centres_lo - h_max, centres_hi + h_max);
        for (i, p) in caps {
            let Geometry::Capsule(cap) = &p.geo else { continue };
            if !p.overlaps(lo, hi) {
                continue;
            }
            let m = and(live, and(ge(splat(f64::from(*i)), from), meets_balls(p, &pts, h)));
            if bits(m) == 0 {
                continue;
            }
            let (c_lo, c_hi) = coverage_bounds(cap, &project(cap, &pts), h, hardness);
            let ok = and(ge(c_lo, zero()), ge(c_hi, zero()));
            let bad = and_not(ok, m);
            let good = and(m, ok);
            a_lo = select(bad, splat(f64::NAN), select(good, max(a_lo, c_lo), a_lo));
            a_hi = select(good, max(a_hi, c_hi), a_hi);
            live = and_not(bad, live);
        }
        let (mut out_lo, mut out_hi) = ([0.0; LANES], [0.0; LANES]);
        store(&mut out_lo, a_lo);
        store(&mut out_hi, a_hi);
        (out_lo, out_hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brush::TINY;
    use crate::noise::hash32;
    use crate::stroke::Geometry;

    fn unit(seed: &mut u32) -> f64 {
        *seed = hash32(*seed);
        f64::from(*seed) / 4294967296.0
    }

    /// A point in the cube [-0.5, 0.5]³.
    fn jitter(seed: &mut u32) -> DVec3 {
        let x = unit(seed);
        let y = unit(seed);
        DVec3::new(x - 0.5, y - 0.5, unit(seed) - 0.5)
    }

    /// Random capsules: chains with open starts, points, zero and huge
    /// radii, NaN and infinite flows now and then.
    fn capsules(seed: &mut u32, n: usize) -> Vec<Prim> {
        let mut out: Vec<Prim> = Vec::new();
        let mut p = DVec3::new(10.0, 10.0, 10.0);
        let (mut r, mut f) = (3.0, 0.8);
        for i in 0..n {
            let kind = unit(seed);
            let q = if kind < 0.1 { p } else { p + jitter(seed) * 8.0 };
            let r1 = if kind > 0.97 { 0.0 } else { 0.5 + 5.0 * unit(seed) };
            let f1 = match (unit(seed) * 40.0) as u32 {
                0 => f64::NAN,
                1 => f64::INFINITY,
                2 => 0.0,
                _ => unit(seed),
            };
            let cap = match out.last() {
                Some(Prim { geo: Geometry::Capsule(prev), .. }) if i % 3 != 0 => Capsule::after(prev, q, r1, f1),
                _ => Capsule::new(p, q, r, r1, f, f1),
            };
            let (lo, hi) = cap.bounds();
            out.push(Prim { geo: Geometry::Capsule(cap), colour: [unit(seed), 0.5, 0.25], lo, hi });
            (p, r, f) = (q, r1, f1);
        }
        out
    }

    /// A unit's 8 centres near `at`, cell size `s`; some on box edges.
    fn centres(seed: &mut u32, at: DVec3, s: f64) -> [DVec3; LANES] {
        std::array::from_fn(|k| {
            let o = DVec3::new((k & 1) as f64, (k >> 1 & 1) as f64, (k >> 2 & 1) as f64) * s;
            at + o + DVec3::splat(0.5 * s)
        })
        .map(|x| if unit(seed) < 0.02 { DVec3::new(f64::NAN, x.y, x.z) } else { x })
    }

    #[test]
    fn the_kernels_run_on_this_machine() {
        // CI and development machines are x86-64 with AVX: the tests below
        // must compare the vector lanes, not find them missing.
        assert_eq!(available(), cfg!(target_arch = "x86_64"), "AVX kernels expected on x86-64");
    }

    #[test]
    fn unit_coverage_and_unit_reach_are_the_scalar_projection_reach_and_coverage() {
        let mut seed = 7;
        let mut compared = 0;
        for _ in 0..400 {
            let prims = capsules(&mut seed, 6);
            let hardness = [0.0, 0.5, 0.9, 1.0, 0.75, 0.3][(unit(&mut seed) * 6.0) as usize];
            for p in &prims {
                let Geometry::Capsule(cap) = &p.geo else { unreachable!() };
                for _ in 0..8 {
                    let s = [0.25, 1.0, 4.0][(unit(&mut seed) * 3.0) as usize];
                    let at = cap.p0 + jitter(&mut seed) * 16.0;
                    let xs = centres(&mut seed, at, s);
                    let h = s * 0.8660254037844386;
                    let Some(u) = unit_coverage(cap, p, hardness, &xs, h) else { return assert!(!available()) };
                    let reach = unit_reach(cap, &xs, h).expect("both kernels or neither");
                    for (l, x) in xs.iter().enumerate() {
                        let cp = cap.project(*x);
                        let a = if p.holds(*x) { cap.coverage_at(&cp, hardness) } else { 0.0 };
                        assert_eq!(u.r[l].to_bits(), cp.r.to_bits(), "r {l} {x:?}");
                        assert_eq!(u.reach >> l & 1 == 1, cap.within_reach(&cp, h), "reach {l} {x:?}");
                        assert_eq!(reach, u.reach, "unit_reach {x:?}");
                        assert_eq!(u.a[l].to_bits(), a.to_bits(), "a {l} {x:?}: {} {}", u.a[l], a);
                        compared += 1;
                    }
                }
            }
        }
        assert!(compared > 100_000);
    }

    /// The stamp kernel is the scalar reach and coverage of box, cylinder
    /// and cone stamps, lane for lane and bit for bit: random turns and
    /// aspects, units inside, across and outside the stamps and their boxes,
    /// NaN lanes, several hardnesses.
    #[test]
    fn unit_stamp_is_the_scalar_stamp_reach_and_coverage() {
        let mut seed = 17;
        let mut compared = 0;
        let mut covered = 0;
        for _ in 0..3000 {
            let shape = [Shape::Box, Shape::Cylinder, Shape::Cone][(unit(&mut seed) * 3.0) as usize];
            let aspect = [0.3 + unit(&mut seed), 0.3 + unit(&mut seed), 0.3 + unit(&mut seed)];
            let q = [unit(&mut seed) - 0.5, unit(&mut seed) - 0.5, unit(&mut seed) - 0.5, unit(&mut seed) - 0.5];
            let r = 0.05 + unit(&mut seed) * 3.0;
            let st = Stamp {
                c: jitter(&mut seed) * 50.0,
                r,
                f: [1.0, 0.85, unit(&mut seed), 0.0][(unit(&mut seed) * 4.0) as usize],
                rot: crate::brush::quat_to_matrix(q),
                mirror: 0,
            };
            let (lo, hi) = st.bounds(crate::brush::stamp_extent(shape, aspect));
            let prim = Prim { geo: Geometry::Stamp(st), colour: [1.0; 3], lo, hi };
            let geo = StampReach::new(aspect);
            let hardness = [0.55, 0.0, 0.5, 1.0, unit(&mut seed)][(unit(&mut seed) * 5.0) as usize];
            for _ in 0..6 {
                let s = r * [0.05, 0.3, 1.0][(unit(&mut seed) * 3.0) as usize];
                let at = st.c + jitter(&mut seed) * r * 2.0;
                let xs = centres(&mut seed, at, s);
                let h = s * 0.8660254037844386;
                let Some(u) = unit_stamp(&st, shape, aspect, &geo, &prim, hardness, &xs, h) else { return assert!(!available()) };
                for (l, &x) in xs.iter().enumerate() {
                    let a = if prim.holds(x) { crate::brush::coverage_profile(st.gauge(shape, aspect, x), hardness) * st.f } else { 0.0 };
                    assert_eq!(
                        (u.reach >> l & 1 == 1, u.a[l].to_bits(), u.r[l]),
                        (st.reach(shape, aspect, &geo, x, h), a.to_bits(), r),
                        "{shape:?} lane {l} at {x:?}: {} against {a}",
                        u.a[l]
                    );
                    compared += 1;
                    covered += usize::from(a > 0.0);
                }
            }
        }
        assert!(compared > 100_000 && covered > 10_000, "{compared} lanes, {covered} covered");
        assert!(
            unit_stamp(
                &Stamp { c: DVec3::ZERO, r: 1.0, f: 1.0, rot: glam::DMat3::IDENTITY, mirror: 0 },
                Shape::Noise,
                [1.0; 3],
                &StampReach::new([1.0; 3]),
                &capsules(&mut seed, 1)[0],
                0.5,
                &[DVec3::ZERO; LANES],
                1.0
            )
            .is_none()
        );
    }

    /// The stamps' stroke maximum at a unit's children is the scalar one:
    /// the first stamp attaining the largest coverage among those whose
    /// boxes hold the centre, below TINY 0, a NaN coverage (a NaN flow)
    /// poisoning the lane.
    #[test]
    fn unit_stamp_maximum_is_the_scalar_stroke_maximum() {
        let mut seed = 23;
        let mut hits = 0;
        for _ in 0..2000 {
            let shape = [Shape::Box, Shape::Cylinder, Shape::Cone][(unit(&mut seed) * 3.0) as usize];
            let aspect = [0.3 + unit(&mut seed), 0.3 + unit(&mut seed), 0.3 + unit(&mut seed)];
            let hardness = [0.55, 0.0, 1.0, unit(&mut seed)][(unit(&mut seed) * 4.0) as usize];
            let r = 0.5 + unit(&mut seed) * 2.0;
            let centre = jitter(&mut seed) * 20.0;
            let prims: Vec<Prim> = (0..1 + (unit(&mut seed) * 6.0) as usize)
                .map(|_| {
                    let q = [unit(&mut seed) - 0.5, unit(&mut seed) - 0.5, unit(&mut seed) - 0.5, unit(&mut seed) - 0.5];
                    let f = match (unit(&mut seed) * 30.0) as u32 {
                        0 => f64::NAN,
                        1 => 0.0,
                        2 => 1e-13,
                        _ => unit(&mut seed),
                    };
                    let st = Stamp { c: centre + jitter(&mut seed) * r, r: r * (0.5 + unit(&mut seed)), f, rot: crate::brush::quat_to_matrix(q), mirror: 0 };
                    let (lo, hi) = st.bounds(crate::brush::stamp_extent(shape, aspect));
                    Prim { geo: Geometry::Stamp(st), colour: [unit(&mut seed), 0.5, 0.25], lo, hi }
                })
                .collect();
            let at = centre + jitter(&mut seed) * r * 2.0;
            let size = r * [0.1, 0.4][(unit(&mut seed) * 2.0) as usize];
            let xs = centres(&mut seed, at, size);
            let Some((a, k)) = unit_stamp_maximum(&prims, shape, aspect, hardness, &xs) else { return assert!(!available()) };
            for (l, &x) in xs.iter().enumerate() {
                let (mut best, mut at) = (0.0, 0);
                let mut poisoned = false;
                for (i, p) in prims.iter().enumerate() {
                    let Geometry::Stamp(st) = &p.geo else { unreachable!() };
                    if !p.holds(x) {
                        continue;
                    }
                    let c = crate::brush::coverage_profile(st.gauge(shape, aspect, x), hardness) * st.f;
                    if c.is_nan() {
                        poisoned = true;
                        break;
                    }
                    if c > best {
                        (best, at) = (c, i);
                    }
                }
                let want = if poisoned || best < crate::brush::TINY { 0.0 } else { best };
                assert_eq!(a[l].to_bits(), want.to_bits(), "{shape:?} lane {l} at {x:?}: {} against {want}", a[l]);
                if want > 0.0 {
                    assert_eq!(k[l] as usize, at);
                    hits += 1;
                }
            }
        }
        assert!(hits > 3000, "{hits} lanes covered");
    }

    #[test]
    fn unit_maximum_is_the_scalar_stroke_maximum() {
        let mut seed = 99;
        let mut hits = 0;
        for _ in 0..2000 {
            let n = 1 + (unit(&mut seed) * 7.0) as usize;
            let prims = capsules(&mut seed, n);
            let hardness = [0.0, 0.5, 1.0, 0.75, 0.2][(unit(&mut seed) * 5.0) as usize];
            let Geometry::Capsule(seg) = prims.last().unwrap().geo else { unreachable!() };
            let s = [0.5, 2.0][(unit(&mut seed) * 2.0) as usize];
            let at = seg.p0 + jitter(&mut seed) * 12.0;
            let xs = centres(&mut seed, at, s);
            let h = s * 0.8660254037844386;
            // The segment is the last primitive, or (first case) not among them.
            for (near, seg_is_last) in [(&prims[..prims.len() - 1], false), (&prims[..], true)] {
                let Some(m) = unit_maximum(near, hardness, &seg, seg_is_last, &xs, h) else { return assert!(!available()) };
                for (l, &x) in xs.iter().enumerate() {
                    // The scalar stroke maximum (paint/walks.rs's, for capsules).
                    let (mut best, mut k) = (0.0, 0);
                    let mut poisoned = false;
                    for (i, p) in near.iter().enumerate() {
                        let Geometry::Capsule(cap) = &p.geo else { unreachable!() };
                        if !p.holds(x) {
                            continue;
                        }
                        let c = cap.coverage(x, hardness);
                        if c.is_nan() {
                            poisoned = true;
                            break;
                        }
                        if c > best {
                            (best, k) = (c, i);
                        }
                    }
                    let a = if poisoned || best < TINY { 0.0 } else { best };
                    assert_eq!(m.a[l].to_bits(), a.to_bits(), "lane {l} at {x:?}: {} against {}", m.a[l], a);
                    if a > 0.0 {
                        assert_eq!(m.k[l] as usize, k);
                        hits += 1;
                    }
                    let cp = seg.project(x);
                    assert_eq!(m.seg_r[l].to_bits(), cp.r.to_bits());
                    assert_eq!(m.seg_reach >> l & 1 == 1, seg.within_reach(&cp, h));
                }
            }
        }
        assert!(hits > 2000, "{hits} lanes covered");
    }

    /// The settled test's bounds at 8 leaves are the scalar fold, lane for
    /// lane and bit for bit: random capsule chains (NaN and infinite flows
    /// among them), balls inside, across and outside them, bounds carried
    /// from earlier primitives, NaN lanes left alone.
    #[test]
    fn unit_settle_bounds_is_the_scalar_fold() {
        let mut seed = 31;
        let mut folded = 0;
        for _ in 0..3000 {
            let n = 1 + (unit(&mut seed) * 8.0) as usize;
            let caps: Vec<(u32, Prim)> = capsules(&mut seed, n).into_iter().enumerate().map(|(i, p)| (i as u32, p)).collect();
            let hardness = [0.0, 0.5, 1.0, 0.8, 0.25][(unit(&mut seed) * 5.0) as usize];
            let Geometry::Capsule(first) = caps[0].1.geo else { unreachable!() };
            let s = [0.25, 1.0, 3.0][(unit(&mut seed) * 3.0) as usize];
            let at = first.p0 + jitter(&mut seed) * 14.0;
            let xs = centres(&mut seed, at, s);
            let hs: [f64; LANES] = std::array::from_fn(|_| s * [0.87, 1.73, 0.43][(unit(&mut seed) * 3.0) as usize]);
            let from: [u32; LANES] = std::array::from_fn(|_| if unit(&mut seed) < 0.7 { 0 } else { (unit(&mut seed) * n as f64) as u32 });
            let lo0: [f64; LANES] = std::array::from_fn(|_| match (unit(&mut seed) * 10.0) as u32 {
                0 => f64::NAN,
                1..=3 => unit(&mut seed) * 0.5,
                _ => 0.0,
            });
            let hi0: [f64; LANES] = std::array::from_fn(|k| if lo0[k] > 0.0 { lo0[k] + unit(&mut seed) * 0.3 } else { 0.0 });
            let Some((lo, hi)) = unit_settle_bounds(&caps, &xs, &hs, &from, &lo0, &hi0, hardness) else { return assert!(!available()) };
            for l in 0..LANES {
                let (a_lo, a_hi) =
                    if lo0[l].is_nan() { (lo0[l], hi0[l]) } else { crate::paint::settle_bounds(&caps, xs[l], hs[l], from[l], lo0[l], hi0[l], hardness) };
                folded += caps.iter().filter(|(i, p)| *i >= from[l] && p.overlaps(xs[l] - hs[l], xs[l] + hs[l])).count();
                // Bit for bit, but for the sign of a zero (the settled test
                // only compares the bounds, and a zero maximum blends to the
                // before-value either way).
                let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a == 0.0 && b == 0.0) || (a.is_nan() && b.is_nan());
                assert!(same(lo[l], a_lo) && same(hi[l], a_hi), "lane {l} at {:?} h {}: [{}, {}] against [{a_lo}, {a_hi}]", xs[l], hs[l], lo[l], hi[l]);
            }
        }
        assert!(folded > 20_000, "{folded} capsules folded");
    }
}

//! The 8 children of a unit against capsules and stamps, 4 points a vector
//! register (AVX): the paint pass's projection, reach test and coverage of
//! a unit whose children are all leaves, and the stroke maximum of a unit's
//! new children, for capsules (sphere brushes) and for the stamps of box,
//! cylinder and cone brushes (noise stamps keep their scalar noise factor).
//! Every lane goes through the IEEE operations of the scalar
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
/// there is within reach ([`Capsule::within_reach`]), and its coverage·flow
/// `a` ([`Capsule::coverage_at`], 0 outside the primitive's box).
#[derive(Clone, Copy, Debug)]
pub struct UnitCoverage {
    pub r: [f64; LANES],
    pub reach: [bool; LANES],
    pub a: [f64; LANES],
}

/// The stroke maximum at a unit's 8 new children: per lane what
/// `stroke_maximum_with` gives (`a`, 0 or at least TINY, and the first
/// primitive `k` attaining it, any when `a` is 0), and for the segment's
/// capsule the local radius and reach, as in [`UnitCoverage`].
#[derive(Clone, Copy, Debug)]
pub struct UnitMaximum {
    pub a: [f64; LANES],
    pub k: [u32; LANES],
    pub seg_r: [f64; LANES],
    pub seg_reach: [bool; LANES],
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

/// The paint pass's [`UnitCoverage`] of `cap` (the primitive `prim`) at
/// the centres `xs`, for cells of half-diagonal `h`.
#[inline]
pub fn unit_coverage(cap: &Capsule, prim: &Prim, hardness: f64, xs: &[DVec3; LANES], h: f64) -> Option<UnitCoverage> {
    #[cfg(target_arch = "x86_64")]
    {
        if available() {
            // SAFETY: the processor has AVX.
            return Some(unsafe { avx::unit_coverage(cap, prim, hardness, xs, h) });
        }
    }
    let _ = (cap, prim, hardness, xs, h);
    None
}

/// A stamp of a box, cylinder or cone brush (`shape`, `aspect`, `geo`) at a
/// unit's 8 children, as [`UnitCoverage`]: per lane [`Stamp::reach`],
/// [`Stamp::gauge`] through `coverage_profile` times the stamp's flow (0
/// outside the primitive's box), and the stamp's radius. None for a noise
/// stamp (its noise factor stays scalar) and where the kernels do not run.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn unit_stamp(st: &Stamp, shape: Shape, aspect: [f64; 3], geo: &StampReach, prim: &Prim, hardness: f64, xs: &[DVec3; LANES], h: f64) -> Option<UnitCoverage> {
    #[cfg(target_arch = "x86_64")]
    {
        if shape != Shape::Noise && shape != Shape::Sphere && available() {
            // SAFETY: the processor has AVX.
            return Some(unsafe { avx::unit_stamp(st, shape, aspect, geo, prim, hardness, xs, h) });
        }
    }
    let _ = (st, shape, aspect, geo, prim, hardness, xs, h);
    None
}

/// The stroke maximum over `prims` (box, cylinder or cone stamps of a
/// brush of `shape` and `aspect`, in stroke order; anything else panics)
/// at a unit's 8 centres `xs`, as the scalar stroke maximum gives it: per
/// lane `a` (0 or at least TINY) and the first primitive attaining it (any
/// when `a` is 0). None for noise brushes and where the kernels do not run.
#[inline]
pub fn unit_stamp_maximum(prims: &[Prim], shape: Shape, aspect: [f64; 3], hardness: f64, xs: &[DVec3; LANES]) -> Option<([f64; LANES], [u32; LANES])> {
    #[cfg(target_arch = "x86_64")]
    {
        if shape != Shape::Noise && shape != Shape::Sphere && available() {
            // SAFETY: the processor has AVX.
            return Some(unsafe { avx::unit_stamp_maximum(prims, shape, aspect, hardness, xs) });
        }
    }
    let _ = (prims, shape, aspect, hardness, xs);
    None
}

/// [`Capsule::within_reach`] of `cap` at the centres `xs` of cells of
/// half-diagonal `h`, as a mask (bit k: lane k within reach): the paint
/// pass's test of a unit's children that are not all leaves.
#[inline]
pub fn unit_reach(cap: &Capsule, xs: &[DVec3; LANES], h: f64) -> Option<u8> {
    #[cfg(target_arch = "x86_64")]
    {
        if available() {
            // SAFETY: the processor has AVX.
            return Some(unsafe { avx::unit_reach(cap, xs, h) });
        }
    }
    let _ = (cap, xs, h);
    None
}

/// The [`UnitMaximum`] over `prims` (capsules, in stroke order; a stamp
/// panics) at the centres `xs` of new cells of half-diagonal `h`; `seg` is
/// the segment's capsule, and `seg_is_last` says it is the last of `prims`
/// too (its projection then serves both).
#[inline]
pub fn unit_maximum(prims: &[Prim], hardness: f64, seg: &Capsule, seg_is_last: bool, xs: &[DVec3; LANES], h: f64) -> Option<UnitMaximum> {
    #[cfg(target_arch = "x86_64")]
    {
        if available() {
            // SAFETY: the processor has AVX.
            return Some(unsafe { avx::unit_maximum(prims, hardness, seg, seg_is_last, xs, h) });
        }
    }
    let _ = (prims, hardness, seg, seg_is_last, xs, h);
    None
}

#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;

    use glam::DVec3;

    use super::{LANES, UnitCoverage, UnitMaximum};
    use crate::brush::{Capsule, Stamp, StampReach, TINY};
    use crate::stroke::{Geometry, Prim};
    use crate::trace::Shape;

    /// `Capsule::project` of 4 points.
    struct Projection {
        dist: __m256d,
        u: __m256d,
        r: __m256d,
        t: __m256d,
        w1: __m256d,
    }

    /// The lanes' coordinates, 4 points a register.
    struct Points {
        x: [__m256d; 2],
        y: [__m256d; 2],
        z: [__m256d; 2],
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn splat(v: f64) -> __m256d {
        _mm256_set1_pd(v)
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn points(xs: &[DVec3; LANES]) -> Points {
        let half = |i: usize, f: fn(&DVec3) -> f64| _mm256_set_pd(f(&xs[i + 3]), f(&xs[i + 2]), f(&xs[i + 1]), f(&xs[i]));
        Points {
            x: [half(0, |p| p.x), half(4, |p| p.x)],
            y: [half(0, |p| p.y), half(4, |p| p.y)],
            z: [half(0, |p| p.z), half(4, |p| p.z)],
        }
    }

    /// `set` where the comparison mask `m` is set, else `clear`. Written
    /// with bitwise operations, not `blendv`: a comparison's lanes are all
    /// ones or all zeros, which the compiler does not see through a
    /// `blendv` under AVX without AVX2 (it tests each lane's sign with
    /// 128-bit integer compares instead, and the kernels ran 10% slower).
    #[inline]
    #[target_feature(enable = "avx")]
    fn select(m: __m256d, set: __m256d, clear: __m256d) -> __m256d {
        _mm256_or_pd(_mm256_and_pd(m, set), _mm256_andnot_pd(m, clear))
    }

    /// `v`, with +0 where the comparison mask `m` is set.
    #[inline]
    #[target_feature(enable = "avx")]
    fn zero_where(m: __m256d, v: __m256d) -> __m256d {
        _mm256_andnot_pd(m, v)
    }

    /// `v.clamp(0.0, 1.0)` as Rust computes it: below 0 gives 0, above 1
    /// gives 1, NaN stays NaN.
    #[inline]
    #[target_feature(enable = "avx")]
    fn clamp01(v: __m256d) -> __m256d {
        let v = zero_where(_mm256_cmp_pd::<_CMP_LT_OQ>(v, _mm256_setzero_pd()), v);
        select(_mm256_cmp_pd::<_CMP_GT_OQ>(v, splat(1.0)), splat(1.0), v)
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn abs(v: __m256d) -> __m256d {
        _mm256_and_pd(v, _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX)))
    }

    /// `Capsule::project`, operation for operation.
    #[inline]
    #[target_feature(enable = "avx")]
    fn project(c: &Capsule, x: __m256d, y: __m256d, z: __m256d) -> Projection {
        let (p0, d) = (c.p0, c.d);
        let wx = _mm256_sub_pd(x, splat(p0.x));
        let wy = _mm256_sub_pd(y, splat(p0.y));
        let wz = _mm256_sub_pd(z, splat(p0.z));
        let t = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(wx, splat(d.x)), _mm256_mul_pd(wy, splat(d.y))), _mm256_mul_pd(wz, splat(d.z)));
        let u = if c.dd >= TINY { clamp01(_mm256_div_pd(t, splat(c.dd))) } else { _mm256_setzero_pd() };
        let ex = _mm256_sub_pd(x, _mm256_add_pd(splat(p0.x), _mm256_mul_pd(splat(d.x), u)));
        let ey = _mm256_sub_pd(y, _mm256_add_pd(splat(p0.y), _mm256_mul_pd(splat(d.y), u)));
        let ez = _mm256_sub_pd(z, _mm256_add_pd(splat(p0.z), _mm256_mul_pd(splat(d.z), u)));
        let s = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(ex, ex), _mm256_mul_pd(ey, ey)), _mm256_mul_pd(ez, ez));
        // sqrt where s > 0, else +0 (and for a NaN s).
        let dist = _mm256_and_pd(_mm256_sqrt_pd(s), _mm256_cmp_pd::<_CMP_GT_OQ>(s, _mm256_setzero_pd()));
        let r = _mm256_add_pd(splat(c.r0), _mm256_mul_pd(splat(c.r1 - c.r0), u));
        let w1 = _mm256_add_pd(_mm256_add_pd(abs(wx), abs(wy)), abs(wz));
        Projection { dist, u, r, t, w1 }
    }

    /// `v` is a power of two whose reciprocal is a normal number too.
    #[inline]
    fn power_of_two(v: f64) -> bool {
        v.is_normal() && v > 0.0 && v.to_bits() & ((1u64 << 52) - 1) == 0 && (1.0 / v).is_normal()
    }

    /// `Capsule::coverage_at` (with `coverage_profile`), as selects.
    #[inline]
    #[target_feature(enable = "avx")]
    fn coverage(c: &Capsule, p: &Projection, hardness: f64) -> __m256d {
        let flow = _mm256_add_pd(splat(c.f0), _mm256_mul_pd(splat(c.f1 - c.f0), p.u));
        let profile = profile(_mm256_div_pd(p.dist, p.r), hardness);
        let cov = _mm256_mul_pd(profile, flow);
        if c.open {
            // Behind an open start: exactly 0 (spec 8.3).
            zero_where(_mm256_cmp_pd::<_CMP_LT_OQ>(p.t, _mm256_setzero_pd()), cov)
        } else {
            cov
        }
    }

    /// `coverage_profile(rho, hardness)`, as selects.
    #[inline]
    #[target_feature(enable = "avx")]
    fn profile(rho: __m256d, hardness: f64) -> __m256d {
        let span = 1.0 - hardness;
        let safe = if span > 0.0 { span } else { 1.0 };
        let above = _mm256_sub_pd(splat(1.0), rho);
        // Dividing by a power of two is multiplying by its reciprocal, bit
        // for bit (both round the same exact quotient): hardness 0 and 0.5
        // (1 and 1/2 here) save a division a lane.
        let t = clamp01(if power_of_two(safe) { _mm256_mul_pd(above, splat(1.0 / safe)) } else { _mm256_div_pd(above, splat(safe)) });
        let smooth = _mm256_mul_pd(_mm256_mul_pd(t, t), _mm256_sub_pd(splat(3.0), _mm256_mul_pd(splat(2.0), t)));
        let profile = select(_mm256_cmp_pd::<_CMP_LE_OQ>(rho, splat(hardness)), splat(1.0), smooth);
        zero_where(_mm256_cmp_pd::<_CMP_GE_OQ>(rho, splat(1.0)), profile)
    }

    /// `Capsule::within_reach` for cells of half-diagonal `h`: a mask.
    #[inline]
    #[target_feature(enable = "avx")]
    fn within_reach(c: &Capsule, p: &Projection, h: f64) -> __m256d {
        let near = _mm256_cmp_pd::<_CMP_LE_OQ>(_mm256_sub_pd(p.dist, p.r), splat(h * c.slack));
        if !c.open {
            return near;
        }
        // -(h·dn + 1e-12·(w1 + h)·dn); the negation flips the sign bit.
        let margin = _mm256_add_pd(splat(h * c.dn), _mm256_mul_pd(_mm256_mul_pd(splat(1e-12), _mm256_add_pd(p.w1, splat(h))), splat(c.dn)));
        let behind = _mm256_cmp_pd::<_CMP_LT_OQ>(p.t, _mm256_xor_pd(margin, splat(-0.0)));
        _mm256_andnot_pd(behind, near)
    }

    /// `Prim::holds` of 4 points: a mask.
    #[inline]
    #[target_feature(enable = "avx")]
    fn holds(p: &Prim, x: __m256d, y: __m256d, z: __m256d) -> __m256d {
        let le = |a: __m256d, b: __m256d| _mm256_cmp_pd::<_CMP_LE_OQ>(a, b);
        let lo = _mm256_and_pd(_mm256_and_pd(le(splat(p.lo.x), x), le(splat(p.lo.y), y)), le(splat(p.lo.z), z));
        let hi = _mm256_and_pd(_mm256_and_pd(le(x, splat(p.hi.x)), le(y, splat(p.hi.y))), le(z, splat(p.hi.z)));
        _mm256_and_pd(lo, hi)
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn store(out: &mut [f64; LANES], half: usize, v: __m256d) {
        // SAFETY: 4 lanes at 4·half of an array of 8.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr().add(4 * half), v) }
    }

    #[inline]
    #[target_feature(enable = "avx")]
    fn store_mask(out: &mut [bool; LANES], half: usize, m: __m256d) {
        let bits = _mm256_movemask_pd(m);
        for l in 0..4 {
            out[4 * half + l] = bits >> l & 1 == 1;
        }
    }

    #[target_feature(enable = "avx")]
    pub(super) fn unit_coverage(cap: &Capsule, prim: &Prim, hardness: f64, xs: &[DVec3; LANES], h: f64) -> UnitCoverage {
        let pts = points(xs);
        let mut o = UnitCoverage { r: [0.0; LANES], reach: [false; LANES], a: [0.0; LANES] };
        for i in 0..2 {
            let (x, y, z) = (pts.x[i], pts.y[i], pts.z[i]);
            let p = project(cap, x, y, z);
            store(&mut o.r, i, p.r);
            store_mask(&mut o.reach, i, within_reach(cap, &p, h));
            // 0 outside the primitive's box (spec 8.5): +0 where the mask is clear.
            store(&mut o.a, i, _mm256_and_pd(coverage(cap, &p, hardness), holds(prim, x, y, z)));
        }
        o
    }

    #[target_feature(enable = "avx")]
    pub(super) fn unit_reach(cap: &Capsule, xs: &[DVec3; LANES], h: f64) -> u8 {
        let pts = points(xs);
        let mut bits = 0;
        for i in 0..2 {
            let p = project(cap, pts.x[i], pts.y[i], pts.z[i]);
            bits |= (_mm256_movemask_pd(within_reach(cap, &p, h)) as u8) << (4 * i);
        }
        bits
    }

    /// `f64::max` as Rust computes it: a NaN argument gives the other.
    /// (`maxpd` gives its second operand when either is NaN.)
    #[inline]
    #[target_feature(enable = "avx")]
    fn max_nan_ignored(a: __m256d, b: __m256d) -> __m256d {
        select(_mm256_cmp_pd::<_CMP_UNORD_Q>(b, b), a, _mm256_max_pd(a, b))
    }

    /// `sqrt(s)` where `s > 0`, else +0 (a NaN `s` included).
    #[inline]
    #[target_feature(enable = "avx")]
    fn sqrt_positive(s: __m256d) -> __m256d {
        _mm256_and_pd(_mm256_sqrt_pd(s), _mm256_cmp_pd::<_CMP_GT_OQ>(s, _mm256_setzero_pd()))
    }

    /// A stamp's local coordinates and gauge at 4 points
    /// (`Stamp::local`, then `Stamp::gauge_local`): `(rho, lz, radial,
    /// cone side)`, the last three for the reach test.
    #[inline]
    #[target_feature(enable = "avx")]
    fn stamp_gauge(st: &Stamp, shape: Shape, aspect: [f64; 3], x: __m256d, y: __m256d, z: __m256d) -> (__m256d, [__m256d; 3], __m256d, __m256d) {
        let r = st.r;
        let (arx, ary, arz) = (aspect[0] * r, aspect[1] * r, aspect[2] * r);
        // x − c, then each row's dot product, summed left to right.
        let (vx, vy, vz) = (_mm256_sub_pd(x, splat(st.c.x)), _mm256_sub_pd(y, splat(st.c.y)), _mm256_sub_pd(z, splat(st.c.z)));
        let dot = |m: DVec3| _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(splat(m.x), vx), _mm256_mul_pd(splat(m.y), vy)), _mm256_mul_pd(splat(m.z), vz));
        let l = [dot(st.rot.x_axis), dot(st.rot.y_axis), dot(st.rot.z_axis)];
        let (nx, ny, nz) = (_mm256_div_pd(l[0], splat(arx)), _mm256_div_pd(l[1], splat(ary)), _mm256_div_pd(l[2], splat(arz)));
        if shape == Shape::Box {
            let rho = max_nan_ignored(max_nan_ignored(abs(nx), abs(ny)), abs(nz));
            return (rho, l, _mm256_setzero_pd(), _mm256_setzero_pd());
        }
        let radial = sqrt_positive(_mm256_add_pd(_mm256_mul_pd(nx, nx), _mm256_mul_pd(ny, ny)));
        let cone_side = _mm256_add_pd(_mm256_mul_pd(splat(2.0), radial), nz);
        let rho = if shape == Shape::Cylinder { max_nan_ignored(radial, abs(nz)) } else { max_nan_ignored(abs(nz), cone_side) };
        (rho, l, radial, cone_side)
    }

    #[target_feature(enable = "avx")]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn unit_stamp(st: &Stamp, shape: Shape, aspect: [f64; 3], geo: &StampReach, prim: &Prim, hardness: f64, xs: &[DVec3; LANES], h: f64) -> UnitCoverage {
        let pts = points(xs);
        let r = st.r;
        let (arx, ary, arz) = (aspect[0] * r, aspect[1] * r, aspect[2] * r);
        let mut o = UnitCoverage { r: [r; LANES], reach: [false; LANES], a: [0.0; LANES] };
        for i in 0..2 {
            let (x, y, z) = (pts.x[i], pts.y[i], pts.z[i]);
            let (rho, l, radial, cone_side) = stamp_gauge(st, shape, aspect, x, y, z);
            // `Stamp::reach_local`, from the same coordinates and quotients.
            let le = |a: __m256d, b: f64| _mm256_cmp_pd::<_CMP_LE_OQ>(a, splat(b));
            let reach = if shape == Shape::Box {
                _mm256_and_pd(_mm256_and_pd(le(abs(l[0]), arx + h), le(abs(l[1]), ary + h)), le(abs(l[2]), arz + h))
            } else {
                let inside = _mm256_and_pd(le(radial, 1.0 + h / (geo.m * r)), le(abs(l[2]), arz + h));
                if shape == Shape::Cylinder { inside } else { _mm256_and_pd(inside, le(cone_side, 1.0 + h * geo.lip / r)) }
            };
            store_mask(&mut o.reach, i, reach);
            // 0 outside the primitive's box (spec 8.5): +0 where the mask is clear.
            store(&mut o.a, i, _mm256_and_pd(_mm256_mul_pd(profile(rho, hardness), splat(st.f)), holds(prim, x, y, z)));
        }
        o
    }

    /// The centres' box, NaN coordinates left out (f64::min, unlike
    /// glam's, ignores a NaN): a NaN centre holds nothing anyway.
    fn centre_box(xs: &[DVec3; LANES]) -> (DVec3, DVec3) {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for x in xs {
            lo = DVec3::new(lo.x.min(x.x), lo.y.min(x.y), lo.z.min(x.z));
            hi = DVec3::new(hi.x.max(x.x), hi.y.max(x.y), hi.z.max(x.z));
        }
        (lo, hi)
    }

    /// A stroke maximum under way at 4 points, as `stroke_maximum_with`
    /// folds it: the largest coverage so far and the index of the first
    /// primitive attaining it (a later one must exceed it), and the lanes a
    /// NaN coverage has poisoned.
    struct Maximum {
        best: __m256d,
        best_k: __m256d,
        nan: __m256d,
    }

    impl Maximum {
        #[inline]
        #[target_feature(enable = "avx")]
        fn new() -> Maximum {
            Maximum { best: _mm256_setzero_pd(), best_k: _mm256_setzero_pd(), nan: _mm256_setzero_pd() }
        }

        /// Fold in primitive `i`'s coverage `cov`, in the lanes its box
        /// holds (`inside`).
        #[inline]
        #[target_feature(enable = "avx")]
        fn fold(&mut self, i: usize, cov: __m256d, inside: __m256d) {
            self.nan = _mm256_or_pd(self.nan, _mm256_and_pd(inside, _mm256_cmp_pd::<_CMP_UNORD_Q>(cov, cov)));
            let up = _mm256_and_pd(inside, _mm256_cmp_pd::<_CMP_GT_OQ>(cov, self.best));
            self.best = select(up, cov, self.best);
            self.best_k = select(up, splat(i as f64), self.best_k);
        }

        /// Store the maximum (0 below TINY and where poisoned) and its
        /// primitive's index into lanes `4·half..` of `a` and `k`.
        #[inline]
        #[target_feature(enable = "avx")]
        fn store(self, a: &mut [f64; LANES], k: &mut [f64; LANES], half: usize) {
            let zero = _mm256_or_pd(self.nan, _mm256_cmp_pd::<_CMP_LT_OQ>(self.best, splat(TINY)));
            store(a, half, _mm256_andnot_pd(zero, self.best));
            store(k, half, self.best_k);
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
        let (mut a, mut k) = ([0.0; LANES], [0.0; LANES]);
        // Stamp by stamp, both halves: a box is tested once a unit.
        let mut m = [Maximum::new(), Maximum::new()];
        for (i, p) in prims.iter().enumerate() {
            if !p.overlaps(lo, hi) {
                continue; // its box holds none of the 8 centres
            }
            let Geometry::Stamp(st) = &p.geo else { panic!("unit_stamp_maximum takes stamps only") };
            for (half, m) in m.iter_mut().enumerate() {
                let (x, y, z) = (pts.x[half], pts.y[half], pts.z[half]);
                let cov = _mm256_mul_pd(profile(stamp_gauge(st, shape, aspect, x, y, z).0, hardness), splat(st.f));
                m.fold(i, cov, holds(p, x, y, z));
            }
        }
        for (half, m) in m.into_iter().enumerate() {
            m.store(&mut a, &mut k, half);
        }
        (a, k.map(|v| v as u32))
    }

    #[target_feature(enable = "avx")]
    pub(super) fn unit_maximum(prims: &[Prim], hardness: f64, seg: &Capsule, seg_is_last: bool, xs: &[DVec3; LANES], h: f64) -> UnitMaximum {
        let pts = points(xs);
        let (lo, hi) = centre_box(xs);
        let mut o = UnitMaximum { a: [0.0; LANES], k: [0; LANES], seg_r: [0.0; LANES], seg_reach: [false; LANES] };
        let mut k = [0.0; LANES];
        let sp = [0, 1].map(|half| project(seg, pts.x[half], pts.y[half], pts.z[half]));
        for half in 0..2 {
            store(&mut o.seg_r, half, sp[half].r);
            store_mask(&mut o.seg_reach, half, within_reach(seg, &sp[half], h));
        }
        // Primitive by primitive, both halves: a box is tested once a unit.
        let mut m = [Maximum::new(), Maximum::new()];
        for (i, p) in prims.iter().enumerate() {
            if !p.overlaps(lo, hi) {
                continue; // its box holds none of the 8 centres
            }
            let Geometry::Capsule(cap) = &p.geo else { panic!("unit_maximum takes capsules only") };
            let last = seg_is_last && i + 1 == prims.len();
            for (half, m) in m.iter_mut().enumerate() {
                let (x, y, z) = (pts.x[half], pts.y[half], pts.z[half]);
                let own;
                let pr = if last {
                    &sp[half]
                } else {
                    own = project(cap, x, y, z);
                    &own
                };
                m.fold(i, coverage(cap, pr, hardness), holds(p, x, y, z));
            }
        }
        for (half, m) in m.into_iter().enumerate() {
            m.store(&mut o.a, &mut k, half);
        }
        o.k = k.map(|v| v as u32);
        o
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
                        assert_eq!(u.reach[l], cap.within_reach(&cp, h), "reach {l} {x:?}");
                        assert_eq!(reach >> l & 1 == 1, u.reach[l], "unit_reach {l} {x:?}");
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
            let st = Stamp { c: jitter(&mut seed) * 50.0, r, f: [1.0, 0.85, unit(&mut seed), 0.0][(unit(&mut seed) * 4.0) as usize], rot: crate::brush::quat_to_matrix(q), mirror: 0 };
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
                    assert_eq!((u.reach[l], u.a[l].to_bits(), u.r[l]), (st.reach(shape, aspect, &geo, x, h), a.to_bits(), r), "{shape:?} lane {l} at {x:?}: {} against {a}", u.a[l]);
                    compared += 1;
                    covered += usize::from(a > 0.0);
                }
            }
        }
        assert!(compared > 100_000 && covered > 10_000, "{compared} lanes, {covered} covered");
        assert!(unit_stamp(&Stamp { c: DVec3::ZERO, r: 1.0, f: 1.0, rot: glam::DMat3::IDENTITY, mirror: 0 }, Shape::Noise, [1.0; 3], &StampReach::new([1.0; 3]), &capsules(&mut seed, 1)[0], 0.5, &[DVec3::ZERO; LANES], 1.0).is_none());
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
                    // The scalar stroke maximum (paint.rs's, for capsules).
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
                    assert_eq!(m.seg_reach[l], seg.within_reach(&cp, h));
                }
            }
        }
        assert!(hits > 2000, "{hits} lanes covered");
    }
}

//! The lane operations at AVX: 8 lanes in two registers of 4, a mask a
//! vector whose lanes are all ones or all zeros.

use std::arch::x86_64::*;

use glam::DVec3;

use super::{LANES, UnitCoverage, UnitMaximum, centre_box, power_of_two};
use crate::brush::{Capsule, Stamp, StampReach, TINY};
use crate::stroke::{Geometry, Prim};
use octopaint_model::Shape;

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

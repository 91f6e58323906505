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
use octopaint_model::Shape;

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

#[cfg(target_arch = "x86_64")]
mod avx;

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

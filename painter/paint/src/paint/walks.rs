//! What a paint pass walks with: one capsule, one stamp or a segment's
//! primitives together ([`Walk`]), and the reach (spec 8.7) and stroke
//! maximum (spec 8.8) rules a round's new children are decided by.
//! Reference twin: `Painting._reach`, `_reach_stamps`, `_reach_one_capsule`
//! and `_evaluate` in paint.py.

use glam::DVec3;

use super::StrokeState;
use crate::brush::{self, Capsule, CapsulePoint, Stamp, StampReach, TINY};
use crate::lanes::{self, LANES};
use crate::stroke::{Geometry, Prim};
use octopaint_model::{Brush, Shape};
use octopaint_octree::pool::Tree;

/// [`Walk::within_reach`] of the 8 centres `xs`, one at a time, as a mask
/// (bit k: lane k): the walk's test where no kernel does it.
#[inline(always)]
fn reach_each<W: Walk + ?Sized>(w: &W, xs: &[DVec3; LANES], h: f64) -> u8 {
    (0..LANES).fold(0, |m, k| m | u8::from(w.within_reach(&w.project(xs[k]), h)) << k)
}

/// What [`walk_run`] paints a segment with: one capsule, one stamp, or the
/// segment's primitives together, each through the tests of spec 8.7 and
/// the stroke maximum of spec 8.8.
pub(super) trait Walk: Sync {
    /// Capsule walks and stamp walks keep their own split choices.
    const CAPSULE: bool;
    /// What a cell centre's tests share (a capsule's projection).
    type Point: Copy;
    fn project(&self, x: DVec3) -> Self::Point;
    /// A cell of half-diagonal `h` at a centre that projects to `p` is
    /// within reach (spec 8.7).
    fn within_reach(&self, p: &Self::Point, h: f64) -> bool;
    /// The radius that sets the target depth there for a cell of
    /// half-diagonal `h` within reach: the leaf is coarser than its target
    /// depth when it is coarser than this radius's.
    fn radius(&self, p: &Self::Point, h: f64) -> f64;
    /// The largest radius anywhere (the parallel split's grain).
    fn largest_radius(&self) -> f64;
    /// Coverage·flow at `x`, which projects to `p`, inside the primitive's
    /// box; a NaN or a value below TINY paints nothing.
    fn coverage_at(&self, x: DVec3, p: &Self::Point, hardness: f64) -> f64;
    /// [`Walk::within_reach`] of the 8 centres `xs` as a mask (bit k: lane k).
    fn unit_reach(&self, xs: &[DVec3; LANES], h: f64) -> u8 {
        reach_each(self, xs, h)
    }
    /// The coverage of a unit's 8 leaves at once, where a kernel does it.
    fn unit_coverage(&self, _prim: &Prim, _hardness: f64, _xs: &[DVec3; LANES], _h: f64) -> Option<lanes::UnitCoverage> {
        None
    }
}

impl Walk for Capsule {
    const CAPSULE: bool = true;
    type Point = CapsulePoint;
    #[inline(always)]
    fn project(&self, x: DVec3) -> CapsulePoint {
        Capsule::project(self, x)
    }
    #[inline(always)]
    fn within_reach(&self, p: &CapsulePoint, h: f64) -> bool {
        Capsule::within_reach(self, p, h)
    }
    #[inline(always)]
    fn radius(&self, p: &CapsulePoint, _h: f64) -> f64 {
        p.r
    }
    fn largest_radius(&self) -> f64 {
        self.r0.max(self.r1)
    }
    #[inline(always)]
    fn coverage_at(&self, _x: DVec3, p: &CapsulePoint, hardness: f64) -> f64 {
        Capsule::coverage_at(self, p, hardness)
    }
    #[inline(always)]
    fn unit_reach(&self, xs: &[DVec3; LANES], h: f64) -> u8 {
        lanes::unit_reach(self, xs, h).unwrap_or_else(|| reach_each(self, xs, h))
    }
    #[inline(always)]
    fn unit_coverage(&self, prim: &Prim, hardness: f64, xs: &[DVec3; LANES], h: f64) -> Option<lanes::UnitCoverage> {
        lanes::unit_coverage(self, prim, hardness, xs, h)
    }
}

/// A stamp with its brush's shape constants: [`Stamp::reach`] and the
/// coverage `stroke_maximum_with` takes of one stamp (the noise factor at
/// the point mirrored by the stamp's copy, for a noise brush).
pub(super) struct StampWalk {
    pub(super) s: Stamp,
    pub(super) prim: Prim,
    pub(super) shape: Shape,
    pub(super) aspect: [f64; 3],
    pub(super) reach: StampReach,
    pub(super) hardness: f64,
    pub(super) noise: Option<(Box<[u16; 512]>, Brush)>,
}

impl Walk for StampWalk {
    const CAPSULE: bool = false;
    /// The point and, but for a noise stamp, its local coordinates: reach
    /// and coverage share one transform.
    type Point = (DVec3, DVec3);
    #[inline(always)]
    fn project(&self, x: DVec3) -> (DVec3, DVec3) {
        (x, if self.noise.is_some() { x } else { self.s.local(x) })
    }
    #[inline(always)]
    fn within_reach(&self, &(x, l): &(DVec3, DVec3), h: f64) -> bool {
        match self.noise {
            Some(_) => self.s.reach(self.shape, self.aspect, &self.reach, x, h),
            None => self.s.reach_local(self.shape, self.aspect, &self.reach, l, h),
        }
    }
    #[inline(always)]
    fn radius(&self, _p: &(DVec3, DVec3), _h: f64) -> f64 {
        self.s.r
    }
    fn largest_radius(&self) -> f64 {
        self.s.r
    }
    #[inline(always)]
    fn unit_reach(&self, xs: &[DVec3; LANES], h: f64) -> u8 {
        // The unit kernel's reach (its coverage is thrown away: a unit with
        // children to descend into is far rarer than a unit of leaves).
        match lanes::unit_stamp(&self.s, self.shape, self.aspect, &self.reach, &self.prim, self.hardness, xs, h) {
            Some(u) => u.reach,
            None => reach_each(self, xs, h),
        }
    }
    #[inline(always)]
    fn unit_coverage(&self, prim: &Prim, hardness: f64, xs: &[DVec3; LANES], h: f64) -> Option<lanes::UnitCoverage> {
        lanes::unit_stamp(&self.s, self.shape, self.aspect, &self.reach, prim, hardness, xs, h)
    }
    #[inline(always)]
    fn coverage_at(&self, x: DVec3, &(_, l): &(DVec3, DVec3), hardness: f64) -> f64 {
        debug_assert_eq!(hardness, self.hardness);
        match &self.noise {
            Some((perm, b)) => {
                let c = brush::coverage_profile(self.s.gauge(self.shape, self.aspect, x), self.hardness) * self.s.f;
                let at = if self.s.mirror == 0 { x } else { crate::stroke::mirrored(x, self.s.mirror, b.mirror.expect("a copy has a mirror").centre) };
                c * brush::noise_factor(perm, b, at)
            }
            None => brush::coverage_profile(self.s.gauge_local(self.shape, self.aspect, l), self.hardness) * self.s.f,
        }
    }
}

/// The primitives of a segment of several (a stroke whose stamps lie
/// closer than its samples, a mirrored stroke: a capsule or stamps a copy),
/// through the rules a round's new children are decided by
/// ([`segment_reach`], [`stroke_maximum_of`]):
/// within reach when one of them is, coarser than the target depth when
/// one within reach asks for a deeper one (the least radius among those
/// within reach: the target depth only deepens as the radius shrinks), and
/// the stroke maximum over them, where a NaN coverage paints nothing. They
/// all paint the segment's colour.
pub(super) struct SegmentWalk {
    pub(super) seg: Vec<Prim>,
    pub(super) brush: Brush,
    pub(super) perm: Box<[u16; 512]>,
    pub(super) reach: StampReach,
    pub(super) largest: f64,
}

impl Walk for SegmentWalk {
    const CAPSULE: bool = false;
    type Point = DVec3;
    #[inline(always)]
    fn project(&self, x: DVec3) -> DVec3 {
        x
    }
    #[inline(always)]
    fn within_reach(&self, x: &DVec3, h: f64) -> bool {
        self.seg.iter().any(|p| prim_reach(&self.brush, &self.reach, p, *x, h).0)
    }
    #[inline(always)]
    fn radius(&self, x: &DVec3, h: f64) -> f64 {
        self.seg.iter().map(|p| prim_reach(&self.brush, &self.reach, p, *x, h)).filter(|&(within, _)| within).fold(f64::INFINITY, |m, (_, r)| m.min(r))
    }
    fn largest_radius(&self) -> f64 {
        self.largest
    }
    #[inline(always)]
    fn coverage_at(&self, x: DVec3, _projected: &DVec3, hardness: f64) -> f64 {
        debug_assert_eq!(hardness, self.brush.hardness);
        stroke_maximum_of(&self.brush, &self.perm, &self.seg, x, None).0
    }
}

/// Within reach of some primitive of the segment, and (when `want_needs`)
/// whether some primitive within reach has a target depth below `d`
/// (spec 8.7).
#[inline]
pub(super) fn segment_reach(tree: &Tree, st: &StrokeState, seg: &[Prim], x: DVec3, d: u32, h: f64, want_needs: bool) -> (bool, bool) {
    let mut reach = false;
    let mut needs = false;
    for p in seg {
        let (r_in, r) = prim_reach(&st.brush, &st.stamp_reach, p, x, h);
        if r_in {
            reach = true;
            if !want_needs {
                break;
            }
            if tree.lat.coarser_than_target(d, r) {
                needs = true;
                break;
            }
        }
    }
    (reach, needs)
}

/// Whether a cell of half-diagonal `h` at `x` is within reach of primitive
/// `p` of a stroke with brush `b` (spec 8.7), and the radius that sets the
/// target depth there.
#[inline]
fn prim_reach(b: &Brush, geo: &StampReach, p: &Prim, x: DVec3, h: f64) -> (bool, f64) {
    match &p.geo {
        Geometry::Capsule(cap) => cap.reach(x, h),
        Geometry::Stamp(s) => (s.reach(b.shape, b.aspect, geo, x, h), s.r),
    }
}

/// The stroke maximum of coverage·flow over `prims` at `x` and the first
/// primitive attaining it; below TINY it is 0, and a NaN coverage poisons
/// the maximum to 0 (as the reference's max does). `last` is the projection
/// of `x` on the last primitive of `prims` when that one is a capsule and
/// the caller has it already.
#[inline]
pub(super) fn stroke_maximum_with(st: &StrokeState, prims: &[Prim], x: DVec3, last: Option<&CapsulePoint>) -> (f64, usize) {
    stroke_maximum_of(&st.brush, &st.perm, prims, x, last)
}

/// [`stroke_maximum_with`] for a stroke with brush `b` and noise
/// permutation `perm`.
#[inline]
fn stroke_maximum_of(b: &Brush, perm: &[u16; 512], prims: &[Prim], x: DVec3, last: Option<&CapsulePoint>) -> (f64, usize) {
    // Noise per mirror copy, each at x mirrored by it (spec 8.11), computed
    // when a stamp of that copy first needs it.
    let mut noise = [f64::NAN; 8];
    let mut noise_at = |mask: u8| {
        let k = usize::from(mask);
        if noise[k].is_nan() {
            let at = if mask == 0 { x } else { crate::stroke::mirrored(x, mask, b.mirror.expect("a copy has a mirror").centre) };
            noise[k] = brush::noise_factor(perm, b, at);
        }
        noise[k]
    };
    let mut best = 0.0;
    let mut k = 0;
    for (i, p) in prims.iter().enumerate() {
        if !p.holds(x) {
            continue; // covers nothing here (spec 8.5)
        }
        let cov = match &p.geo {
            Geometry::Capsule(cap) => match last {
                Some(cp) if i + 1 == prims.len() => cap.coverage_at(cp, b.hardness),
                _ => cap.coverage(x, b.hardness),
            },
            Geometry::Stamp(s) => {
                let c = brush::coverage_profile(s.gauge(b.shape, b.aspect, x), b.hardness) * s.f;
                if b.shape == Shape::Noise { c * noise_at(s.mirror) } else { c }
            }
        };
        if cov.is_nan() {
            return (0.0, 0);
        }
        if cov > best {
            best = cov;
            k = i;
        }
    }
    if best < TINY { (0.0, k) } else { (best, k) }
}

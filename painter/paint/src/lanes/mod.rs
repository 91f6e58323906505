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
mod tests;

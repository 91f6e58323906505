//! Settled leaves (spec 8.7): a leaf whose refinement could not change a
//! value is left as it is. Its stroke maximum over its reach ball is
//! bounded from the capsules near it, and the bounds kept in its slot so
//! that the next test folds in only the capsules added since. Reference
//! twin: `Painting._settled` in paint.py.

use glam::DVec3;

use super::{FirstWrite, Painting};
use crate::brush::{Capsule, TINY};
use crate::lanes::{self, LANES};
use crate::stroke::{Geometry, Prim};
use octopaint_octree::par;
use octopaint_octree::pool::NONE;

/// The capsules among `prims` whose boxes meet the bounds of the balls
/// `(centre, radius)` (the only ones that cover any point of them), with
/// their indices in the stroke, ascending.
fn capsules_near(prims: &[Prim], balls: impl Iterator<Item = (DVec3, f64)>) -> Vec<(u32, Prim)> {
    let (lo, hi) = balls.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), (x, h)| (lo.min(x - h), hi.max(x + h)));
    prims.iter().enumerate().filter(|(_, p)| matches!(p.geo, Geometry::Capsule(_)) && p.overlaps(lo, hi)).map(|(i, p)| (i as u32, *p)).collect()
}

/// The settled test's bounds `[a_lo, a_hi]` of a ball of radius `h` about
/// `x`, so far over the stroke's first `from` primitives, raised by each
/// capsule of `caps` (with its index in the stroke, ascending) from `from`
/// on whose box meets the ball, to `Capsule::coverage_bounds` there; NaN
/// (never settled) at a negative or NaN bound. `lanes::unit_settle_bounds`
/// folds 8 balls the same way.
pub(crate) fn settle_bounds(caps: &[(u32, Prim)], x: DVec3, h: f64, from: u32, mut a_lo: f64, mut a_hi: f64, hardness: f64) -> (f64, f64) {
    let (ball_lo, ball_hi) = (x - h, x + h);
    for (i, p) in caps {
        let Geometry::Capsule(cap) = &p.geo else { continue };
        if *i < from || !p.overlaps(ball_lo, ball_hi) {
            continue; // folded in already, or covers nothing in the ball
        }
        let (lo, hi) = cap.coverage_bounds(&cap.project(x), h, hardness);
        if !(lo >= 0.0 && hi >= 0.0) {
            return (f64::NAN, a_hi); // absurd input: never settled
        }
        a_lo = a_lo.max(lo);
        a_hi = a_hi.max(hi);
    }
    (a_lo, a_hi)
}

impl Painting {
    /// The cells among `leaves` (cell, centre, reach radius) that are not
    /// settled, in order; the settled ones are counted. The tests run in
    /// parallel, each over the capsules whose boxes meet the leaves' balls;
    /// each touched leaf's bounds are written back after.
    pub(super) fn unsettled(&mut self, leaves: Vec<(u32, DVec3, f64)>) -> Vec<u32> {
        let st = self.stroke.as_ref().expect("stroke");
        let caps = capsules_near(&st.prims, leaves.iter().map(|&(_, x, h)| (x, h)));
        let caps = &caps[..];
        // Tests 8 at a time in vector lanes where the kernels run, the rest
        // one at a time (a test folds in a few capsules: about as much work
        // as 4 cells).
        let grouped = if lanes::available() { leaves.len() / LANES * LANES } else { 0 };
        let mut tests = vec![(false, None); grouped];
        par::for_groups(&leaves[..grouped], &mut tests, LANES, |g, out| out.copy_from_slice(&self.settled_lanes(g.try_into().expect("8 leaves"), caps)));
        tests.extend(par::map_weighted(&leaves[grouped..], 4, |&(c, x, h)| self.settled(c, x, h, caps)));
        let st = self.stroke.as_mut().expect("stroke");
        let upto = st.prims.len() as u32;
        let mut out = Vec::with_capacity(leaves.len());
        let mut settled_now = Vec::new();
        for (&(c, _, _), (settled, bounds)) in leaves.iter().zip(tests) {
            if let Some((slot, bounds)) = bounds {
                let s = &mut st.slots[slot as usize];
                s.bounds = bounds;
                s.bounds_upto = upto;
            }
            if settled {
                self.counters.leaves_settled += 1;
                settled_now.push(c);
            } else {
                out.push(c);
            }
        }
        for c in settled_now {
            self.defer(c);
        }
        out
    }

    /// Mark a settled leaf deferred (spec 8.7). A leaf the stroke has not
    /// touched gets its slot first, its before-value its stored value and
    /// written unchanged (journalled like every slotted cell, which the
    /// paint pass may later write in place).
    fn defer(&mut self, c: u32) {
        if self.slot_of.get(c) == NONE {
            let (rgb, sigma) = (self.tree.rgb()[c as usize], self.tree.sigma()[c as usize]);
            self.first_write(&FirstWrite { c, before_rgb: rgb, before_sigma: sigma, a: 0.0, rgb, sigma, next: false });
        }
        let slot = self.slot_of.get(c);
        self.stroke.as_mut().expect("stroke").deferred.set(slot, true);
    }

    /// The deferred leaves among `leaves` (cell, centre, reach radius;
    /// each has a slot) that some capsule of the stroke so far must refine:
    /// within its reach and coarser than its target depth at the centre
    /// (spec 8.7; the caller has applied the sigma gate). The others need
    /// no earlier primitive, and a later segment tests its own, so their
    /// marks are cleared. A capsule reaching a ball has the ball's centre
    /// at most `r(u) + h·K` from its axis, inside its box grown by `h·K`:
    /// the box grown by twice that picks the capsules to test.
    pub(super) fn needed_by_stroke(&mut self, leaves: Vec<(u32, DVec3, f64)>) -> Vec<(u32, DVec3, f64)> {
        let st = self.stroke.as_ref().expect("stroke");
        let (lat, depth) = (&self.tree.lat, self.tree.depth());
        let grown = |p: &Prim, cap: &Capsule, h: f64| {
            let g = DVec3::splat(2.0 * h * cap.slack);
            (p.lo - g, p.hi + g)
        };
        let (lo, hi) = leaves.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &(_, x, _)| (lo.min(x), hi.max(x)));
        let h_max = leaves.iter().fold(0.0f64, |m, l| m.max(l.2));
        let caps: Vec<(&Prim, &Capsule)> = st
            .prims
            .iter()
            .filter_map(|p| match &p.geo {
                Geometry::Capsule(cap) => {
                    let (g_lo, g_hi) = grown(p, cap, h_max);
                    (g_hi.cmpge(lo).all() && g_lo.cmple(hi).all()).then_some((p, cap))
                }
                Geometry::Stamp(_) => None,
            })
            .collect();
        let needs = par::map(&leaves, |&(c, x, h)| {
            let d = u32::from(depth[c as usize]);
            caps.iter().any(|&(p, cap)| {
                let (g_lo, g_hi) = grown(p, cap, h);
                g_hi.cmpge(x).all() && g_lo.cmple(x).all() && {
                    let cp = cap.project(x);
                    cap.within_reach(&cp, h) && lat.coarser_than_target(d, cp.r)
                }
            })
        });
        let (mut out, mut idle) = (Vec::new(), Vec::new());
        for (l, need) in leaves.into_iter().zip(needs) {
            if need { out.push(l) } else { idle.push(l.0) }
        }
        let st = self.stroke.as_mut().expect("stroke");
        for c in idle {
            st.deferred.set(self.slot_of.get(c), false);
        }
        out
    }

    /// A leaf whose refinement could not change a value (spec 8.7): over
    /// the ball of its reach radius `h` about `x`, the stroke maximum lies
    /// in `[a_lo, a_hi]` (from the capsules among `caps` whose boxes meet
    /// the ball's box; `caps` holds at least every such capsule, with its
    /// index in the stroke), and the stored value of the blend is the same
    /// at both ends, hence everywhere between (the blend and the rounding
    /// to bytes and f32 are monotone in `a`). Nothing covering it counts as
    /// settled too: every cell under it keeps the before-value. A touched
    /// leaf keeps its bounds in its slot, so the next test folds in only
    /// the capsules added since: returned with its slot, for the caller to
    /// write.
    pub(super) fn settled(&self, c: u32, x: DVec3, h: f64, caps: &[(u32, Prim)]) -> (bool, Option<(u32, [f64; 2])>) {
        let (slot, a_lo, a_hi, from) = self.bounds_so_far(c);
        if a_lo.is_nan() {
            return (false, None);
        }
        let hardness = self.stroke.as_ref().expect("stroke").brush.hardness;
        let (a_lo, a_hi) = settle_bounds(caps, x, h, from, a_lo, a_hi, hardness);
        self.settled_by(c, slot, a_lo, a_hi)
    }

    /// [`Painting::settled`] of 8 leaves (cell, centre, reach radius), their
    /// bounds folded in vector lanes (`lanes::unit_settle_bounds`; the
    /// caller has checked that the kernels run).
    fn settled_lanes(&self, leaves: &[(u32, DVec3, f64); LANES], caps: &[(u32, Prim)]) -> [(bool, Option<(u32, [f64; 2])>); LANES] {
        let so_far = leaves.map(|(c, _, _)| self.bounds_so_far(c));
        let hardness = self.stroke.as_ref().expect("stroke").brush.hardness;
        let (lo, hi) = lanes::unit_settle_bounds(
            caps,
            &leaves.map(|(_, x, _)| x),
            &leaves.map(|(_, _, h)| h),
            &so_far.map(|(_, _, _, from)| from),
            &so_far.map(|(_, lo, _, _)| lo),
            &so_far.map(|(_, _, hi, _)| hi),
            hardness,
        )
        .expect("the kernels run");
        std::array::from_fn(|k| {
            let (slot, lo0, _, _) = so_far[k];
            if lo0.is_nan() { (false, None) } else { self.settled_by(leaves[k].0, slot, lo[k], hi[k]) }
        })
    }

    /// `c`'s slot (NONE: untouched) and the settled test's bounds kept in
    /// it, `(slot, a_lo, a_hi, from)`: over the stroke's first `from`
    /// primitives.
    #[inline]
    fn bounds_so_far(&self, c: u32) -> (u32, f64, f64, u32) {
        match self.slot_of.get(c) {
            NONE => (NONE, 0.0, 0.0, 0),
            s => {
                let b = &self.stroke.as_ref().expect("stroke").slots[s as usize];
                (s, b.bounds[0], b.bounds[1], b.bounds_upto)
            }
        }
    }

    /// The settled test's answer for `c` (slot `slot`) whose stroke maximum
    /// lies in `[a_lo, a_hi]` (NaN: never settled), with the bounds for its
    /// slot.
    fn settled_by(&self, c: u32, slot: u32, a_lo: f64, a_hi: f64) -> (bool, Option<(u32, [f64; 2])>) {
        let st = self.stroke.as_ref().expect("stroke");
        let bounds = (slot != NONE).then_some((slot, [a_lo, a_hi]));
        if a_lo.is_nan() {
            return (false, bounds);
        }
        if a_hi < TINY {
            return (true, bounds);
        }
        if a_lo < TINY {
            return (false, bounds); // 0 and a > 0 may differ at any a
        }
        if a_lo == a_hi {
            return (true, bounds); // one maximum everywhere (often full coverage)
        }
        let (before_rgb, before_sigma) = self.before_value(c);
        let value = |a: f64| {
            let (rgb, sigma) = st.stored(before_rgb, before_sigma, st.colour, a);
            (rgb, sigma.to_bits())
        };
        (value(a_lo) == value(a_hi), bounds)
    }
}

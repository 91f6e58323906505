//! The levels after the paint pass: a refinement round (or part of one) on
//! the candidates, then the round's new children painted, each decided
//! with its parent's before-value and its stroke maximum over the stroke so
//! far (spec 8.8, 8.10 step 6), a unit's 8 children at once in vector lanes
//! where the kernels run. Reference twin: `Painting._round` and
//! `_paint_new_cells` in paint.py.

use glam::DVec3;

use super::walks::{segment_reach, stroke_maximum_with};
use super::{FirstWrite, Painting, Slot, StrokeState};
use crate::lanes::{self, LANES};
use crate::stroke::{Geometry, Prim};
use octopaint_model::{Mode, Shape};
use octopaint_octree::par;
use octopaint_octree::pool::{NONE, Tree, UNIT};

/// What the pass over a round's new children reads
/// ([`Painting::paint_new_cells`]).
struct NewCells<'a> {
    pub(super) tree: &'a Tree,
    pub(super) st: &'a StrokeState,
    /// The stroke's primitives whose boxes meet the new centres.
    pub(super) near: &'a [Prim],
    /// The segment's primitives.
    pub(super) seg: &'a [Prim],
    pub(super) sigma_gate: bool,
}

impl NewCells<'_> {
    /// What new cell `c` (centre `x`, depth `d`) stores and whether the next
    /// round refines it, given its parent's before-value, its stroke maximum
    /// `a` (0 or at least TINY) with the primitive `k` of `near` attaining
    /// it, and, for a segment of one capsule, whether the cell is within its
    /// reach and the capsule's radius at the cell's projection.
    #[inline(always)]
    fn decide(&self, (c, x, d): (u32, DVec3, u32), before: ([u8; 3], f32), (a, k): (f64, usize), seg_reach: Option<(bool, f64)>) -> FirstWrite {
        let (before_rgb, before_sigma) = before;
        let lat = &self.tree.lat;
        // At a = 0 the blend keeps the before-value whatever the colour
        // (`k` then names no primitive).
        let colour = if a > 0.0 { self.near[k].colour } else { [0.0; 3] };
        let (rgb, sigma) = self.st.stored(before_rgb, before_sigma, colour, a);
        let (reach, needs) = match seg_reach {
            Some((reach, r)) => (reach, reach && lat.coarser_than_target(d, r)),
            None => segment_reach(self.tree, self.st, self.seg, x, d, lat.reach_radius[d as usize], true),
        };
        let next = reach && needs && !(self.sigma_gate && !(sigma > 0.0));
        FirstWrite { c, before_rgb, before_sigma, a, rgb, sigma, next }
    }
}

/// The bounding box of some centres.
fn centre_bounds(xs: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    xs.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)))
}

impl Painting {
    /// Refinement of (part of) a round's sorted candidates, then the new
    /// children painted (spec 8.10 step 6). Returns how many candidates were
    /// consumed and the new cells that need refinement, or None when the
    /// segment stops: a refusal, or a round that allocated nothing.
    pub(super) fn refine_part(&mut self, candidates: &[u32], max_units: usize, first: usize, line: usize) -> Option<(usize, Vec<u32>)> {
        let (units, consumed, refusal) = self.tree.refine_candidates(candidates, max_units);
        if let Some(r) = refusal {
            self.counters.refusals += 1;
            let st = self.stroke.as_mut().expect("stroke");
            if !st.refusal_warned {
                st.refusal_warned = true;
                self.warnings.push(r.warning(line, &self.tree));
            }
        }
        if units.is_empty() {
            // Nothing allocated: a refusal, or candidates all refined already
            // for balance (the round goes on with the rest).
            return if refusal.is_some() || consumed == 0 { None } else { Some((consumed, Vec::new())) };
        }
        self.counters.cells_created += units.len() as u64 * u64::from(UNIT);
        // New cells with their centres and depth (children of one parent share it).
        let mut cells: Vec<(u32, DVec3, u32)> = Vec::with_capacity(units.len() * UNIT as usize);
        // A parent's origin is its own parent's plus its octant's offset;
        // consecutive parents often share that grandparent, whose origin
        // (a walk up the parent chain) is then found once.
        let mut grand: Option<(u32, [u32; 3])> = None;
        for &(parent, unit) in &units {
            let d = u32::from(self.tree.depth()[parent as usize]);
            let o = if d == 0 {
                self.tree.origin(parent)
            } else {
                let g = self.tree.parent()[parent as usize];
                let og = match grand {
                    Some((c, o)) if c == g => o,
                    _ => {
                        let o = self.tree.origin(g);
                        grand = Some((g, o));
                        o
                    }
                };
                self.tree.child_origin(og, d - 1, parent % UNIT)
            };
            for k in 0..UNIT {
                let co = self.tree.child_origin(o, d, k);
                cells.push((unit + k, self.tree.lat.centre(co, d + 1), d + 1));
            }
        }
        let mut next = self.paint_new_cells(&cells, first);
        if refusal.is_some() {
            return None;
        }
        if self.stroke.as_ref().expect("stroke").deferred.any {
            let more = self.deferred_children(&units, &cells, &next);
            next.extend(more);
        }
        let st = self.stroke.as_ref().expect("stroke");
        let next = if st.settles { self.unsettled(next) } else { next.into_iter().map(|(c, _, _)| c).collect() };
        Some((consumed, next))
    }

    /// New children take their parent's before-value and their own stroke
    /// maximum over every primitive of the stroke so far (spec 8.8), and are
    /// always written: one outside the brush returns to its before-value.
    /// Values are decided in parallel for large rounds, written in order.
    ///
    /// The same pass tests each new cell for the next round (within reach
    /// of the segment `prims[first..]`, coarser than a target depth there,
    /// and not an empty cell an erase or recolour leaves alone): those are
    /// returned, in order, with their centres and reach radii.
    fn paint_new_cells(&mut self, cells: &[(u32, DVec3, u32)], first: usize) -> Vec<(u32, DVec3, f64)> {
        let st = self.stroke.as_ref().expect("stroke");
        let (lo, hi) = centre_bounds(cells.iter().map(|&(_, x, _)| x));
        // Only primitives whose box meets the new centres can cover them.
        let near: Vec<Prim> = st.prims.iter().filter(|p| p.overlaps(lo, hi)).copied().collect();
        let seg = &st.prims[first..];
        let lat = &self.tree.lat;
        let sigma_gate = matches!(st.brush.mode, Mode::Erase | Mode::Recolor);
        // A segment of one capsule (every sphere stroke) is the stroke's
        // last primitive, and the last of `near` when its box meets the new
        // centres: each centre is projected on it once, for its coverage
        // and for the next round's reach test.
        let seg_cap = match seg {
            [Prim { geo: Geometry::Capsule(cap), .. }] => Some(*cap),
            _ => None,
        };
        let seg_is_last_near = seg_cap.is_some() && seg[0].overlaps(lo, hi);
        let hardness = st.brush.hardness;
        let nc = NewCells { tree: &self.tree, st, near: &near, seg, sigma_gate };
        let (per_unit, per_cell);
        let values: &[FirstWrite] = match seg_cap {
            Some(cap) if lanes::available() && cells.len().is_multiple_of(LANES) && near.iter().all(|p| matches!(p.geo, Geometry::Capsule(_))) => {
                // Every primitive near is a capsule (every sphere stroke): a
                // unit's 8 children at once in vector lanes, and their
                // parent's before-value found once.
                let mut out = vec![FirstWrite::NONE; cells.len()];
                par::for_groups(cells, &mut out, LANES, |u, out| {
                    let (c0, _, d) = u[0];
                    let before = self.before_value(self.tree.parent()[c0 as usize]);
                    let xs: [DVec3; LANES] = std::array::from_fn(|l| u[l].1);
                    let h = lat.reach_radius[d as usize];
                    let m = lanes::unit_maximum(&near, hardness, &cap, seg_is_last_near, &xs, h).expect("lanes available");
                    for (l, o) in out.iter_mut().enumerate() {
                        *o = nc.decide((u[l].0, xs[l], d), before, (m.a[l], m.k[l] as usize), Some((m.seg_reach >> l & 1 == 1, m.seg_r[l])));
                    }
                });
                per_unit = out;
                &per_unit
            }
            None if cells.len().is_multiple_of(LANES)
                && lanes::available()
                && matches!(st.brush.shape, Shape::Box | Shape::Cylinder | Shape::Cone)
                && near.iter().all(|p| matches!(p.geo, Geometry::Stamp(_))) =>
            {
                // Box, cylinder and cone stamps: a unit's 8 children at once
                // in vector lanes, their parent's before-value found once,
                // and for a segment of one stamp its reach from the same
                // kernel as the paint pass's.
                let b = &st.brush;
                let seg_stamp = match seg {
                    [prim @ Prim { geo: Geometry::Stamp(s), .. }] => Some((*s, *prim)),
                    _ => None,
                };
                let mut out = vec![FirstWrite::NONE; cells.len()];
                par::for_groups(cells, &mut out, LANES, |u, out| {
                    let (c0, _, d) = u[0];
                    let before = self.before_value(self.tree.parent()[c0 as usize]);
                    let xs: [DVec3; LANES] = std::array::from_fn(|l| u[l].1);
                    let (a, k) = lanes::unit_stamp_maximum(&near, b.shape, b.aspect, b.hardness, &xs).expect("lanes available");
                    let h = lat.reach_radius[d as usize];
                    let seg = seg_stamp
                        .map(|(s, prim)| lanes::unit_stamp(&s, b.shape, b.aspect, &st.stamp_reach, &prim, b.hardness, &xs, h).expect("lanes available"));
                    for (l, o) in out.iter_mut().enumerate() {
                        *o = nc.decide((u[l].0, xs[l], d), before, (a[l], k[l] as usize), seg.as_ref().map(|u| (u.reach >> l & 1 == 1, u.r[l])));
                    }
                });
                per_unit = out;
                &per_unit
            }
            _ => {
                per_cell = par::map(cells, |&(c, x, d)| {
                    let before = self.before_value(self.tree.parent()[c as usize]);
                    let cp = seg_cap.map(|cap| cap.project(x));
                    let last = if seg_is_last_near { cp.as_ref() } else { None };
                    let (a, k) = if near.is_empty() { (0.0, 0) } else { stroke_maximum_with(st, &near, x, last) };
                    let seg_reach = seg_cap.zip(cp).map(|(cap, cp)| (cap.within_reach(&cp, lat.reach_radius[d as usize]), cp.r));
                    nc.decide((c, x, d), before, (a, k), seg_reach)
                });
                &per_cell
            }
        };
        self.counters.cells_written += values.len() as u64;
        self.first_writes_of_new_children(values);
        let mut next = Vec::new();
        for (v, &(_, x, d)) in values.iter().zip(cells) {
            if v.next {
                next.push((v.c, x, self.tree.lat.reach_radius[d as usize]));
            }
        }
        next
    }

    /// The new children of deferred parents are deferred too (spec 8.7).
    /// `units`: the round's (parent, first child) pairs, whose children
    /// `cells` (cell, centre, depth) lists unit by unit; `next`: the
    /// children the segment refines. The marked children that `next` does
    /// not hold, and that an erase or recolour does not leave alone (sigma
    /// as just painted), are tested against the stroke so far; returned are
    /// those it refines.
    fn deferred_children(&mut self, units: &[(u32, u32)], cells: &[(u32, DVec3, u32)], next: &[(u32, DVec3, f64)]) -> Vec<(u32, DVec3, f64)> {
        let st = self.stroke.as_mut().expect("stroke");
        let marked: Vec<usize> = (0..units.len())
            .filter(|&i| {
                let slot = self.slot_of.get(units[i].0);
                slot != NONE && st.deferred.get(slot)
            })
            .collect();
        if marked.is_empty() {
            return Vec::new();
        }
        let sigma_gate = matches!(st.brush.mode, Mode::Erase | Mode::Recolor);
        let (sigma, lat) = (self.tree.sigma(), &self.tree.lat);
        let refined: std::collections::HashSet<u32> = next.iter().map(|&(c, _, _)| c).collect();
        let mut test = Vec::new();
        for i in marked {
            for &(c, x, d) in &cells[i * UNIT as usize..(i + 1) * UNIT as usize] {
                st.deferred.set(self.slot_of.get(c), true);
                if !refined.contains(&c) && !(sigma_gate && !(sigma[c as usize] > 0.0)) {
                    test.push((c, x, lat.reach_radius[d as usize]));
                }
            }
        }
        if test.is_empty() { test } else { self.needed_by_stroke(test) }
    }

    /// [`Painting::first_write`] of a round's new children, in order: their
    /// slots appended together, then their values written (cells that
    /// `make_children` made in this step, journalled and marked already).
    pub(super) fn first_writes_of_new_children(&mut self, values: &[FirstWrite]) {
        let st = self.stroke.as_mut().expect("stroke");
        let first = st.slots.len();
        st.slots.extend(values.iter().map(|w| Slot::new(w.c, w.before_rgb, w.before_sigma)));
        // `record` gives a slot the maximum 0, and `first_write` raises it
        // when `a` is above 0.
        st.slot_a.extend(values.iter().map(|w| if w.a > 0.0 { w.a } else { 0.0 }));
        // A round's new cells are whole units, each its 8 children in order.
        for (i, u) in values.chunks_exact(UNIT as usize).enumerate() {
            debug_assert!(u.iter().enumerate().all(|(k, w)| w.c == u[0].c + k as u32) && u[0].c % UNIT == 0);
            self.slot_of.set_unit(u[0].c, (first + i * UNIT as usize) as u32);
            for w in u {
                self.tree.set_new_child_value(w.c, w.rgb, w.sigma);
            }
        }
    }
}

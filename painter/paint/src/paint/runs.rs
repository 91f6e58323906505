//! One run of the paint pass, walked as the serial pass walks it: the only
//! unsafe code of the painting. A run writes in place the leaves the
//! stroke has touched before (their cells and slots belong to that run
//! alone: the pools through octopaint-octree's [`InPlaceValues`], the
//! slots through its [`Disjoint`]) and hands back the first writes, the
//! cells and dirty blocks it wrote and the candidates for refinement.

use glam::DVec3;

use super::walks::Walk;
use super::{FirstWrite, Slot, StrokeState};
use crate::brush::TINY;
use crate::lanes::LANES;
use crate::slots::SlotMap;
use crate::stroke::Prim;
use octopaint_octree::par::Disjoint;
use octopaint_octree::pool::{InPlaceValues, NONE, Tree, UNIT};

/// What a run of the capsule paint pass reads, and the vectors it writes
/// in place (see [`Painting::paint_pass_walk`]).
pub(super) struct RunContext<'a, W> {
    pub(super) tree: &'a Tree,
    pub(super) st: &'a StrokeState,
    pub(super) slot_of: &'a SlotMap,
    pub(super) walk: &'a W,
    pub(super) prim: &'a Prim,
    pub(super) hardness: f64,
    pub(super) sigma_gate: bool,
    pub(super) values: InPlaceValues,
    pub(super) slot_a: Disjoint<f64>,
    pub(super) slots: Disjoint<Slot>,
}

impl<W: Walk> RunContext<'_, W> {
    /// The primitive's coverage·flow at `x`, which projects to `cp`: 0
    /// outside the primitive's box (spec 8.5). [`lanes::unit_coverage`]
    /// computes the same for a capsule at a unit's 8 children.
    #[inline]
    pub(super) fn coverage(&self, x: DVec3, cp: &W::Point) -> f64 {
        if self.prim.holds(x) { self.walk.coverage_at(x, cp, self.hardness) } else { 0.0 }
    }
}

/// Walk a run of the paint pass as the serial pass does: `out.stack` holds
/// its subtrees, the next to visit last, and its lists are empty. A cell's
/// children are tested for reach together, in vector lanes, before they
/// are pushed, so the stack above the run's own subtrees holds only cells
/// within reach (the serial pass would pop the others and skip them, so
/// the order of the rest is the same). A unit whose 8 children are all
/// leaves is done at once: the serial pass would pop them next, 7 to 0,
/// with nothing between, and their projections are independent, so the
/// processor overlaps their divisions and square roots.
pub(super) fn walk_run<W: Walk>(ctx: &RunContext<W>, mut out: Run) -> Run {
    let (tree, walk) = (ctx.tree, ctx.walk);
    let lat = &tree.lat;
    let mut stack = std::mem::take(&mut out.stack);
    // Entries below `untested` are the run's subtrees, not tested yet.
    let mut untested = stack.len();
    while let Some((c, o)) = stack.pop() {
        let d = u32::from(tree.depth()[c as usize]);
        let fc = tree.first_child()[c as usize];
        let tested = stack.len() >= untested;
        if !tested {
            untested = stack.len(); // what this cell pushes is tested
        }
        if !tested || fc == NONE {
            let x = lat.centre(o, d);
            let cp = walk.project(x);
            let h = lat.reach_radius[d as usize];
            if !tested && !walk.within_reach(&cp, h) {
                continue;
            }
            if fc == NONE {
                let (slot, radius, a) = (ctx.slot_of.get(c), walk.radius(&cp, h), ctx.coverage(x, &cp));
                leaf(ctx, &mut out, Leaf { cell: c, slot, depth: d, centre: x, radius, reach_radius: h, a });
                continue;
            }
        }
        let d1 = d + 1;
        let h1 = lat.reach_radius[d1 as usize];
        let xs: [DVec3; LANES] = std::array::from_fn(|k| lat.centre(tree.child_origin(o, d, k as u32), d1));
        let unit = &tree.first_child()[fc as usize..(fc + UNIT) as usize];
        if unit.iter().any(|&g| g != NONE) {
            let reach = walk.unit_reach(&xs, h1);
            for k in 0..UNIT {
                if reach >> k & 1 == 1 {
                    stack.push((fc + k, tree.child_origin(o, d, k)));
                }
            }
            continue;
        }
        // The unit's slots, found with one page lookup.
        let slots = ctx.slot_of.unit(fc).copied().unwrap_or([NONE; LANES]);
        if let Some(u) = walk.unit_coverage(ctx.prim, ctx.hardness, &xs, h1) {
            for k in (0..LANES).rev() {
                if u.reach >> k & 1 == 1 {
                    leaf(ctx, &mut out, Leaf { cell: fc + k as u32, slot: slots[k], depth: d1, centre: xs[k], radius: u.r[k], reach_radius: h1, a: u.a[k] });
                }
            }
            continue;
        }
        let cps: [W::Point; LANES] = std::array::from_fn(|k| walk.project(xs[k]));
        for k in (0..LANES).rev() {
            if walk.within_reach(&cps[k], h1) {
                let (radius, a) = (walk.radius(&cps[k], h1), ctx.coverage(xs[k], &cps[k]));
                leaf(ctx, &mut out, Leaf { cell: fc + k as u32, slot: slots[k], depth: d1, centre: xs[k], radius, reach_radius: h1, a });
            }
        }
    }
    out.stack = stack;
    out
}

/// A leaf within reach of the walk, as a run visits it.
#[derive(Clone, Copy)]
struct Leaf {
    cell: u32,
    /// Its slot in the stroke (NONE: untouched in this stroke).
    slot: u32,
    depth: u32,
    centre: DVec3,
    /// The walk's radius at the centre's projection (its target depth).
    radius: f64,
    /// The cell's half-diagonal (spec 8.7).
    reach_radius: f64,
    /// Coverage·flow at the centre (0 outside the primitive's box).
    a: f64,
}

/// A leaf within reach: its write (in place when its slot exists, else
/// kept for the serial part) and whether it is a candidate for refinement.
#[inline(always)]
fn leaf<W: Walk>(ctx: &RunContext<W>, out: &mut Run, leaf: Leaf) {
    let Leaf { cell: c, slot, depth: d, centre: x, radius: r, reach_radius: h, a } = leaf;
    out.visited += 1;
    // SAFETY (every in-place access here): `c` is a live cell of this
    // run's subtrees, which no other run holds, and its slot is its own;
    // the vectors do not change length while the runs go on.
    // Its stored sigma, read where it is needed: a leaf that is neither
    // new to the stroke nor written leaves its pools unread.
    let sigma_now = || unsafe { ctx.values.sigma(c) };
    // A deferred leaf (spec 8.7) coarser than no target of this segment may
    // still be coarser than an earlier primitive's: the serial part tests
    // it against the stroke so far.
    let coarser = ctx.tree.lat.coarser_than_target(d, r);
    let deferred = !coarser && ctx.st.deferred.any && slot != NONE && ctx.st.deferred.get(slot);
    let needs = (coarser || deferred) && !(ctx.sigma_gate && !(sigma_now() > 0.0));
    if a >= TINY {
        out.hit += 1;
        let colour = ctx.prim.colour;
        match slot {
            NONE => {
                let before_sigma = sigma_now();
                let before_rgb = unsafe { ctx.values.rgb(c) };
                let (rgb, sigma) = ctx.st.stored(before_rgb, before_sigma, colour, a);
                out.fresh.push(FirstWrite { c, before_rgb, before_sigma, a, rgb, sigma, next: false });
            }
            s => unsafe {
                // Touched before in this stroke, so written and journalled.
                let sa = &mut *ctx.slot_a.at(s as usize);
                if a > *sa {
                    *sa = a;
                    let slot = &*ctx.slots.at(s as usize);
                    let (rgb, sigma) = ctx.st.stored(slot.before_rgb, slot.before_sigma, colour, a);
                    ctx.values.set(ctx.tree, c, rgb, sigma);
                    out.written += 1;
                    // Its unit stands for it (the same parent; see
                    // Tree::note_values_written), once for the unit's run.
                    if out.wrote.last() != Some(&(c & !7)) {
                        out.wrote.push(c & !7);
                    }
                    let block = c / octopaint_octree::dirty::BLOCK_CELLS;
                    if out.blocks.last() != Some(&block) {
                        out.blocks.push(block);
                    }
                }
            },
        }
    }
    if needs {
        if coarser { out.needs.push((c, x, h)) } else { out.deferred.push((c, x, h)) }
    }
}

/// The most items' room a split pass's run keeps in each list for the next
/// (room for a pass of about 100,000 leaves on 2 threads; a list that grew
/// larger is given back).
pub(super) const SPARE_RUN_ITEMS: usize = 1 << 13;

/// What one run of the parallel paint pass leaves for the serial part.
#[derive(Clone, Default)]
pub(super) struct Run {
    pub(super) fresh: Vec<FirstWrite>,
    /// Leaves coarser than their target depth: (cell, centre, reach radius).
    pub(super) needs: Vec<(u32, DVec3, f64)>,
    /// Deferred leaves (spec 8.7) that this segment alone does not refine,
    /// the same way, for the test against the stroke so far.
    pub(super) deferred: Vec<(u32, DVec3, f64)>,
    /// Dirty blocks of the cells written in place, consecutive repeats dropped.
    pub(super) blocks: Vec<u32>,
    /// The units of the cells written in place, consecutive repeats dropped
    /// (their ancestors' values follow, spec 4.4).
    pub(super) wrote: Vec<u32>,
    pub(super) visited: u64,
    pub(super) hit: u64,
    pub(super) written: u64,
    /// The walk's stack, handed back for reuse.
    pub(super) stack: Vec<(u32, [u32; 3])>,
}

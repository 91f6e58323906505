//! Level 0 of a sample: the paint pass over every leaf within reach of the
//! segment (spec 8.7, 8.8), walked serially or split into runs across
//! threads as measured ([`SplitChoice`]). Reference twin:
//! `Painting._process_segment` and `_evaluate` in paint.py.

use glam::DVec3;

use super::runs::{Run, RunContext, SPARE_RUN_ITEMS, walk_run};
use super::walks::{SegmentWalk, StampWalk, Walk};
use super::{Painting, StrokeState};
use crate::lanes::LANES;
use crate::stroke::{Geometry, Prim};
use octopaint_model::{Mode, Shape};
use octopaint_octree::par;
use octopaint_octree::par::Disjoint;
use octopaint_octree::pool::NONE;

/// The capsule paint pass splits across threads when the cells its box
/// spans, over this, reach the grain: a split walk builds a front of
/// subtrees and keeps lists per run, which a few thousand cells do not
/// repay (r = 4 on two threads ran 3 times slower with it at the grain).
const WALK_GRAIN: f64 = 16.0;

/// Whether the capsule paint pass splits its walk across threads, chosen
/// by measurement: each way's recent cost per leaf visited, the cheaper
/// taken, the other tried for [`SplitChoice::TRY`] passes in every
/// [`SplitChoice::PERIOD`] (the last few of them measured), so that a
/// change of costs is followed, slowly. Splitting pays where cores are
/// many and a hand-off is cheap, and costs where they are few (a 2-core
/// host: `bench tree` at r = 10 on two threads, docs/benchmarks.md, "How
/// the core got here", the 16th step); the bytes are the same either way. Only passes the grain finds
/// worth splitting are measured, and each painting learns on its own.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SplitChoice {
    /// Nanoseconds and leaves visited of recent passes, unsplit [0] and
    /// split [1], each pass's weight decaying by 1/64 with every later
    /// pass measured the same way (with 1/16 the choice flipped on the
    /// noise of single passes at r = 32): their quotient is the cost per
    /// leaf, weighted by the passes' sizes as the run's time is.
    ns: [f64; 2],
    visits: [f64; 2],
    /// Passes chosen so far.
    pub(super) passes: u64,
    /// The way the last pass went, and how many passes in a row went so.
    pub(super) last: bool,
    streak: u32,
    /// Splitting was the cheaper way at the last pass outside the tries.
    cheaper: bool,
}

impl SplitChoice {
    /// Every PERIOD passes, TRY passes go the other way.
    const PERIOD: u64 = 128;
    const TRY: u64 = 8;
    /// Passes after a change of way that are not measured: the first ones
    /// after a change pay for the cache lines the other way left on other
    /// cores (measured, they made either way look dearer when tried
    /// among the other, and the choice stuck with whichever came first).
    const SETTLE: u32 = 2;

    /// Split the next pass: unsplit until measured, split until measured,
    /// then the cheaper way, but for TRY passes every PERIOD.
    fn choose(&mut self) -> bool {
        let split = if self.visits[0] == 0.0 {
            false
        } else if self.visits[1] == 0.0 {
            true
        } else if self.passes % Self::PERIOD >= Self::PERIOD - Self::TRY {
            // The tries go the other way from the choice before them, all
            // of them (what they measure does not switch them back).
            !self.cheaper
        } else {
            self.cheaper = self.ns[1] * self.visits[0] < self.ns[0] * self.visits[1];
            self.cheaper
        };
        self.passes += 1;
        if split == self.last {
            self.streak = self.streak.saturating_add(1);
        } else {
            self.last = split;
            self.streak = 1;
        }
        split
    }

    /// The pass just chosen took `ns` for `visits` leaves.
    pub(super) fn record(&mut self, ns: f64, visits: u64) {
        if self.streak <= Self::SETTLE || visits == 0 || !ns.is_finite() {
            return;
        }
        let w = usize::from(self.last);
        self.ns[w] = self.ns[w] * (63.0 / 64.0) + ns;
        self.visits[w] = self.visits[w] * (63.0 / 64.0) + visits as f64;
    }
}

impl Painting {
    /// Level 0: every leaf within reach of the segment (the top-down
    /// traversal of spec 8.7) is painted (spec 8.8); returns those that need
    /// refinement, decided on sigma as it was before the leaf was painted.
    pub(super) fn paint_pass(&mut self, first: usize) -> Vec<u32> {
        let st = self.stroke.as_ref().expect("stroke");
        let seg = &st.prims[first..];
        let lat = &self.tree.lat;
        let rs = lat.root_size;
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        for p in seg {
            lo = lo.min(p.lo);
            hi = hi.max(p.hi);
        }
        let mut box_lo = [0u32; 3];
        let mut box_hi = [0u32; 3];
        for a in 0..3 {
            let top = f64::from(lat.roots[a] - 1);
            let l = ((lo[a] - rs) / rs).floor().max(0.0);
            let h = ((hi[a] + rs) / rs).floor().min(top);
            if !(h >= l) {
                return Vec::new();
            }
            box_lo[a] = l as u32;
            box_hi[a] = h as u32;
        }
        let mut stack = std::mem::take(&mut self.spare_stack);
        stack.clear();
        for z in box_lo[2]..=box_hi[2] {
            for y in box_lo[1]..=box_hi[1] {
                for x in box_lo[0]..=box_hi[0] {
                    let r = lat.root_index([x, y, z]);
                    stack.push((r, lat.root_origin(r)));
                }
            }
        }
        let mut candidates = Vec::new();
        let st = self.stroke.as_ref().expect("stroke");
        match &st.prims[first..] {
            [prim @ Prim { geo: Geometry::Capsule(cap), .. }] => {
                let (cap, prim) = (*cap, *prim);
                self.spare_stack = self.paint_pass_walk(&cap, &prim, stack, &mut candidates);
                candidates
            }
            [prim @ Prim { geo: Geometry::Stamp(s), .. }] => {
                let (b, prim) = (&st.brush, *prim);
                let walk = StampWalk {
                    s: *s,
                    prim,
                    shape: b.shape,
                    aspect: b.aspect,
                    reach: st.stamp_reach,
                    hardness: b.hardness,
                    noise: (b.shape == Shape::Noise).then(|| (st.perm.clone(), *b)),
                };
                self.spare_stack = self.paint_pass_walk(&walk, &prim, stack, &mut candidates);
                candidates
            }
            prims => {
                // Several primitives (a stroke whose stamps lie closer than
                // its samples, a mirrored stroke): one walk over their
                // union's box, each leaf tested against all of them.
                let (lo, hi) = prims.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p.lo), hi.max(p.hi)));
                let union = Prim { lo, hi, ..prims[0] };
                let largest = prims.iter().fold(0.0f64, |m, p| match &p.geo {
                    Geometry::Capsule(c) => m.max(c.r0).max(c.r1),
                    Geometry::Stamp(s) => m.max(s.r),
                });
                let walk = SegmentWalk { seg: prims.to_vec(), brush: st.brush, perm: st.perm.clone(), reach: st.stamp_reach, largest };
                self.spare_stack = self.paint_pass_walk(&walk, &union, stack, &mut candidates);
                candidates
            }
        }
    }

    /// The paint pass of a segment, walked with `walk`: one capsule (every
    /// sphere stroke), one stamp (most segments of a stamped stroke, whose
    /// stamps lie half a radius apart or more), or several primitives
    /// ([`SegmentWalk`]). The top-down traversal of spec 8.7, each leaf
    /// within reach painted (spec 8.8), with the projection of each cell
    /// centre on a capsule computed once for reach, refinement and coverage,
    /// a capsule's unit of 8 leaves at a time (in vector lanes,
    /// [`crate::lanes`]), and on the current rayon pool when the primitive
    /// reaches enough leaves.
    /// Same result and same order of every list on any pool:
    ///
    /// 1. On more than one thread, for a pass the grain finds worth
    ///    splitting and the measured choice splits ([`SplitChoice`]; every
    ///    such pass with `par::set_measured_split(false)`), the traversal
    ///    stack is expanded top-down into a *front* of subtrees in the
    ///    order the serial pass visits them (a stack pops its last entry,
    ///    and a unit's children are visited 7 to 0), cut into runs.
    ///    Otherwise the stack is one run.
    /// 2. The runs are walked in parallel, each exactly as the serial pass
    ///    walks it ([`walk_run`]). A leaf the stroke touched before (it has
    ///    a slot) is blended and written in place: its cell and slot belong
    ///    to that run alone, and its journal entry was saved at its first
    ///    write. A leaf touched for the first time is only evaluated.
    /// 3. In the runs' order, serially: the first-touched leaves get their
    ///    slots and are written (journalled in the serial order), the dirty
    ///    blocks are marked, the cells written in place are listed for the
    ///    interior values (spec 4.4), and the candidates are joined.
    fn paint_pass_walk<W: Walk>(&mut self, walk: &W, prim: &Prim, mut stack: Vec<(u32, [u32; 3])>, candidates: &mut Vec<u32>) -> Vec<(u32, [u32; 3])> {
        let threads = rayon::current_num_threads();
        let lat = &self.tree.lat;
        let worth = threads > 1 && {
            let cell = lat.size_canvas[lat.target_depth(walk.largest_radius()) as usize];
            let reach = (prim.hi - prim.lo + 2.0 * cell).max(DVec3::splat(cell));
            par::worth((reach.x / cell * (reach.y / cell) * (reach.z / cell) / WALK_GRAIN).min(1e18) as usize)
        };
        let measured = worth && par::measured_split();
        let choice = if W::CAPSULE { &mut self.split } else { &mut self.split_stamp };
        let parallel = worth && (!measured || choice.choose());
        // What a measured pass took, from here to its lists joined.
        let start = measured.then(|| (std::time::Instant::now(), self.counters.leaves_visited));
        let (depth, first_child) = (self.tree.depth(), self.tree.first_child());
        // 1. The front, in visiting order, and its runs (parallel only).
        let mut front: Vec<(u32, [u32; 3])> = Vec::new();
        let mut bounds = vec![0];
        if parallel {
            // Internal cells larger than a quarter of the capsule's box are
            // opened, so that each one left holds a small share of the work
            // (it lies under internal cells; a leaf is one visit). Runs take
            // about equal volumes of internal cells, a few runs a thread,
            // and rayon's stealing evens out the rest. Depth first, from
            // the traversal's stack, so the front comes out in visiting
            // order: an open cell within reach gives way to its children
            // within reach (tested together in vector lanes, as the walk
            // tests them), anything else is a subtree of the front.
            let extent = (prim.hi - prim.lo).max_element();
            let open = |c: u32| first_child[c as usize] != NONE && lat.size_canvas[depth[c as usize] as usize] > 0.25 * extent;
            while let Some((c, o)) = stack.pop() {
                if !open(c) {
                    front.push((c, o));
                    continue;
                }
                let d = u32::from(depth[c as usize]);
                if !walk.within_reach(&walk.project(lat.centre(o, d)), lat.reach_radius[d as usize]) {
                    continue;
                }
                let (fc, d1) = (first_child[c as usize], d + 1);
                let os: [[u32; 3]; LANES] = std::array::from_fn(|k| self.tree.child_origin(o, d, k as u32));
                let reach = walk.unit_reach(&os.map(|o| lat.centre(o, d1)), lat.reach_radius[d1 as usize]);
                for (k, &o) in os.iter().enumerate() {
                    if reach >> k & 1 == 1 {
                        stack.push((fc + k as u32, o));
                    }
                }
            }
            let weight = |c: u32| if first_child[c as usize] == NONE { 0.0 } else { lat.size_canvas[depth[c as usize] as usize].powi(3) };
            let share = front.iter().map(|&(c, _)| weight(c)).sum::<f64>() / (8 * threads) as f64;
            let mut acc = 0.0;
            for (i, &(c, _)) in front.iter().enumerate() {
                acc += weight(c);
                if acc >= share {
                    bounds.push(i + 1);
                    acc = 0.0;
                }
            }
            if *bounds.last().expect("one bound") != front.len() {
                bounds.push(front.len());
            }
        }
        // 2. The runs.
        let mut spare_runs = std::mem::take(&mut self.spare_runs);
        let st = self.stroke.as_mut().expect("stroke");
        let slot_a = Disjoint::new(&mut st.slot_a);
        let slots = Disjoint::new(&mut st.slots);
        let st: &StrokeState = st;
        let (tree, values) = self.tree.in_place_values();
        let ctx = RunContext {
            tree,
            st,
            slot_of: &self.slot_of,
            walk,
            prim,
            hardness: st.brush.hardness,
            sigma_gate: matches!(st.brush.mode, Mode::Erase | Mode::Recolor),
            values,
            slot_a,
            slots,
        };
        let runs: Vec<Run> = if parallel {
            // Each run's stack pops its subtrees in visiting order; its lists
            // are those of an earlier split pass, emptied.
            let lists: Vec<std::sync::Mutex<Run>> = (1..bounds.len()).map(|_| std::sync::Mutex::new(spare_runs.pop().unwrap_or_default())).collect();
            par::tasks(bounds.len() - 1, |i| {
                let mut run = std::mem::take(&mut *lists[i].lock().unwrap_or_else(|e| e.into_inner()));
                run.stack.extend(front[bounds[i]..bounds[i + 1]].iter().rev());
                walk_run(&ctx, run)
            })
        } else {
            // One run: the traversal's stack itself, and the lists of the
            // last serial pass, kept between passes.
            vec![walk_run(&ctx, Run { stack: std::mem::take(&mut stack), ..std::mem::take(&mut self.spare_run) })]
        };
        // 3. In order, serially.
        let settles = st.settles;
        let mut maybe = Vec::new();
        let mut deferred = Vec::new();
        for mut run in runs {
            for &b in &run.blocks {
                self.tree.mark_block_written(b);
            }
            self.tree.note_values_written(&run.wrote);
            self.counters.cells_written += run.written + run.fresh.len() as u64;
            for f in &run.fresh {
                self.first_write(f);
            }
            self.counters.leaves_visited += run.visited;
            self.counters.leaves_hit += run.hit;
            if settles {
                maybe.append(&mut run.needs);
                deferred.append(&mut run.deferred);
            } else {
                candidates.extend(run.needs.iter().map(|&(c, _, _)| c));
            }
            if run.stack.capacity() > stack.capacity() {
                stack = std::mem::take(&mut run.stack);
            }
            run.fresh.clear();
            run.needs.clear();
            run.deferred.clear();
            run.blocks.clear();
            run.wrote.clear();
            run.stack.clear();
            let mut emptied =
                Run { fresh: run.fresh, needs: run.needs, deferred: run.deferred, blocks: run.blocks, wrote: run.wrote, stack: run.stack, ..Run::default() };
            if parallel {
                // A huge pass (a brush over millions of leaves) leaves no
                // lasting claim on memory: a kept list holds at most
                // SPARE_RUN_ITEMS items' room.
                emptied.fresh.shrink_to(SPARE_RUN_ITEMS);
                emptied.needs.shrink_to(SPARE_RUN_ITEMS);
                emptied.deferred.shrink_to(SPARE_RUN_ITEMS);
                emptied.blocks.shrink_to(SPARE_RUN_ITEMS);
                emptied.wrote.shrink_to(SPARE_RUN_ITEMS);
                emptied.stack.shrink_to(SPARE_RUN_ITEMS);
                spare_runs.push(emptied);
            } else {
                self.spare_run = emptied;
            }
        }
        self.spare_runs = spare_runs;
        if let Some((t0, visited)) = start {
            let choice = if W::CAPSULE { &mut self.split } else { &mut self.split_stamp };
            choice.record(t0.elapsed().as_nanos() as f64, self.counters.leaves_visited - visited);
        }
        if !deferred.is_empty() {
            maybe.extend(self.needed_by_stroke(deferred));
        }
        if !maybe.is_empty() {
            candidates.extend(self.unsettled(maybe));
        }
        stack.clear();
        stack
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `n` passes of 1,000 leaves through a split choice whose two ways
    /// cost `serial` and `split` ns a leaf, but a pass right after a change
    /// of way costs `penalty` times as much (the cache lines the other way
    /// left behind). Returns the passes split.
    fn split_passes(choice: &mut SplitChoice, n: u64, serial: f64, split: f64, penalty: f64) -> u64 {
        let mut splits = 0;
        let mut last = None;
        for _ in 0..n {
            let s = choice.choose();
            let cost = if s { split } else { serial } * if last.is_some_and(|l| l != s) { penalty } else { 1.0 };
            choice.record(cost * 1000.0, 1000);
            splits += u64::from(s);
            last = Some(s);
        }
        splits
    }

    #[test]
    fn the_split_choice_takes_the_cheaper_way_and_keeps_trying_the_other() {
        let n = 100 * SplitChoice::PERIOD;
        let tries = n / SplitChoice::PERIOD * SplitChoice::TRY;
        // Costs far apart and close (10% either way), with and without a
        // penalty for the first passes after a change of way: measuring
        // those passes, close costs left the choice on whichever way it
        // had, here unsplit.
        for penalty in [1.0, 3.0] {
            for (cheap, dear) in [(1.3, 3.0), (1.8, 2.2)] {
                let mut c = SplitChoice::default();
                let splits = split_passes(&mut c, n, 2.0, cheap, penalty);
                assert!(splits >= n - tries - 8 && splits <= n - tries + 8, "split at {cheap}, penalty {penalty}: {splits} of {n}");
                let mut c = SplitChoice::default();
                let splits = split_passes(&mut c, n, 2.0, dear, penalty);
                assert!(splits >= tries - 8 && splits <= tries + 8, "split at {dear}, penalty {penalty}: {splits} of {n}");
            }
        }
        // The costs change places: the choice follows within a few tries.
        let mut c = SplitChoice::default();
        split_passes(&mut c, n, 2.0, 1.3, 1.0);
        let later = split_passes(&mut c, 20 * SplitChoice::PERIOD, 1.3, 2.0, 1.0);
        assert!(later < 4 * SplitChoice::PERIOD, "still split {later} passes after splitting became dearer");
    }

    #[test]
    fn passes_right_after_a_change_of_way_are_not_measured() {
        let mut c = SplitChoice::default();
        assert!(!c.choose());
        // The first pass, right after no pass at all, is measured only from
        // the SETTLE+1th in a row.
        c.record(1e9, 1000);
        assert_eq!(c.visits[0], 0.0);
        for _ in 0..SplitChoice::SETTLE {
            assert!(!c.choose());
            c.record(1000.0, 1000);
        }
        assert_eq!(c.visits[0], 1000.0, "the third pass in a row is measured");
        assert_eq!(c.ns[0], 1000.0);
        // Then split, the first way not measured yet: again only from the
        // third split pass in a row.
        for k in 1..=SplitChoice::SETTLE + 1 {
            assert!(c.choose(), "split until measured");
            c.record(500.0, 1000);
            assert_eq!(c.visits[1] > 0.0, k > SplitChoice::SETTLE, "split pass {k} measured");
        }
        assert_eq!(c.ns[1], 500.0);
    }
}

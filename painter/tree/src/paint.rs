//! Painting on the tree: per-segment processing with one-level-at-a-time
//! refinement, per-stroke maximum blending, cleaning and undo (spec 8-10).
//! Reference twin: reference/octopaint_ref/paint.py.
//!
//! A `sample` event is processed in levels (spec 8.10): level 0 paints the
//! existing leaves within reach; every further level runs one refinement
//! round on the leaves that need it and paints the new children. Between
//! levels the tree is consistent and [`Tree::take_publication`] hands the
//! level's changes to whoever publishes them (the stroke thread of the
//! real-time pipeline). [`Painting::add_sample`] runs all levels at once.

use glam::DVec3;

use crate::brush::{self, Capsule, CapsulePoint, Stamp, StampReach, TINY, blend, quantize_rgb, quantize_sigma};
use crate::clean::clean;
use crate::history::History;
use crate::lanes::{self, LANES};
use crate::noise::permutation;
use crate::par;
use crate::pool::{NONE, Tree, UNIT};
use crate::slots::SlotMap;
use crate::stroke::{Geometry, Prim, StrokePath};
use crate::trace::{Brush, Canvas, Mode, Sample, Shape};

/// `v / 255.0` for every stored channel value, computed once (the same
/// correctly rounded quotients the blend would compute each time).
static UNIT_RGB: [f64; 256] = {
    let mut t = [0.0; 256];
    let mut v = 0;
    while v < 256 {
        t[v] = v as f64 / 255.0;
        v += 1;
    }
    t
};

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
/// host, two threads: r = 10's paint passes 1.01 s always split against
/// 0.72-0.75 s as measured, docs/benchmarks.md, issue 15's sixteenth
/// step); the bytes are the same either way. Only passes the grain finds
/// worth splitting are measured, and each painting learns on its own.
#[derive(Clone, Copy, Debug, Default)]
struct SplitChoice {
    /// Nanoseconds and leaves visited of recent passes, unsplit [0] and
    /// split [1], each pass's weight decaying by 1/64 with every later
    /// pass measured the same way (with 1/16 the choice flipped on the
    /// noise of single passes at r = 32): their quotient is the cost per
    /// leaf, weighted by the passes' sizes as the run's time is.
    ns: [f64; 2],
    visits: [f64; 2],
    /// Passes chosen so far.
    passes: u64,
    /// The way the last pass went, and how many passes in a row went so.
    last: bool,
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
    fn record(&mut self, ns: f64, visits: u64) {
        if self.streak <= Self::SETTLE || visits == 0 || !ns.is_finite() {
            return;
        }
        let w = usize::from(self.last);
        self.ns[w] = self.ns[w] * (63.0 / 64.0) + ns;
        self.visits[w] = self.visits[w] * (63.0 / 64.0) + visits as f64;
    }
}

/// A touched cell's stroke state (spec 8.8), but for its stroke maximum
/// `a`, which lives in its own array: the paint pass reads it for every
/// leaf and rarely needs the rest. The colour K of the primitive that
/// attained `a` is not kept: a cell is blended only when its maximum rises,
/// with the colour of the primitive that raised it (32 bytes a slot).
#[derive(Clone, Copy, Debug)]
struct Slot {
    cell: u32,
    before_rgb: [u8; 3],
    before_sigma: f32,
    /// The settled test's bounds `[a_lo, a_hi]` over the stroke's first
    /// `bounds_upto` primitives (0: not computed yet; NaN: a NaN bound).
    /// Both are maxima over primitives, so a later test folds in only the
    /// primitives added since.
    bounds: [f64; 2],
    bounds_upto: u32,
}

const _: () = assert!(std::mem::size_of::<Slot>() == 32);

impl Slot {
    /// A new slot of `cell` with its before-value, no bounds yet.
    fn new(cell: u32, before_rgb: [u8; 3], before_sigma: f32) -> Slot {
        Slot { cell, before_rgb, before_sigma, bounds: [0.0; 2], bounds_upto: 0 }
    }
}

/// The stroke in progress.
#[derive(Clone)]
struct StrokeState {
    brush: Brush,
    /// The stroke and its mirrored copies (spec 8.11), in painting order.
    paths: Vec<StrokePath>,
    /// The stroke colour K (moves toward the canvas in pickup mode).
    colour: [f64; 3],
    sigma_b: f64,
    alpha: f64,
    /// Every primitive of the stroke so far, in order.
    prims: Vec<Prim>,
    perm: Box<[u16; 512]>,
    stamp_reach: StampReach,
    /// Leaves may be settled (spec 8.7): a sphere brush whose colour stays
    /// the same along the stroke (every mode but pickup).
    settles: bool,
    refusal_warned: bool,
    slots: Vec<Slot>,
    /// The stroke maximum of coverage·flow of each slot.
    slot_a: Vec<f64>,
}

/// The segment being processed, between levels.
#[derive(Clone)]
struct SegmentWork {
    /// The segment's primitives are `prims[first..]`.
    first: usize,
    line: usize,
    stage: Stage,
}

#[derive(Clone)]
enum Stage {
    /// The paint pass comes next.
    PaintPass,
    /// A round is under way: its candidates, ascending, from `at` on are
    /// still to refine; `next` gathers the new cells that need refinement
    /// (the next round's candidates).
    Round { candidates: Vec<u32>, at: usize, next: Vec<u32> },
}

/// Work counters, for benchmarks and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PaintCounters {
    /// Leaves within reach visited by paint passes.
    pub leaves_visited: u64,
    /// Of those, the leaves with coverage > 0 (cell updates: each is
    /// compared with its stroke maximum and rewritten when it rises).
    pub leaves_hit: u64,
    /// Cells rewritten with a new blended value.
    pub cells_written: u64,
    /// Cells created by refinement.
    pub cells_created: u64,
    /// Leaves within reach and coarser than their target depth that were
    /// left unrefined because they are settled (spec 8.7).
    pub leaves_settled: u64,
    /// Refinement rounds refused by the cell budget or memory.
    pub refusals: u64,
    /// Cells collapsed by cleaning.
    pub collapses: u64,
    /// Time in paint passes (level 0), in refinement levels (rounds plus
    /// painting the new children), and in cleaning and undo bookkeeping at
    /// stroke end, in nanoseconds.
    pub paint_pass_ns: u64,
    pub refine_ns: u64,
    pub stroke_end_ns: u64,
}

impl StrokeState {
    /// What a cell with `before` stores after blending the colour `colour`
    /// at stroke maximum `a` (spec 8.5, rounded by spec 5).
    #[inline(always)]
    fn stored(&self, before_rgb: [u8; 3], before_sigma: f32, colour: [f64; 3], a: f64) -> ([u8; 3], f32) {
        if a == 0.0 && before_sigma.is_finite() {
            // The blend keeps the cell, and rounding a stored value gives
            // it back: `v / 255` to a byte is `v`, and a finite f32 through
            // f64 is itself (half the new children lie outside the brush).
            return (before_rgb, before_sigma);
        }
        if a == 0.0 {
            return self.stored_general(before_rgb, before_sigma, colour, a); // a NaN or infinite density
        }
        let (rgb, sigma) = self.blended(before_rgb, f64::from(before_sigma), colour, a);
        (quantize_rgb(rgb), quantize_sigma(sigma))
    }

    /// `brush::blend` of a cell at `a != 0`, channel by channel, with the
    /// same operations in the same order (so the same bits, unrounded): no
    /// arrays through memory, which the general form moves, and no call.
    #[inline(always)]
    fn blended(&self, before_rgb: [u8; 3], bs: f64, colour: [f64; 3], a: f64) -> ([f64; 3], f64) {
        let before = |i: usize| UNIT_RGB[before_rgb[i] as usize];
        match self.brush.mode {
            Mode::Paint | Mode::Pickup => {
                let fresh = bs == 0.0;
                let channel = |i: usize| {
                    let base = if fresh { colour[i] } else { before(i) };
                    base + (colour[i] - base) * a
                };
                ([channel(0), channel(1), channel(2)], bs + (self.sigma_b - bs) * a)
            }
            Mode::Erase => ([before(0), before(1), before(2)], bs * (1.0 - a * self.alpha)),
            Mode::Recolor if bs > 0.0 => {
                let t = a * self.alpha;
                let channel = |i: usize| before(i) + (colour[i] - before(i)) * t;
                ([channel(0), channel(1), channel(2)], bs)
            }
            Mode::Recolor => ([before(0), before(1), before(2)], bs),
            Mode::Mix => {
                let fresh = bs == 0.0;
                let mut wb = self.brush.mix_ratio * a * self.sigma_b;
                if wb < TINY {
                    wb = 0.0;
                }
                let den = bs + wb;
                let channel = |i: usize| {
                    let base = if fresh { colour[i] } else { before(i) };
                    if den > 0.0 { (bs * base + wb * colour[i]) / den } else { base }
                };
                ([channel(0), channel(1), channel(2)], bs + a * self.sigma_b)
            }
        }
    }

    /// [`StrokeState::stored`] for every mode, through `brush::blend`.
    #[inline(never)]
    fn stored_general(&self, before_rgb: [u8; 3], before_sigma: f32, colour: [f64; 3], a: f64) -> ([u8; 3], f32) {
        let before = [UNIT_RGB[before_rgb[0] as usize], UNIT_RGB[before_rgb[1] as usize], UNIT_RGB[before_rgb[2] as usize]];
        let b = &self.brush;
        let (rgb, sigma) = blend(b.mode, before, f64::from(before_sigma), colour, self.sigma_b, self.alpha, a, b.mix_ratio);
        (quantize_rgb(rgb), quantize_sigma(sigma))
    }
}

/// A tree plus the strokes painted on it.
#[derive(Clone)]
pub struct Painting {
    pub tree: Tree,
    pub history: History,
    pub counters: PaintCounters,
    /// Warnings in the order they happened (the replay prints them).
    pub warnings: Vec<String>,
    stroke: Option<StrokeState>,
    work: Option<SegmentWork>,
    /// cell -> slot in the stroke, NONE when untouched; cleared per stroke.
    slot_of: SlotMap,
    /// Allocations kept from one stroke or level to the next.
    spare_slots: Vec<Slot>,
    spare_slot_a: Vec<f64>,
    spare_stack: Vec<(u32, [u32; 3])>,
    /// The serial paint pass's lists, emptied (their capacity kept).
    spare_run: Run,
    /// The split paint pass's runs' lists, emptied the same way.
    spare_runs: Vec<Run>,
    /// Whether the paint pass of one capsule, and of one stamp, splits its
    /// walk, as measured (their costs a leaf differ).
    split: SplitChoice,
    split_stamp: SplitChoice,
    /// Settled leaves are left unrefined (spec 8.7); off only to measure
    /// what the rule saves and to test that it changes no value.
    settling: bool,
}

impl Painting {
    pub fn new(canvas: &Canvas) -> Self {
        Painting::from_parts(Tree::new(canvas), History::default())
    }

    /// A painting resumed from a saved tree and its undo history (a
    /// document); no stroke open.
    pub fn from_parts(tree: Tree, history: History) -> Self {
        Painting {
            tree,
            history,
            counters: PaintCounters::default(),
            warnings: Vec::new(),
            stroke: None,
            work: None,
            slot_of: SlotMap::default(),
            spare_slots: Vec::new(),
            spare_slot_a: Vec::new(),
            spare_stack: Vec::new(),
            spare_run: Run::default(),
            spare_runs: Vec::new(),
            split: SplitChoice::default(),
            split_stamp: SplitChoice::default(),
            settling: true,
        }
    }

    /// Turn the settled-leaf rule of spec 8.7 off (or on again) from the
    /// next stroke: without it every leaf within reach refines to its
    /// target depth and cleaning removes what did not need to be there.
    /// The values at every centre are the same either way; benchmarks and
    /// tests compare the two. Documents and traces always paint with it.
    pub fn set_settling(&mut self, on: bool) {
        self.settling = on;
    }

    pub fn in_stroke(&self) -> bool {
        self.stroke.is_some()
    }

    pub fn begin_stroke(&mut self, brush: &Brush) {
        assert!(self.stroke.is_none(), "a stroke is already open");
        self.tree.begin_journal();
        self.stroke = Some(StrokeState {
            brush: *brush,
            paths: StrokePath::all(*brush),
            colour: brush.color,
            sigma_b: brush::sigma_brush(brush.opacity, brush.radius),
            alpha: brush.opacity,
            prims: Vec::new(),
            perm: Box::new(if brush.shape == Shape::Noise { permutation(brush.noise.seed) } else { [0; 512] }),
            stamp_reach: StampReach::new(brush.aspect),
            settles: self.settling && brush.shape == Shape::Sphere && brush.mode != Mode::Pickup,
            refusal_warned: false,
            slots: std::mem::take(&mut self.spare_slots),
            slot_a: std::mem::take(&mut self.spare_slot_a),
        });
    }

    /// Process one sample completely (all levels).
    pub fn add_sample(&mut self, sample: &Sample, line: usize) {
        self.begin_sample(sample, line);
        while !self.step_level() {}
    }

    /// Start a sample: pickup, then the segment's primitives (spec 8.10
    /// steps 1-2). The levels follow with [`Painting::step_level`].
    pub fn begin_sample(&mut self, sample: &Sample, line: usize) {
        assert!(self.work.is_none(), "the previous sample is not finished");
        let tree = &self.tree;
        let st = self.stroke.as_mut().expect("sample outside a stroke");
        if st.brush.mode == Mode::Pickup {
            if let Some(c) = tree.leaf_at(sample.p) {
                if tree.sigma[c as usize] > 0.0 {
                    let canvas = tree.rgb[c as usize].map(|v| f64::from(v) / 255.0);
                    let rate = st.brush.pickup_rate;
                    st.colour = [0, 1, 2].map(|i| st.colour[i] + (canvas[i] - st.colour[i]) * rate);
                }
            }
        }
        let first = st.prims.len();
        let colour = st.colour;
        for path in &mut st.paths {
            path.segment(sample, colour, &mut st.prims);
        }
        if st.prims.len() > first {
            self.work = Some(SegmentWork { first, line, stage: Stage::PaintPass });
        }
    }

    /// Run one level of the current sample. Returns true when the sample is
    /// finished (also when there was nothing to do).
    pub fn step_level(&mut self) -> bool {
        self.step(None)
    }

    /// One step of the current sample: the paint pass, or a round of
    /// refinement, or with `max_units` only the part of a round that
    /// allocates about that many units (and paints their children). Smaller
    /// steps publish sooner (the real-time pipeline's aggressive staging);
    /// the tree is 2:1 balanced after every step, and the final tree is the
    /// same for any step size. Returns true when the sample is finished.
    pub fn step(&mut self, max_units: Option<usize>) -> bool {
        let Some(mut work) = self.work.take() else { return true };
        let t0 = std::time::Instant::now();
        let more = match std::mem::replace(&mut work.stage, Stage::PaintPass) {
            Stage::PaintPass => {
                let mut candidates = self.paint_pass(work.first);
                par::sort_dedup(&mut candidates);
                let more = !candidates.is_empty();
                work.stage = Stage::Round { candidates, at: 0, next: Vec::new() };
                self.counters.paint_pass_ns += t0.elapsed().as_nanos() as u64;
                more
            }
            Stage::Round { candidates, at, mut next } => {
                let part = self.refine_part(&candidates[at..], max_units.unwrap_or(usize::MAX), work.first, work.line);
                let more = match part {
                    None => false,
                    Some((consumed, new_needing)) => {
                        next.extend(new_needing);
                        if at + consumed < candidates.len() {
                            work.stage = Stage::Round { candidates, at: at + consumed, next };
                            true
                        } else if next.is_empty() {
                            false
                        } else {
                            par::sort_dedup(&mut next);
                            work.stage = Stage::Round { candidates: next, at: 0, next: Vec::new() };
                            true
                        }
                    }
                };
                self.counters.refine_ns += t0.elapsed().as_nanos() as u64;
                more
            }
        };
        if more {
            self.work = Some(work);
        }
        !more
    }

    /// End the stroke: clean (spec 9) and make it one undo step (spec 10).
    pub fn end_stroke(&mut self) {
        assert!(self.work.is_none(), "the last sample is not finished");
        let t0 = std::time::Instant::now();
        let mut st = self.stroke.take().expect("no stroke open");
        self.slot_of.clear(st.slots.iter().map(|s| s.cell));
        self.clean_and_commit(st.slots.iter().map(|s| s.cell));
        st.slots.clear();
        st.slot_a.clear();
        self.spare_slots = st.slots;
        self.spare_slot_a = st.slot_a;
        self.counters.stroke_end_ns += t0.elapsed().as_nanos() as u64;
    }

    /// The end of a stroke or an import: cleaning from the touched cells
    /// (spec 9), then the journal made one undo step (spec 10), which drops
    /// the redo history.
    fn clean_and_commit(&mut self, touched: impl IntoIterator<Item = u32>) {
        let collapses = clean(&mut self.tree, touched);
        self.counters.collapses += collapses as u64;
        let step = self.tree.commit_journal();
        self.history.done.push(step);
        self.history.undone.clear();
    }

    /// Paint a voxel set (an `import` event, spec 15.3) as one undo step:
    /// the traversal, paint pass and rounds of [`crate::voxels`], then
    /// cleaning and the undo step, as at the end of a stroke.
    pub fn import_voxels(&mut self, vs: &crate::voxels::VoxelSet, line: usize) {
        assert!(self.stroke.is_none(), "an import inside a stroke");
        let t0 = std::time::Instant::now();
        self.tree.begin_journal();
        let work = crate::voxels::paint_voxels(&mut self.tree, vs, line, &mut self.warnings);
        self.counters.cells_created += work.created;
        self.counters.refusals += work.refusals;
        self.counters.cells_written += work.touched.len() as u64;
        self.clean_and_commit(work.touched);
        self.counters.refine_ns += t0.elapsed().as_nanos() as u64;
    }

    /// Bytes the cell-to-slot map holds (its pages, kept from stroke to
    /// stroke: as many as the stroke that touched the most pages used).
    pub fn slot_map_bytes(&self) -> usize {
        self.slot_of.bytes()
    }

    /// Undo the last stroke; false if there is none.
    pub fn undo(&mut self) -> bool {
        assert!(self.stroke.is_none(), "undo inside a stroke");
        let Some(mut step) = self.history.done.pop() else { return false };
        // The pools hold the step's after-records: they are copied out, for
        // redo, before the before-records are written back.
        step.take_after_from_pools(&self.tree);
        self.tree.apply_step(&step, false);
        self.history.undone.push(step);
        true
    }

    /// Redo the last undone stroke; false if there is none.
    pub fn redo(&mut self) -> bool {
        assert!(self.stroke.is_none(), "redo inside a stroke");
        let Some(step) = self.history.undone.pop() else { return false };
        self.tree.apply_step(&step, true);
        self.history.done.push(step);
        true
    }

    // ------------------------------------------------------------ levels

    /// Level 0: every leaf within reach of the segment (the top-down
    /// traversal of spec 8.7) is painted (spec 8.8); returns those that need
    /// refinement, decided on sigma as it was before the leaf was painted.
    fn paint_pass(&mut self, first: usize) -> Vec<u32> {
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
                self.spare_stack = self.paint_pass_one(&cap, &prim, stack, &mut candidates);
                candidates
            }
            [prim @ Prim { geo: Geometry::Stamp(s), .. }] => {
                let (b, prim) = (&st.brush, *prim);
                let walk = StampWalk { s: *s, prim, shape: b.shape, aspect: b.aspect, reach: st.stamp_reach, hardness: b.hardness, noise: (b.shape == Shape::Noise).then(|| (st.perm.clone(), *b)) };
                self.spare_stack = self.paint_pass_one(&walk, &prim, stack, &mut candidates);
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
                self.spare_stack = self.paint_pass_one(&walk, &union, stack, &mut candidates);
                candidates
            }
        }
    }

    /// The paint pass of a segment, walked with `cap`: one capsule (every
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
    ///    blocks are marked, and the candidates are joined.
    fn paint_pass_one<W: Walk>(
        &mut self,
        cap: &W,
        prim: &Prim,
        mut stack: Vec<(u32, [u32; 3])>,
        candidates: &mut Vec<u32>,
    ) -> Vec<(u32, [u32; 3])> {
        let threads = rayon::current_num_threads();
        let lat = &self.tree.lat;
        let worth = threads > 1 && {
            let cell = lat.size_canvas[lat.target_depth(cap.largest_radius()) as usize];
            let reach = (prim.hi - prim.lo + 2.0 * cell).max(DVec3::splat(cell));
            par::worth((reach.x / cell * (reach.y / cell) * (reach.z / cell) / WALK_GRAIN).min(1e18) as usize)
        };
        let measured = worth && par::measured_split();
        let choice = if W::CAPSULE { &mut self.split } else { &mut self.split_stamp };
        let parallel = worth && (!measured || choice.choose());
        // What a measured pass took, from here to its lists joined.
        let start = measured.then(|| (std::time::Instant::now(), self.counters.leaves_visited));
        let (depth, first_child) = (&self.tree.depth, &self.tree.first_child);
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
                if !cap.within_reach(&cap.project(lat.centre(o, d)), lat.reach_radius[d as usize]) {
                    continue;
                }
                let (fc, d1) = (first_child[c as usize], d + 1);
                let os: [[u32; 3]; LANES] = std::array::from_fn(|k| self.tree.child_origin(o, d, k as u32));
                let reach = cap.unit_reach(&os.map(|o| lat.centre(o, d1)), lat.reach_radius[d1 as usize]);
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
        let tree = &mut self.tree;
        let (rgb, sigma) = (Disjoint::new(&mut tree.rgb), Disjoint::new(&mut tree.sigma));
        let ctx = RunContext {
            tree,
            st,
            slot_of: &self.slot_of,
            cap,
            prim,
            hardness: st.brush.hardness,
            sigma_gate: matches!(st.brush.mode, Mode::Erase | Mode::Recolor),
            rgb,
            sigma,
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
        for mut run in runs {
            for &b in &run.blocks {
                self.tree.changes.mark_block(b * crate::dirty::BLOCK_CELLS);
            }
            self.counters.cells_written += run.written + run.fresh.len() as u64;
            for f in &run.fresh {
                self.first_write(f);
            }
            self.counters.leaves_visited += run.visited;
            self.counters.leaves_hit += run.hit;
            if settles {
                maybe.append(&mut run.needs);
            } else {
                candidates.extend(run.needs.iter().map(|&(c, _, _)| c));
            }
            if run.stack.capacity() > stack.capacity() {
                stack = std::mem::take(&mut run.stack);
            }
            run.fresh.clear();
            run.needs.clear();
            run.blocks.clear();
            run.stack.clear();
            let mut emptied = Run { fresh: run.fresh, needs: run.needs, blocks: run.blocks, stack: run.stack, ..Run::default() };
            if parallel {
                // A huge pass (a brush over millions of leaves) leaves no
                // lasting claim on memory: a kept list holds at most
                // SPARE_RUN_ITEMS items' room.
                emptied.fresh.shrink_to(SPARE_RUN_ITEMS);
                emptied.needs.shrink_to(SPARE_RUN_ITEMS);
                emptied.blocks.shrink_to(SPARE_RUN_ITEMS);
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
        if !maybe.is_empty() {
            candidates.extend(self.unsettled(maybe));
        }
        stack.clear();
        stack
    }

    /// The cells among `leaves` (cell, centre, reach radius) that are not
    /// settled, in order; the settled ones are counted. The tests run in
    /// parallel, each over the capsules whose boxes meet the leaves' balls;
    /// each touched leaf's bounds are written back after.
    fn unsettled(&mut self, leaves: Vec<(u32, DVec3, f64)>) -> Vec<u32> {
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
        for (&(c, _, _), (settled, bounds)) in leaves.iter().zip(tests) {
            if let Some((slot, bounds)) = bounds {
                let s = &mut st.slots[slot as usize];
                s.bounds = bounds;
                s.bounds_upto = upto;
            }
            if settled {
                self.counters.leaves_settled += 1;
            } else {
                out.push(c);
            }
        }
        out
    }

    /// Refinement of (part of) a round's sorted candidates, then the new
    /// children painted (spec 8.10 step 6). Returns how many candidates were
    /// consumed and the new cells that need refinement, or None when the
    /// segment stops: a refusal, or a round that allocated nothing.
    fn refine_part(&mut self, candidates: &[u32], max_units: usize, first: usize, line: usize) -> Option<(usize, Vec<u32>)> {
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
            let d = u32::from(self.tree.depth[parent as usize]);
            let o = if d == 0 {
                self.tree.origin(parent)
            } else {
                let g = self.tree.parent[parent as usize];
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
        let next = self.paint_new_cells(&cells, first);
        if refusal.is_some() {
            return None;
        }
        let st = self.stroke.as_ref().expect("stroke");
        let next = if st.settles {
            self.unsettled(next)
        } else {
            next.into_iter().map(|(c, _, _)| c).collect()
        };
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
                    let before = self.before_value(self.tree.parent[c0 as usize]);
                    let xs: [DVec3; LANES] = std::array::from_fn(|l| u[l].1);
                    let h = lat.reach_radius[d as usize];
                    let m = lanes::unit_maximum(&near, hardness, &cap, seg_is_last_near, &xs, h).expect("lanes available");
                    for (l, o) in out.iter_mut().enumerate() {
                        *o = nc.decide(u[l].0, xs[l], d, before, m.a[l], m.k[l] as usize, Some((m.seg_reach >> l & 1 == 1, m.seg_r[l])));
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
                    let before = self.before_value(self.tree.parent[c0 as usize]);
                    let xs: [DVec3; LANES] = std::array::from_fn(|l| u[l].1);
                    let (a, k) = lanes::unit_stamp_maximum(&near, b.shape, b.aspect, b.hardness, &xs).expect("lanes available");
                    let h = lat.reach_radius[d as usize];
                    let seg = seg_stamp.map(|(s, prim)| lanes::unit_stamp(&s, b.shape, b.aspect, &st.stamp_reach, &prim, b.hardness, &xs, h).expect("lanes available"));
                    for (l, o) in out.iter_mut().enumerate() {
                        *o = nc.decide(u[l].0, xs[l], d, before, a[l], k[l] as usize, seg.as_ref().map(|u| (u.reach >> l & 1 == 1, u.r[l])));
                    }
                });
                per_unit = out;
                &per_unit
            }
            _ => {
                per_cell = par::map(cells, |&(c, x, d)| {
                    let before = self.before_value(self.tree.parent[c as usize]);
                    let cp = seg_cap.map(|cap| cap.project(x));
                    let last = if seg_is_last_near { cp.as_ref() } else { None };
                    let (a, k) = if near.is_empty() { (0.0, 0) } else { stroke_maximum_with(st, &near, x, last) };
                    let seg_reach = seg_cap.zip(cp).map(|(cap, cp)| (cap.within_reach(&cp, lat.reach_radius[d as usize]), cp.r));
                    nc.decide(c, x, d, before, a, k, seg_reach)
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

    /// [`Painting::first_write`] of a round's new children, in order: their
    /// slots appended together, then their values written (cells that
    /// `make_children` made in this step, journalled and marked already).
    fn first_writes_of_new_children(&mut self, values: &[FirstWrite]) {
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

    /// A leaf's first write in the stroke, decided already by a paint-pass
    /// run: its slot with its before-value, its maximum when `a` rose above
    /// 0 (the slot's maximum starts at 0), and the stored value. (A
    /// round's new children: [`Painting::first_writes_of_new_children`].)
    fn first_write(&mut self, w: &FirstWrite) {
        let slot = self.record(w.c, w.before_rgb, w.before_sigma) as usize;
        if w.a > 0.0 {
            let st = self.stroke.as_mut().expect("stroke");
            st.slot_a[slot] = w.a;
        }
        self.tree.set_value(w.c, w.rgb, w.sigma);
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
    fn settled(&self, c: u32, x: DVec3, h: f64, caps: &[(u32, Prim)]) -> (bool, Option<(u32, [f64; 2])>) {
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

    /// `c`'s before-value (spec 8.8): the one its slot recorded when the
    /// stroke touched it, else its stored value.
    fn before_value(&self, c: u32) -> ([u8; 3], f32) {
        match self.slot_of.get(c) {
            NONE => (self.tree.rgb[c as usize], self.tree.sigma[c as usize]),
            s => {
                let s = &self.stroke.as_ref().expect("stroke").slots[s as usize];
                (s.before_rgb, s.before_sigma)
            }
        }
    }

    /// Give `c` a slot with its before-value (a = 0).
    fn record(&mut self, c: u32, before_rgb: [u8; 3], before_sigma: f32) -> u32 {
        let st = self.stroke.as_mut().expect("stroke");
        let slot = st.slots.len() as u32;
        st.slots.push(Slot::new(c, before_rgb, before_sigma));
        st.slot_a.push(0.0);
        self.slot_of.set(c, slot);
        slot
    }
}

/// A vector's elements, written by the parallel paint pass through a raw
/// pointer: each run touches only the cells of its own subtrees and their
/// slots, so no element is accessed by two threads.
#[derive(Clone, Copy)]
struct Disjoint<T> {
    ptr: *mut T,
    len: usize,
}

// SAFETY: the pointer is only dereferenced at elements one run owns (see
// `Painting::paint_pass_capsule`).
unsafe impl<T: Send> Send for Disjoint<T> {}
unsafe impl<T: Send> Sync for Disjoint<T> {}

impl<T> Disjoint<T> {
    fn new(v: &mut [T]) -> Self {
        Disjoint { ptr: v.as_mut_ptr(), len: v.len() }
    }

    /// Element `i` (checked against the length: an index past it panics).
    ///
    /// # Safety
    /// No other thread accesses element `i` while the pointer is used, and
    /// the vector is not resized meanwhile.
    #[inline]
    unsafe fn at(self, i: usize) -> *mut T {
        assert!(i < self.len, "cell or slot {i} out of range");
        unsafe { self.ptr.add(i) }
    }
}

/// What a run of the capsule paint pass reads, and the vectors it writes
/// in place (see [`Painting::paint_pass_capsule`]).
struct RunContext<'a, W> {
    tree: &'a Tree,
    st: &'a StrokeState,
    slot_of: &'a SlotMap,
    cap: &'a W,
    prim: &'a Prim,
    hardness: f64,
    sigma_gate: bool,
    rgb: Disjoint<[u8; 3]>,
    sigma: Disjoint<f32>,
    slot_a: Disjoint<f64>,
    slots: Disjoint<Slot>,
}

impl<W: Walk> RunContext<'_, W> {
    /// The primitive's coverage·flow at `x`, which projects to `cp`: 0
    /// outside the primitive's box (spec 8.5). [`lanes::unit_coverage`]
    /// computes the same for a capsule at a unit's 8 children.
    #[inline]
    fn coverage(&self, x: DVec3, cp: &W::Point) -> f64 {
        if self.prim.holds(x) { self.cap.coverage_at(x, cp, self.hardness) } else { 0.0 }
    }
}

/// [`Walk::within_reach`] of the 8 centres `xs`, one at a time, as a mask
/// (bit k: lane k): the walk's test where no kernel does it.
#[inline(always)]
fn reach_each<W: Walk + ?Sized>(w: &W, xs: &[DVec3; LANES], h: f64) -> u8 {
    (0..LANES).fold(0, |m, k| m | u8::from(w.within_reach(&w.project(xs[k]), h)) << k)
}

/// What [`walk_run`] paints a segment with: one capsule, one stamp, or the
/// segment's primitives together, each through the tests of spec 8.7 and
/// the stroke maximum of spec 8.8.
trait Walk: Sync {
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
struct StampWalk {
    s: Stamp,
    prim: Prim,
    shape: Shape,
    aspect: [f64; 3],
    reach: StampReach,
    hardness: f64,
    noise: Option<(Box<[u16; 512]>, Brush)>,
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
struct SegmentWalk {
    seg: Vec<Prim>,
    brush: Brush,
    perm: Box<[u16; 512]>,
    reach: StampReach,
    largest: f64,
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
    fn coverage_at(&self, x: DVec3, _x: &DVec3, hardness: f64) -> f64 {
        debug_assert_eq!(hardness, self.brush.hardness);
        stroke_maximum_of(&self.brush, &self.perm, &self.seg, x, None).0
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
fn walk_run<W: Walk>(ctx: &RunContext<W>, mut out: Run) -> Run {
    let (tree, cap) = (ctx.tree, ctx.cap);
    let lat = &tree.lat;
    let mut stack = std::mem::take(&mut out.stack);
    // Entries below `untested` are the run's subtrees, not tested yet.
    let mut untested = stack.len();
    while let Some((c, o)) = stack.pop() {
        let d = u32::from(tree.depth[c as usize]);
        let fc = tree.first_child[c as usize];
        let tested = stack.len() >= untested;
        if !tested {
            untested = stack.len(); // what this cell pushes is tested
        }
        if !tested || fc == NONE {
            let x = lat.centre(o, d);
            let cp = cap.project(x);
            let h = lat.reach_radius[d as usize];
            if !tested && !cap.within_reach(&cp, h) {
                continue;
            }
            if fc == NONE {
                leaf(ctx, &mut out, c, ctx.slot_of.get(c), d, x, cap.radius(&cp, h), h, ctx.coverage(x, &cp));
                continue;
            }
        }
        let d1 = d + 1;
        let h1 = lat.reach_radius[d1 as usize];
        let xs: [DVec3; LANES] = std::array::from_fn(|k| lat.centre(tree.child_origin(o, d, k as u32), d1));
        let unit = &tree.first_child[fc as usize..(fc + UNIT) as usize];
        if unit.iter().any(|&g| g != NONE) {
            let reach = cap.unit_reach(&xs, h1);
            for k in 0..UNIT {
                if reach >> k & 1 == 1 {
                    stack.push((fc + k, tree.child_origin(o, d, k)));
                }
            }
            continue;
        }
        // The unit's slots, found with one page lookup.
        let slots = ctx.slot_of.unit(fc).copied().unwrap_or([NONE; LANES]);
        if let Some(u) = cap.unit_coverage(ctx.prim, ctx.hardness, &xs, h1) {
            for k in (0..LANES).rev() {
                if u.reach >> k & 1 == 1 {
                    leaf(ctx, &mut out, fc + k as u32, slots[k], d1, xs[k], u.r[k], h1, u.a[k]);
                }
            }
            continue;
        }
        let cps: [W::Point; LANES] = std::array::from_fn(|k| cap.project(xs[k]));
        for k in (0..LANES).rev() {
            if cap.within_reach(&cps[k], h1) {
                leaf(ctx, &mut out, fc + k as u32, slots[k], d1, xs[k], cap.radius(&cps[k], h1), h1, ctx.coverage(xs[k], &cps[k]));
            }
        }
    }
    out.stack = stack;
    out
}

/// A leaf within reach of the capsule, with its slot (NONE: untouched in
/// this stroke), coverage·flow `a` there (0 outside the primitive's box)
/// and the capsule's radius `r` at its projection: its write (in place
/// when its slot exists, else kept for the serial part) and whether it is
/// a candidate for refinement.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn leaf<W: Walk>(ctx: &RunContext<W>, out: &mut Run, c: u32, slot: u32, d: u32, x: DVec3, r: f64, h: f64, a: f64) {
    out.visited += 1;
    // SAFETY (every `Disjoint` access here): `c` is a live cell of this
    // run's subtrees, which no other run holds, and its slot is its own;
    // the vectors do not change length while the runs go on.
    // Its stored sigma, read where it is needed: a leaf that is neither
    // new to the stroke nor written leaves its pools unread.
    let sigma_now = || unsafe { *ctx.sigma.at(c as usize) };
    let needs = ctx.tree.lat.coarser_than_target(d, r) && !(ctx.sigma_gate && !(sigma_now() > 0.0));
    if a >= TINY {
        out.hit += 1;
        let colour = ctx.prim.colour;
        match slot {
            NONE => {
                let before_sigma = sigma_now();
                let before_rgb = unsafe { *ctx.rgb.at(c as usize) };
                let (rgb, sigma) = ctx.st.stored(before_rgb, before_sigma, colour, a);
                out.fresh.push(FirstWrite { c, before_rgb, before_sigma, a, rgb, sigma, next: false });
            }
            s => unsafe {
                // Touched before in this stroke, so written and journalled.
                debug_assert!(ctx.tree.journal.as_ref().is_none_or(|j| !j.needs_save(c)));
                let sa = &mut *ctx.slot_a.at(s as usize);
                if a > *sa {
                    *sa = a;
                    let slot = &*ctx.slots.at(s as usize);
                    let (rgb, sigma) = ctx.st.stored(slot.before_rgb, slot.before_sigma, colour, a);
                    *ctx.rgb.at(c as usize) = rgb;
                    *ctx.sigma.at(c as usize) = sigma;
                    out.written += 1;
                    let block = c / crate::dirty::BLOCK_CELLS;
                    if out.blocks.last() != Some(&block) {
                        out.blocks.push(block);
                    }
                }
            },
        }
    }
    if needs {
        out.needs.push((c, x, h));
    }
}

/// What the pass over a round's new children reads
/// ([`Painting::paint_new_cells`]).
struct NewCells<'a> {
    tree: &'a Tree,
    st: &'a StrokeState,
    /// The stroke's primitives whose boxes meet the new centres.
    near: &'a [Prim],
    /// The segment's primitives.
    seg: &'a [Prim],
    sigma_gate: bool,
}

impl NewCells<'_> {
    /// What new cell `c` (centre `x`, depth `d`) stores and whether the next
    /// round refines it, given its parent's before-value, its stroke maximum
    /// `a` (0 or at least TINY), the primitive `k` of `near` attaining it,
    /// and, for a segment of one capsule, whether the cell is within its
    /// reach and the capsule's radius at the cell's projection.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn decide(&self, c: u32, x: DVec3, d: u32, before: ([u8; 3], f32), a: f64, k: usize, seg_reach: Option<(bool, f64)>) -> FirstWrite {
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

/// A cell's first write in the stroke (a new child, or a leaf a paint-pass
/// run touched for the first time), decided before any is written: its
/// before-value, its stroke maximum, what it stores now, and (new children)
/// whether the next round refines it. 32 bytes: a round's new children
/// are decided into a list of these before any is written.
#[derive(Clone, Copy)]
struct FirstWrite {
    c: u32,
    before_rgb: [u8; 3],
    before_sigma: f32,
    a: f64,
    rgb: [u8; 3],
    sigma: f32,
    next: bool,
}

const _: () = assert!(std::mem::size_of::<FirstWrite>() == 32);

impl FirstWrite {
    /// A placeholder, overwritten before use.
    const NONE: FirstWrite = FirstWrite { c: NONE, before_rgb: [0; 3], before_sigma: 0.0, a: 0.0, rgb: [0; 3], sigma: 0.0, next: false };
}

/// The most items' room a split pass's run keeps in each list for the next
/// (room for a pass of about 100,000 leaves on 2 threads; a list that grew
/// larger is given back).
const SPARE_RUN_ITEMS: usize = 1 << 13;

/// What one run of the parallel paint pass leaves for the serial part.
#[derive(Clone, Default)]
struct Run {
    fresh: Vec<FirstWrite>,
    /// Leaves coarser than their target depth: (cell, centre, reach radius).
    needs: Vec<(u32, DVec3, f64)>,
    /// Dirty blocks of the cells written in place, consecutive repeats dropped.
    blocks: Vec<u32>,
    visited: u64,
    hit: u64,
    written: u64,
    /// The walk's stack, handed back for reuse.
    stack: Vec<(u32, [u32; 3])>,
}

/// The bounding box of some centres.
fn centre_bounds(xs: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    xs.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)))
}

/// The capsules among `prims` whose boxes meet the bounds of the balls
/// `(centre, radius)` (the only ones that cover any point of them), with
/// their indices in the stroke, ascending.
fn capsules_near(prims: &[Prim], balls: impl Iterator<Item = (DVec3, f64)>) -> Vec<(u32, Prim)> {
    let (lo, hi) = balls.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), (x, h)| (lo.min(x - h), hi.max(x + h)));
    prims
        .iter()
        .enumerate()
        .filter(|(_, p)| matches!(p.geo, Geometry::Capsule(_)) && p.overlaps(lo, hi))
        .map(|(i, p)| (i as u32, *p))
        .collect()
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

/// Within reach of some primitive of the segment, and (when `want_needs`)
/// whether some primitive within reach has a target depth below `d`
/// (spec 8.7).
#[inline]
fn segment_reach(tree: &Tree, st: &StrokeState, seg: &[Prim], x: DVec3, d: u32, h: f64, want_needs: bool) -> (bool, bool) {
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
fn stroke_maximum_with(st: &StrokeState, prims: &[Prim], x: DVec3, last: Option<&CapsulePoint>) -> (f64, usize) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::hash32;

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

    /// The blends of `StrokeState::stored`, computed channel by channel,
    /// store the same bytes and f32 as the general form through
    /// `brush::blend` in every mode for every kind of input: empty and
    /// filled cells (a NaN and an infinite density too), any stored colour,
    /// mix ratios from 0 to 1, maxima from 0 and tiny to 1, and the edges.
    #[test]
    fn the_paint_blend_stores_what_the_general_blend_stores() {
        let unit = |i: u32| f64::from(hash32(i)) / 4294967296.0;
        for mode in [Mode::Paint, Mode::Pickup, Mode::Erase, Mode::Recolor, Mode::Mix] {
            for i in 0..2000u32 {
                let colour = [unit(7 * i), unit(7 * i + 1), unit(7 * i + 2)];
                let opacity = [1.0, 0.5, unit(7 * i + 3)][i as usize % 3];
                let mut brush = Brush::new(Shape::Sphere, mode, 0.01 + unit(7 * i + 4), colour, opacity, 0.5);
                brush.mix_ratio = [1.0, 0.0, unit(7 * i + 5)][i as usize % 3];
                let mut painting = Painting::new(&Canvas { roots: [1, 1, 1], max_depth: 4, root_size: 1.0, capacity: 64 });
                painting.begin_stroke(&brush);
                let st = painting.stroke.as_ref().expect("stroke");
                let before_rgb = [hash32(i) as u8, (hash32(i) >> 8) as u8, (hash32(i) >> 16) as u8];
                let sigmas = [0.0f32, 1e-30, 0.25, 3.0e5, f32::MAX, unit(i + 11) as f32 * 100.0, f32::NAN, f32::INFINITY];
                let maxima = [0.0, TINY, 1e-6, 0.5, 1.0, unit(i + 13), unit(i + 17) * 1e-3];
                for &before_sigma in &sigmas {
                    for &a in &maxima {
                        if a != 0.0 {
                            // Unrounded, bit for bit: a change of one ulp
                            // rarely moves a stored byte.
                            let before = before_rgb.map(|v| f64::from(v) / 255.0);
                            let bs = f64::from(before_sigma);
                            let (rgb, sigma) = st.blended(before_rgb, bs, colour, a);
                            let (g_rgb, g_sigma) = blend(mode, before, bs, colour, st.sigma_b, st.alpha, a, brush.mix_ratio);
                            assert_eq!((rgb.map(f64::to_bits), sigma.to_bits()), (g_rgb.map(f64::to_bits), g_sigma.to_bits()), "{mode:?} {before_rgb:?} {before_sigma} {a}");
                        }
                        let (fast, general) = (st.stored(before_rgb, before_sigma, colour, a), st.stored_general(before_rgb, before_sigma, colour, a));
                        assert_eq!(
                            (fast.0, fast.1.to_bits()),
                            (general.0, general.1.to_bits()),
                            "{mode:?} {before_rgb:?} {before_sigma} {colour:?} {a}"
                        );
                    }
                }
            }
        }
    }
}

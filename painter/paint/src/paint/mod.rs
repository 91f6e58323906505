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
//!
//! | file | what it holds | in paint.py |
//! | --- | --- | --- |
//! | mod.rs | a stroke's state and slots, the levels of a sample, stroke end, undo | `Stroke`, `begin_stroke` .. `redo` |
//! | blend.rs | what a cell stores at a stroke maximum (spec 8.5, rounded by spec 5) | `_apply` |
//! | pass.rs | level 0: the paint pass, serial or split across threads | `_process_segment`, `_evaluate` |
//! | runs.rs | one run of the paint pass, its only unsafe code (in-place writes) | `_evaluate` |
//! | walks.rs | what a pass walks with (a capsule, a stamp, a segment), reach and stroke maxima | `_reach`, `_reach_stamps`, `_reach_one_capsule` |
//! | refine.rs | refinement rounds and a round's new children | `_round`, `_paint_new_cells` |
//! | settle.rs | the settled-leaf test (spec 8.7) | `_settled` |

mod blend;
mod pass;
mod refine;
mod runs;
mod settle;
mod walks;

#[cfg(test)]
pub(crate) use settle::settle_bounds;

use crate::brush::{self, StampReach};
use crate::noise::permutation;
use crate::slots::SlotMap;
use crate::stroke::{Prim, StrokePath};
use octopaint_model::{Brush, Canvas, Mode, Sample, Shape};
use octopaint_octree::clean::clean;
use octopaint_octree::history::History;
use octopaint_octree::par;
use octopaint_octree::pool::{NONE, Tree};

use pass::SplitChoice;
use runs::Run;

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

/// The deferred marks of a stroke's slots (spec 8.7), one bit a slot: a
/// slot is deferred when its cell was settled at a decision of this stroke
/// or is a new child of a deferred cell, so that whether it needs
/// refinement is tested against every primitive of the stroke so far. A
/// mark is cleared when that test finds no primitive wanting the cell
/// finer (a later segment's own test misses nothing then). Apart from the
/// slots so that the paint pass reads a bit, not a slot, per leaf.
#[derive(Clone, Default)]
struct Marks {
    bits: Vec<u64>,
    /// Some slot was ever marked in this stroke (the pass reads no bits
    /// until then).
    any: bool,
}

impl Marks {
    #[inline]
    fn get(&self, slot: u32) -> bool {
        self.bits.get(slot as usize / 64).is_some_and(|w| w >> (slot % 64) & 1 == 1)
    }

    fn set(&mut self, slot: u32, on: bool) {
        let (i, bit) = (slot as usize / 64, 1u64 << (slot % 64));
        if i >= self.bits.len() {
            if !on {
                return;
            }
            self.bits.resize(i + 1, 0);
        }
        if on {
            self.bits[i] |= bit;
            self.any = true;
        } else {
            self.bits[i] &= !bit;
        }
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
    deferred: Marks,
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
    /// Interior cells rewritten by the prefilter (spec 4.4) at stroke and
    /// import ends and snapshots, and the time that took (also counted in
    /// `stroke_end_ns` at a stroke's end; publications' updates are not
    /// counted).
    pub prefilter_cells: u64,
    pub prefilter_ns: u64,
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
            deferred: Marks::default(),
            refusal_warned: false,
            slots: std::mem::take(&mut self.spare_slots),
            slot_a: std::mem::take(&mut self.spare_slot_a),
        });
    }

    /// Process one sample completely (all levels).
    pub fn add_sample(&mut self, sample: &Sample, line: usize) {
        self.begin_sample(sample, line);
        while !self.advance_level() {}
    }

    /// Start a sample: pickup, then the segment's primitives (spec 8.10
    /// steps 1-2). The levels follow with [`Painting::advance_level`].
    pub fn begin_sample(&mut self, sample: &Sample, line: usize) {
        assert!(self.work.is_none(), "the previous sample is not finished");
        let tree = &self.tree;
        let st = self.stroke.as_mut().expect("sample outside a stroke");
        if st.brush.mode == Mode::Pickup
            && let Some(c) = tree.leaf_at(sample.p)
            && tree.sigma()[c as usize] > 0.0
        {
            let canvas = tree.rgb()[c as usize].map(|v| f64::from(v) / 255.0);
            let rate = st.brush.pickup_rate;
            st.colour = [0, 1, 2].map(|i| st.colour[i] + (canvas[i] - st.colour[i]) * rate);
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
    pub fn advance_level(&mut self) -> bool {
        self.advance(None)
    }

    /// One step of the current sample: the paint pass, or a round of
    /// refinement, or with `max_units` only the part of a round that
    /// allocates about that many units (and paints their children). Smaller
    /// steps publish sooner (the real-time pipeline's aggressive staging);
    /// the tree is 2:1 balanced after every step, and the final tree is the
    /// same for any step size. Returns true when the sample is finished.
    pub fn advance(&mut self, max_units: Option<usize>) -> bool {
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
        self.update_prefilter();
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

    /// Bring the interior values up to date (spec 4.4): the ancestors of
    /// every cell written since the last update, each once. A stroke's
    /// writes reach them at its end (and at every publication on the way,
    /// [`Tree::take_publication`]); a reader of the tree inside a stroke
    /// (a snapshot) calls this first. Counted in the paint counters.
    pub fn update_prefilter(&mut self) {
        let t0 = std::time::Instant::now();
        self.counters.prefilter_cells += self.tree.update_prefilter() as u64;
        self.counters.prefilter_ns += t0.elapsed().as_nanos() as u64;
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

    /// `c`'s before-value (spec 8.8): the one its slot recorded when the
    /// stroke touched it, else its stored value.
    fn before_value(&self, c: u32) -> ([u8; 3], f32) {
        match self.slot_of.get(c) {
            NONE => (self.tree.rgb()[c as usize], self.tree.sigma()[c as usize]),
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

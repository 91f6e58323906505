//! Undo and redo of whole strokes (spec 10). Reference twin:
//! reference/octopaint_ref/history.py.
//!
//! While a stroke runs, a journal (pool/journal.rs) saves each cell's record
//! before its first write (the pools' writes call it). At commit, the saved cells whose
//! record really changed become an undo step with their records before and
//! after the stroke, plus the used length before and after. Undo writes the
//! before-records back and restores the used length, so the pools are byte
//! for byte what they were, indices and free units included; redo writes
//! the after-records.
//!
//! A done step keeps no after-records: they are redundant. Every change of
//! the pools goes through an undo step, and undo takes back the newest done
//! step first, so while a step is the newest done one the pools hold its
//! after-records; an older step's are what the steps above it hold as
//! before-records, or the pools where none of them changed the cell. So a
//! done step keeps its changed cells and their before-records, and of its
//! *tail* (the cells past the used length at the stroke's start, which
//! were free before: most of a stroke's new cells) only how many are live.
//! Undo copies the after-records out of the pools before it writes the
//! before-records back (an undone step keeps every record, for redo), and
//! [`History::full_steps`] rebuilds every step's records for a document or
//! a comparison.

mod packed;

use packed::{CellRun, Packed};

use crate::par;
use crate::pool::{CellRecord, FREE, NONE, Tree, UNIT};

/// One stroke's effect on the pools: for each changed cell its record
/// before and after the stroke, kept by what changed so that most cells
/// cost far less than their two 16-byte records:
/// - *values*: a leaf before and after whose only change is rgb and sigma
///   (a painted leaf): the cell, its parent and depth, both values, 23
///   bytes;
/// - *born*: free before (a new cell), only the after-record, 20 bytes;
///   the cells past the used length at the stroke's start (its *tail*,
///   where most new cells are) keep their after-records in runs of
///   consecutive cells, freed ones included, packed: 7 bytes a cell, 9 a
///   span of cells with one parent and depth (a unit), 8 a cell with
///   children, about 9 bytes a cell in all;
/// - *freed*: free after (a collapse), only the before-record, 20 bytes;
/// - *other*: both records (a refined leaf, a parent), 36 bytes.
///
/// A done step of a painting leaves its after-records in the pools (see the
/// module's notes): a value cell then takes 11 bytes, a born cell of the
/// list 4, a tail cell nothing, a freed or other cell 20.
#[derive(Clone, Debug, Default)]
pub struct UndoStep {
    pub n_before: u32,
    pub n_after: u32,
    value_cells: Vec<u32>,
    value_parent: Vec<u32>,
    value_depth: Vec<u8>,
    value_rgb: Vec<[[u8; 3]; 2]>,
    value_sigma: Vec<[f32; 2]>,
    born_cells: Vec<u32>,
    born: Vec<CellRecord>,
    /// The tail: runs of consecutive cells from `n_before` on, ascending,
    /// their records packed (at commit one run, packed from the pools). A
    /// cell whose record is `CellRecord::FREE` here is no entry.
    tail: Vec<CellRun>,
    /// How many tail records are not free (entries).
    tail_born: usize,
    /// The after-records are left in the pools (see the module's notes):
    /// `tail` is empty, and the tail is the cells from `n_before` to
    /// `n_after`, `tail_born` of them not free; the born cells of the list
    /// have no records in `born`, and the value and other cells keep their
    /// before-records in `before_*` (their `value_*` and `other` vectors
    /// are empty).
    after_in_pools: bool,
    freed_cells: Vec<u32>,
    freed: Vec<CellRecord>,
    other_cells: Vec<u32>,
    other: Vec<[CellRecord; 2]>,
    /// With the after-records in the pools: the value cells' rgb and
    /// sigma before, and the other cells' records before.
    before_rgb: Vec<[u8; 3]>,
    before_sigma: Vec<f32>,
    before_other: Vec<CellRecord>,
}

/// How an undo step keeps a changed cell (see [`UndoStep`]).
enum Kind {
    /// Free before.
    Born,
    /// Free after.
    Freed,
    /// A leaf before and after whose only change is rgb and sigma.
    Value,
    Other,
}

impl Kind {
    fn of(before: &CellRecord, after: &CellRecord) -> Kind {
        if before.same_bits(&CellRecord::FREE) {
            Kind::Born
        } else if after.same_bits(&CellRecord::FREE) {
            Kind::Freed
        } else if before.first_child == NONE && (before.parent, before.first_child, before.depth) == (after.parent, after.first_child, after.depth) {
            Kind::Value
        } else {
            Kind::Other
        }
    }
}

/// How many free records a born cell may add to a step's tail to reach
/// its place (a step read from a document, whose born cells come one by
/// one): a unit's worth, so a document cannot make a step much bigger
/// than itself. Cells further on go to the list of born cells.
const TAIL_GAP: usize = UNIT as usize;

impl UndoStep {
    pub fn new(n_before: u32, n_after: u32) -> Self {
        UndoStep { n_before, n_after, ..UndoStep::default() }
    }

    /// Add a cell that changed from `before` to `after` (each cell once).
    pub fn push(&mut self, c: u32, before: CellRecord, after: CellRecord) {
        match Kind::of(&before, &after) {
            Kind::Born => self.push_born(c, after),
            Kind::Freed => {
                self.freed_cells.push(c);
                self.freed.push(before);
            }
            Kind::Value => {
                self.value_cells.push(c);
                self.value_parent.push(before.parent);
                self.value_depth.push(before.depth);
                self.value_rgb.push([before.rgb, after.rgb]);
                self.value_sigma.push([before.sigma, after.sigma]);
            }
            Kind::Other => {
                self.other_cells.push(c);
                self.other.push([before, after]);
            }
        }
    }

    /// [`UndoStep::push`] for a step whose after-records stay in the pools
    /// (a commit; the step is then marked so): only the before-records are
    /// kept. `after` (not free when `before` is) sorts the cell.
    fn push_before(&mut self, c: u32, before: CellRecord, after: &CellRecord) {
        match Kind::of(&before, after) {
            Kind::Born => {
                debug_assert!(!after.same_bits(&CellRecord::FREE));
                self.born_cells.push(c);
            }
            Kind::Freed => {
                self.freed_cells.push(c);
                self.freed.push(before);
            }
            Kind::Value => {
                self.value_cells.push(c);
                self.before_rgb.push(before.rgb);
                self.before_sigma.push(before.sigma);
            }
            Kind::Other => {
                self.other_cells.push(c);
                self.before_other.push(before);
            }
        }
    }

    /// Add a cell that was free before the stroke and is `after` now (what
    /// `push` does with a free `before`).
    #[inline]
    pub fn push_born(&mut self, c: u32, after: CellRecord) {
        // In the tail when its place is at or past the last run's end (a unit on
        // at most, else a new run); a free after-record goes to the list,
        // where it stays an entry, and so does a cell whose place lies
        // inside a run (the packed runs only grow at their end). A step
        // read back may count fewer free records in `bytes` than the step
        // that was saved (its runs skip gaps of more than a unit).
        if c >= self.n_before && c < self.n_after && !after.same_bits(&CellRecord::FREE) {
            // A new run only while runs hold 8 entries each on average:
            // a crafted document's scattered cells go to the list.
            let new_run = self.tail.len() <= self.tail_born / UNIT as usize;
            match self.tail.last_mut() {
                Some(run) if c < run.end() => {} // inside a run or before it
                Some(run) if (c - run.end()) as usize <= TAIL_GAP => {
                    while run.end() < c {
                        run.cols.push(CellRecord::FREE);
                    }
                    run.cols.push(after);
                    self.tail_born += 1;
                    return;
                }
                _ if new_run => {
                    let mut cols = Packed::default();
                    cols.push(after);
                    self.tail.push(CellRun { first: c, cols });
                    self.tail_born += 1;
                    return;
                }
                _ => {} // too scattered
            }
        }
        self.born_cells.push(c);
        self.born.push(after);
    }

    /// The tail of a step that has none yet: the pools' records of the
    /// cells from `n_before` to `n_after` (the pools hold the step's
    /// after-records), as one run.
    fn take_tail(&mut self, tree: &Tree) {
        debug_assert!(self.tail.is_empty());
        // None when the pools ended shorter than they began.
        let (from, to) = (self.n_before as usize, self.n_after as usize);
        if from >= to {
            return;
        }
        let t = Packed::from_pools(tree, from..to);
        self.tail_born = t.len() - t.free_records();
        self.tail = vec![CellRun { first: self.n_before, cols: t }];
    }

    /// A step just committed (its cells pushed by `push_before`) leaves its
    /// after-records in the pools: of its tail only how many records are
    /// not free is counted (a collapse frees whole units; a free record's
    /// depth is FREE, and a live cell's is not).
    fn leave_after_in_pools(&mut self, tree: &Tree) {
        debug_assert!(self.tail.is_empty() && self.n_after == tree.n_used());
        let (from, to) = (self.n_before as usize, self.n_after as usize);
        self.tail_born = if from < to { tree.depth[from..to].iter().filter(|&&d| d != FREE).count() } else { 0 };
        debug_assert_eq!(self.tail_born, (from..to).filter(|&c| !tree.record(c as u32).same_bits(&CellRecord::FREE)).count());
        self.after_in_pools = true;
    }

    /// Whether the after-records are left in the pools, which must then
    /// hold them when they are read: the step is the newest done one.
    pub fn after_in_pools(&self) -> bool {
        self.after_in_pools
    }

    /// Copy after-records left in the pools out of `tree`, which holds
    /// them (this is the newest done step there): the step then holds
    /// every record.
    pub fn take_after_from_pools(&mut self, tree: &Tree) {
        if !self.after_in_pools {
            return;
        }
        self.after_in_pools = false;
        let born = self.tail_born;
        self.take_tail(tree);
        debug_assert_eq!(self.tail_born, born, "the pools do not hold the step's after-records");
        for run in &mut self.tail {
            run.cols.shrink();
        }
        self.born = self.born_cells.iter().map(|&c| tree.record(c)).collect();
        let n = self.value_cells.len();
        (self.value_parent, self.value_depth, self.value_rgb, self.value_sigma) =
            (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
        for (i, &c) in self.value_cells.iter().enumerate() {
            // A value cell's parent and depth did not change; its values did.
            let c = c as usize;
            self.value_parent.push(tree.parent[c]);
            self.value_depth.push(tree.depth[c]);
            self.value_rgb.push([self.before_rgb[i], tree.rgb[c]]);
            self.value_sigma.push([self.before_sigma[i], tree.sigma[c]]);
        }
        self.other = self.other_cells.iter().zip(&self.before_other).map(|(&c, &b)| [b, tree.record(c)]).collect();
        self.before_rgb = Vec::new();
        self.before_sigma = Vec::new();
        self.before_other = Vec::new();
    }

    /// Steps built in parts, one after another, as one step (the parts'
    /// entries in order, with no spare capacity).
    fn joined(parts: Vec<UndoStep>) -> UndoStep {
        if parts.len() == 1 {
            let mut step = parts.into_iter().next().expect("one part");
            step.shrink();
            return step;
        }
        fn join<T: Copy>(parts: &[UndoStep], field: impl Fn(&UndoStep) -> &Vec<T>) -> Vec<T> {
            let mut out = Vec::with_capacity(parts.iter().map(|p| field(p).len()).sum());
            for p in parts {
                out.extend_from_slice(field(p));
            }
            out
        }
        UndoStep {
            n_before: 0,
            n_after: 0,
            value_cells: join(&parts, |p| &p.value_cells),
            value_parent: join(&parts, |p| &p.value_parent),
            value_depth: join(&parts, |p| &p.value_depth),
            value_rgb: join(&parts, |p| &p.value_rgb),
            value_sigma: join(&parts, |p| &p.value_sigma),
            born_cells: join(&parts, |p| &p.born_cells),
            born: join(&parts, |p| &p.born),
            tail: Vec::new(),
            tail_born: 0,
            after_in_pools: false,
            freed_cells: join(&parts, |p| &p.freed_cells),
            freed: join(&parts, |p| &p.freed),
            other_cells: join(&parts, |p| &p.other_cells),
            other: join(&parts, |p| &p.other),
            before_rgb: join(&parts, |p| &p.before_rgb),
            before_sigma: join(&parts, |p| &p.before_sigma),
            before_other: join(&parts, |p| &p.before_other),
        }
    }

    /// Give back what the vectors hold beyond their contents (a finished
    /// step no longer grows), so that [`UndoStep::bytes`] is what it takes.
    pub fn shrink(&mut self) {
        self.value_cells.shrink_to_fit();
        self.value_parent.shrink_to_fit();
        self.value_depth.shrink_to_fit();
        self.value_rgb.shrink_to_fit();
        self.value_sigma.shrink_to_fit();
        self.born_cells.shrink_to_fit();
        self.born.shrink_to_fit();
        for run in &mut self.tail {
            run.cols.shrink();
        }
        self.tail.shrink_to_fit();
        self.freed_cells.shrink_to_fit();
        self.freed.shrink_to_fit();
        self.other_cells.shrink_to_fit();
        self.other.shrink_to_fit();
        self.before_rgb.shrink_to_fit();
        self.before_sigma.shrink_to_fit();
        self.before_other.shrink_to_fit();
    }

    /// How many cells the stroke changed.
    pub fn len(&self) -> usize {
        self.value_cells.len() + self.born_cells.len() + self.tail_born + self.freed_cells.len() + self.other_cells.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every changed cell with its records before and after the stroke
    /// (values first, then born (the list, then the tail in index order),
    /// freed and other cells). Not for a step whose after-records are left
    /// in the pools (a done step of a painting: [`History::full_steps`]).
    pub fn entries(&self) -> impl Iterator<Item = (u32, CellRecord, CellRecord)> + '_ {
        assert!(!self.after_in_pools, "the step's after-records are in the pools: History::full_steps gives them");
        let values = (0..self.value_cells.len()).map(|i| (self.value_cells[i], self.value_record(i, 0), self.value_record(i, 1)));
        let born = self.born_cells.iter().zip(&self.born).map(|(&c, r)| (c, CellRecord::FREE, *r));
        let tail = self.tail.iter().flat_map(|run| {
            run.cols.records().enumerate().filter(|(_, r)| !r.same_bits(&CellRecord::FREE)).map(move |(i, r)| (run.first + i as u32, CellRecord::FREE, r))
        });
        let freed = self.freed_cells.iter().zip(&self.freed).map(|(&c, r)| (c, *r, CellRecord::FREE));
        let other = self.other_cells.iter().zip(&self.other).map(|(&c, r)| (c, r[0], r[1]));
        values.chain(born).chain(tail).chain(freed).chain(other)
    }

    /// Value cell `i`'s record before (`k` = 0) or after (1) the stroke.
    fn value_record(&self, i: usize, k: usize) -> CellRecord {
        CellRecord { parent: self.value_parent[i], first_child: NONE, depth: self.value_depth[i], rgb: self.value_rgb[i][k], sigma: self.value_sigma[i][k] }
    }

    /// What the step holds, in bytes (after-records left in the pools take
    /// none).
    pub fn bytes(&self) -> usize {
        if self.after_in_pools {
            return self.value_cells.len() * (4 + 3 + 4)
                + self.born_cells.len() * 4
                + self.freed_cells.len() * (4 + std::mem::size_of::<CellRecord>())
                + self.other_cells.len() * (4 + std::mem::size_of::<CellRecord>());
        }
        self.value_cells.len() * (4 + 4 + 1 + 2 * 3 + 2 * 4)
            + (self.born_cells.len() + self.freed_cells.len()) * (4 + std::mem::size_of::<CellRecord>())
            + self.tail.iter().map(|run| run.cols.bytes()).sum::<usize>()
            + self.other_cells.len() * (4 + 2 * std::mem::size_of::<CellRecord>())
    }
}

/// Done and undone strokes.
#[derive(Clone, Default)]
pub struct History {
    pub done: Vec<UndoStep>,
    pub undone: Vec<UndoStep>,
}

impl History {
    pub fn bytes(&self) -> usize {
        self.done.iter().chain(self.undone.iter()).map(UndoStep::bytes).sum()
    }

    /// Changed cells over all steps (a cell changed by two strokes counts
    /// twice).
    pub fn changed_cells(&self) -> usize {
        self.done.iter().chain(self.undone.iter()).map(UndoStep::len).sum()
    }

    /// Forget the oldest done strokes until the history takes at most
    /// `max_bytes` (the newest stroke is always kept, and redo steps are
    /// never dropped: they are the newest). Returns how many were dropped.
    pub fn trim_to(&mut self, max_bytes: usize) -> usize {
        let mut total = self.bytes();
        let mut drop = 0;
        while total > max_bytes && drop + 1 < self.done.len() {
            total -= self.done[drop].bytes();
            drop += 1;
        }
        self.done.drain(..drop);
        drop
    }

    /// Every step, the done ones and then the undone ones, with all its
    /// records, for `tree`, which holds the newest done step's
    /// after-records (between strokes). A done step whose after-records
    /// are left in the pools gets a copy with them: the newest from `tree`,
    /// an older one from a copy of the records that the steps above it
    /// have been undone on (so it holds that step's after-records).
    pub fn full_steps<'a>(&'a self, tree: &Tree) -> Vec<std::borrow::Cow<'a, UndoStep>> {
        use std::borrow::Cow;
        let mut out: Vec<Cow<'a, UndoStep>> = self.done.iter().chain(&self.undone).map(Cow::Borrowed).collect();
        let Some(lowest) = self.done.iter().position(UndoStep::after_in_pools) else { return out };
        let top = self.done.len() - 1;
        let mut copy: Option<Tree> = None;
        for k in (lowest..=top).rev() {
            let at = copy.as_ref().unwrap_or(tree);
            if self.done[k].after_in_pools {
                let mut full = self.done[k].clone();
                full.take_after_from_pools(at);
                out[k] = Cow::Owned(full);
            }
            if k > lowest {
                copy.get_or_insert_with(|| tree.records_copy()).undo_records(&out[k]);
            }
        }
        out
    }
}

impl Tree {
    /// Start saving records for an undo step.
    pub fn begin_journal(&mut self) {
        // The last stroke's vectors, emptied: a stroke saves about as many
        // cells as the one before, and fresh vectors cost page faults and
        // copies as they grow.
        let mut j = std::mem::take(&mut self.spare_journal);
        j.n_before = self.n_used();
        self.journal = Some(j);
    }

    /// Stop saving and return the stroke's undo step: the cells whose
    /// record changed (each once, so the order of writing them back does
    /// not matter): the saved cells, then the cells past the old used
    /// length, which were free.
    pub fn commit_journal(&mut self) -> UndoStep {
        let j = self.journal.take().expect("commit without begin");
        let n_used = self.n_used();
        let tree = &*self;
        let saved = |part: &mut UndoStep, at: usize, cells: &[u32]| {
            for (&c, before) in cells.iter().zip(&j.before[at..]) {
                let now = tree.record(c);
                if !now.same_bits(before) {
                    part.push_before(c, *before, &now);
                }
            }
        };
        let mut step = if par::worth(j.cells.len()) {
            // Built in parallel chunks, joined in order: the same step as
            // one pass over the saved cells.
            let parts = par::chunks(&j.cells, |at, cells| {
                let mut part = UndoStep::default();
                saved(&mut part, at, cells);
                part
            });
            UndoStep::joined(parts)
        } else {
            let mut step = UndoStep::default();
            saved(&mut step, 0, &j.cells);
            step.shrink();
            step
        };
        (step.n_before, step.n_after) = (j.n_before, n_used);
        // The after-records stay in the pools, until undo copies them out;
        // of the cells past the old used length, all free before, the live
        // ones are entries (the ones cleaning freed again are not).
        step.leave_after_in_pools(tree);
        self.spare_journal = j.emptied();
        step
    }

    /// The records and used length of `apply_step(step, false)`, written
    /// straight into the columns of a [`Tree::records_copy`].
    fn undo_records(&mut self, step: &UndoStep) {
        assert!(!step.after_in_pools);
        self.set_used_length(step.n_before.max(step.n_after).max(self.n_used()));
        let mut put = |c: u32, r: &CellRecord| self.put_record(c, r);
        // The entries' before-records, category by category; the tail's
        // cells lie past `n_before`, where the used length ends.
        for (i, &c) in step.value_cells.iter().enumerate() {
            put(c, &step.value_record(i, 0));
        }
        for &c in &step.born_cells {
            put(c, &CellRecord::FREE);
        }
        for (&c, r) in step.freed_cells.iter().zip(&step.freed) {
            put(c, r);
        }
        for (&c, r) in step.other_cells.iter().zip(&step.other) {
            put(c, &r[0]);
        }
        self.set_used_length(step.n_before);
    }

    /// Write one side of an undo step: the records and the used length.
    /// Marks the rewritten cells dirty, and the cells that gained or lost
    /// children as topology changes (spec 10, 3.4).
    pub fn apply_step(&mut self, step: &UndoStep, forward: bool) {
        assert!(!step.after_in_pools, "apply_step of a step whose after-records are in the pools");
        let n = if forward { step.n_after } else { step.n_before };
        self.set_used_length(step.n_before.max(step.n_after));
        for (c, before, after) in step.entries() {
            let (r, o) = if forward { (after, before) } else { (before, after) };
            self.write_record(c, r);
            self.list_written(c);
            self.changes.direct(c);
            if r.first_child != o.first_child {
                let unit = if r.first_child != NONE { r.first_child } else { o.first_child };
                self.changes.topology(c, unit);
            }
        }
        self.set_used_length(n);
        self.rebuild_free_units();
        // The restored side kept spec 4.4 when it was recorded; the
        // ancestors of its cells are recomputed all the same, so that a
        // step recorded before the rule (a document from then) comes back
        // to a tree that keeps it. On a step recorded since, nothing
        // changes.
        self.update_prefilter();
    }
}

#[cfg(test)]
mod tests;

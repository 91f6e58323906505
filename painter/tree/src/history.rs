//! Undo and redo of whole strokes (spec 10). Reference twin:
//! reference/octopaint_ref/history.py.
//!
//! While a stroke runs, a journal saves each cell's record before its first
//! write (pool.rs calls it on every write). At commit, the saved cells whose
//! record really changed become an undo step with their records before and
//! after the stroke, plus the used length before and after. Undo writes the
//! before-records back and restores the used length, so the pools are byte
//! for byte what they were, indices and free units included; redo writes
//! the after-records.

use crate::par;
use crate::pool::{CellRecord, NONE, Tree};

#[derive(Clone, Default)]
pub(crate) struct Journal {
    n_before: u32,
    saved: Vec<u64>,
    cells: Vec<u32>,
    before: Vec<CellRecord>,
}

impl Journal {
    /// Whether `c`'s record must be saved before its first write. Cells at
    /// or past the used length of the stroke's start were free then: their
    /// before-record is known and commit adds them without a save.
    #[inline]
    pub fn needs_save(&self, c: u32) -> bool {
        if c >= self.n_before {
            return false;
        }
        let w = (c / 64) as usize;
        w >= self.saved.len() || self.saved[w] >> (c % 64) & 1 == 0
    }

    /// Every cell of the unit at `unit` was free when the stroke began
    /// (past its used length): none needs a save.
    #[inline]
    pub fn unit_is_new(&self, unit: u32) -> bool {
        unit >= self.n_before
    }

    /// The journal with nothing saved, its vectors kept: the saved bits are
    /// cleared word by word from the saved cells, not the whole bitset.
    fn emptied(mut self) -> Journal {
        for &c in &self.cells {
            self.saved[(c / 64) as usize] = 0;
        }
        self.cells.clear();
        self.before.clear();
        self
    }

    pub fn save(&mut self, c: u32, rec: CellRecord) {
        let w = (c / 64) as usize;
        if w >= self.saved.len() {
            self.saved.resize((w + 1).next_power_of_two(), 0);
        }
        self.saved[w] |= 1 << (c % 64);
        self.cells.push(c);
        self.before.push(rec);
    }
}

/// One stroke's effect on the pools: for each changed cell its record
/// before and after the stroke, kept by what changed so that most cells
/// cost far less than their two 16-byte records:
/// - *values*: a leaf before and after whose only change is rgb and sigma
///   (a painted leaf): the cell, its parent and depth, both values, 23
///   bytes;
/// - *born*: free before (a new cell), only the after-record, 20 bytes;
/// - *freed*: free after (a collapse), only the before-record, 20 bytes;
/// - *other*: both records (a refined leaf, a parent), 36 bytes.
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
    freed_cells: Vec<u32>,
    freed: Vec<CellRecord>,
    other_cells: Vec<u32>,
    other: Vec<[CellRecord; 2]>,
}

impl UndoStep {
    pub fn new(n_before: u32, n_after: u32) -> Self {
        UndoStep { n_before, n_after, ..UndoStep::default() }
    }

    /// Add a cell that changed from `before` to `after` (each cell once).
    pub fn push(&mut self, c: u32, before: CellRecord, after: CellRecord) {
        if before.same_bits(&CellRecord::FREE) {
            self.push_born(c, after);
        } else if after.same_bits(&CellRecord::FREE) {
            self.freed_cells.push(c);
            self.freed.push(before);
        } else if before.first_child == NONE && (before.parent, before.first_child, before.depth) == (after.parent, after.first_child, after.depth) {
            self.value_cells.push(c);
            self.value_parent.push(before.parent);
            self.value_depth.push(before.depth);
            self.value_rgb.push([before.rgb, after.rgb]);
            self.value_sigma.push([before.sigma, after.sigma]);
        } else {
            self.other_cells.push(c);
            self.other.push([before, after]);
        }
    }

    /// Add a cell that was free before the stroke and is `after` now (what
    /// `push` does with a free `before`).
    #[inline]
    pub fn push_born(&mut self, c: u32, after: CellRecord) {
        self.born_cells.push(c);
        self.born.push(after);
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
            freed_cells: join(&parts, |p| &p.freed_cells),
            freed: join(&parts, |p| &p.freed),
            other_cells: join(&parts, |p| &p.other_cells),
            other: join(&parts, |p| &p.other),
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
        self.freed_cells.shrink_to_fit();
        self.freed.shrink_to_fit();
        self.other_cells.shrink_to_fit();
        self.other.shrink_to_fit();
    }

    /// How many cells the stroke changed.
    pub fn len(&self) -> usize {
        self.value_cells.len() + self.born_cells.len() + self.freed_cells.len() + self.other_cells.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every changed cell with its records before and after the stroke
    /// (values first, then born, freed and other cells).
    pub fn entries(&self) -> impl Iterator<Item = (u32, CellRecord, CellRecord)> + '_ {
        let values = (0..self.value_cells.len()).map(|i| {
            let (parent, depth) = (self.value_parent[i], self.value_depth[i]);
            let rec = |k: usize| CellRecord { parent, first_child: NONE, depth, rgb: self.value_rgb[i][k], sigma: self.value_sigma[i][k] };
            (self.value_cells[i], rec(0), rec(1))
        });
        let born = self.born_cells.iter().zip(&self.born).map(|(&c, r)| (c, CellRecord::FREE, *r));
        let freed = self.freed_cells.iter().zip(&self.freed).map(|(&c, r)| (c, *r, CellRecord::FREE));
        let other = self.other_cells.iter().zip(&self.other).map(|(&c, r)| (c, r[0], r[1]));
        values.chain(born).chain(freed).chain(other)
    }

    pub fn bytes(&self) -> usize {
        self.value_cells.len() * (4 + 4 + 1 + 2 * 3 + 2 * 4)
            + (self.born_cells.len() + self.freed_cells.len()) * (4 + std::mem::size_of::<CellRecord>())
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
}

impl Tree {
    /// Start saving records for an undo step.
    pub(crate) fn begin_journal(&mut self) {
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
    pub(crate) fn commit_journal(&mut self) -> UndoStep {
        let j = self.journal.take().expect("commit without begin");
        let n_used = self.n_used();
        let tree = &*self;
        let saved = |part: &mut UndoStep, at: usize, cells: &[u32]| {
            for (&c, before) in cells.iter().zip(&j.before[at..]) {
                let now = tree.record(c);
                if !now.same_bits(before) {
                    part.push(c, *before, now);
                }
            }
        };
        let born = |part: &mut UndoStep, cells: std::ops::Range<u32>| {
            for c in cells {
                let now = tree.record(c);
                if !now.same_bits(&CellRecord::FREE) {
                    part.push_born(c, now);
                }
            }
        };
        let mut step = if par::worth(j.cells.len() + n_used.saturating_sub(j.n_before) as usize) {
            // Built in parallel chunks, joined in order: the same step as
            // one pass over the saved cells and then the new ones.
            let mut parts = par::chunks(&j.cells, |at, cells| {
                let mut part = UndoStep::default();
                saved(&mut part, at, cells);
                part
            });
            parts.extend(par::ranges(j.n_before, n_used, |cells| {
                let mut part = UndoStep::default();
                born(&mut part, cells);
                part
            }));
            UndoStep::joined(parts)
        } else {
            let mut step = UndoStep::default();
            saved(&mut step, 0, &j.cells);
            born(&mut step, j.n_before..n_used.max(j.n_before));
            step.shrink();
            step
        };
        (step.n_before, step.n_after) = (j.n_before, n_used);
        self.spare_journal = j.emptied();
        step
    }

    /// Write one side of an undo step: the records and the used length.
    /// Marks the rewritten cells dirty, and the cells that gained or lost
    /// children as topology changes (spec 10, 3.4).
    pub(crate) fn apply_step(&mut self, step: &UndoStep, forward: bool) {
        let n = if forward { step.n_after } else { step.n_before };
        self.set_used_length(step.n_before.max(step.n_after));
        for (c, before, after) in step.entries() {
            let (r, o) = if forward { (after, before) } else { (before, after) };
            self.write_record(c, r);
            self.changes.direct(c);
            if r.first_child != o.first_child {
                let unit = if r.first_child != NONE { r.first_child } else { o.first_child };
                self.changes.topology(c, unit);
            }
        }
        self.set_used_length(n);
        self.rebuild_free_units();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(parent: u32, first_child: u32, depth: u8, rgb: [u8; 3], sigma: f32) -> CellRecord {
        CellRecord { parent, first_child, depth, rgb, sigma }
    }

    #[test]
    fn a_step_keeps_every_change_in_its_cheapest_form() {
        let leaf = |rgb, sigma| rec(0, NONE, 3, rgb, sigma);
        let cases = [
            (8, leaf([1, 2, 3], 0.5), leaf([4, 5, 6], 0.75)),                    // value: 23 bytes
            (9, CellRecord::FREE, leaf([7, 8, 9], 1.0)),                         // born: 20
            (10, leaf([1, 1, 1], 2.0), CellRecord::FREE),                        // freed: 20
            (11, leaf([1, 1, 1], 2.0), rec(0, 16, 3, [1, 1, 1], 2.0)),           // refined: 36
            (12, rec(0, 16, 3, [0; 3], 0.0), rec(0, 16, 3, [0; 3], -0.0)),       // internal: 36
            (13, leaf([1, 1, 1], 2.0), rec(5, NONE, 3, [1, 1, 1], 2.0)),         // reparented: 36
        ];
        let mut step = UndoStep::new(16, 24);
        for (c, b, a) in cases {
            step.push(c, b, a);
        }
        assert_eq!(step.len(), cases.len());
        assert_eq!(step.bytes(), 23 + 20 + 20 + 36 + 36 + 36);
        let mut got: Vec<_> = step.entries().collect();
        got.sort_by_key(|e| e.0);
        for ((c, b, a), (d, e, f)) in cases.iter().zip(&got) {
            assert_eq!(c, d);
            assert!(b.same_bits(e) && a.same_bits(f), "cell {c} came back changed");
        }
    }
}

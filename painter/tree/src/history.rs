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

use crate::pool::{CellRecord, Tree};

#[derive(Clone)]
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

/// One stroke's effect on the pools.
#[derive(Clone, Debug)]
pub struct UndoStep {
    pub n_before: u32,
    pub n_after: u32,
    pub cells: Vec<u32>,
    pub before: Vec<CellRecord>,
    pub after: Vec<CellRecord>,
}

impl UndoStep {
    pub fn bytes(&self) -> usize {
        self.cells.len() * (4 + 2 * std::mem::size_of::<CellRecord>())
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
        self.journal = Some(Journal { n_before: self.n_used(), saved: Vec::new(), cells: Vec::new(), before: Vec::new() });
    }

    /// Stop saving and return the stroke's undo step: the cells whose
    /// record changed (each once, so the order of writing them back does
    /// not matter): the saved cells, then the cells past the old used
    /// length, which were free.
    pub(crate) fn commit_journal(&mut self) -> UndoStep {
        let j = self.journal.take().expect("commit without begin");
        let mut step = UndoStep { n_before: j.n_before, n_after: self.n_used(), cells: vec![], before: vec![], after: vec![] };
        for (&c, before) in j.cells.iter().zip(&j.before) {
            let now = self.record(c);
            if !now.same_bits(before) {
                step.cells.push(c);
                step.before.push(*before);
                step.after.push(now);
            }
        }
        for c in j.n_before..self.n_used() {
            let now = self.record(c);
            if !now.same_bits(&CellRecord::FREE) {
                step.cells.push(c);
                step.before.push(CellRecord::FREE);
                step.after.push(now);
            }
        }
        step
    }

    /// Write one side of an undo step: the records and the used length.
    /// Marks the rewritten cells dirty, and the cells that gained or lost
    /// children as topology changes (spec 10, 3.4).
    pub(crate) fn apply_step(&mut self, step: &UndoStep, forward: bool) {
        let (recs, old, n) =
            if forward { (&step.after, &step.before, step.n_after) } else { (&step.before, &step.after, step.n_before) };
        self.set_used_length(step.n_before.max(step.n_after));
        for ((&c, r), o) in step.cells.iter().zip(recs).zip(old) {
            self.write_record(c, *r);
            self.changes.direct(c);
            if r.first_child != o.first_child {
                let unit = if r.first_child != crate::pool::NONE { r.first_child } else { o.first_child };
                self.changes.topology(c, unit);
            }
        }
        self.set_used_length(n);
        self.rebuild_free_units();
    }
}

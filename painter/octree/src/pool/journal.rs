//! The undo journal of the stroke under way: each cell's record before its
//! first write, saved by the pools' writes (mod.rs); history.rs turns it
//! into an undo step at stroke end. Reference twin: the journal of
//! reference/octopaint_ref/history.py.

use super::CellRecord;

#[derive(Clone, Default)]
pub(crate) struct Journal {
    /// The used length when the stroke began.
    pub(crate) n_before: u32,
    /// One bit per cell below `n_before`: saved already.
    saved: Vec<u64>,
    /// The saved cells in the order of their first write, and their
    /// records before it.
    pub(crate) cells: Vec<u32>,
    pub(crate) before: Vec<CellRecord>,
}

impl Journal {
    /// Whether `c`'s record must be saved before its first write. Cells at
    /// or past the used length of the stroke's start were free then: their
    /// before-record is known and commit adds them without a save.
    #[inline]
    pub(crate) fn needs_save(&self, c: u32) -> bool {
        if c >= self.n_before {
            return false;
        }
        let w = (c / 64) as usize;
        w >= self.saved.len() || self.saved[w] >> (c % 64) & 1 == 0
    }

    /// Every cell of the unit at `unit` was free when the stroke began
    /// (past its used length): none needs a save.
    #[inline]
    pub(crate) fn unit_is_new(&self, unit: u32) -> bool {
        unit >= self.n_before
    }

    /// The journal with nothing saved, its vectors kept: the saved bits are
    /// cleared word by word from the saved cells, not the whole bitset.
    pub(crate) fn emptied(mut self) -> Journal {
        for &c in &self.cells {
            self.saved[(c / 64) as usize] = 0;
        }
        self.cells.clear();
        self.before.clear();
        self
    }

    pub(crate) fn save(&mut self, c: u32, rec: CellRecord) {
        let w = (c / 64) as usize;
        if w >= self.saved.len() {
            self.saved.resize((w + 1).next_power_of_two(), 0);
        }
        self.saved[w] |= 1 << (c % 64);
        self.cells.push(c);
        self.before.push(rec);
    }
}

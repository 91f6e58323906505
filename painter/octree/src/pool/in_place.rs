//! The pools' values written in place by a parallel pass: the paint pass's
//! runs (octopaint-paint, paint/runs.rs), each on cells of subtrees no
//! other run holds. The one writer of the tree that does not journal or
//! mark blocks itself, so its contract is narrow: it writes the colour and
//! density of cells whose before-record the stroke's journal holds
//! already, and its caller marks the written blocks afterwards, in order,
//! on one thread ([`Tree::mark_block_written`]).

use super::Tree;
use super::changes::BLOCK_CELLS;
use crate::par::Disjoint;

/// The colour and density pools, for reading and writing in place from
/// several threads (see the module's contract).
#[derive(Clone, Copy)]
pub struct InPlaceValues {
    rgb: Disjoint<[u8; 3]>,
    sigma: Disjoint<f32>,
}

impl InPlaceValues {
    /// Cell `c`'s stored colour.
    ///
    /// # Safety
    /// No other thread writes cell `c` meanwhile, and the tree is not
    /// written otherwise while this value is used.
    #[inline]
    pub unsafe fn rgb(self, c: u32) -> [u8; 3] {
        unsafe { *self.rgb.at(c as usize) }
    }

    /// Cell `c`'s stored density (the safety of [`InPlaceValues::rgb`]).
    ///
    /// # Safety
    /// As [`InPlaceValues::rgb`].
    #[inline]
    pub unsafe fn sigma(self, c: u32) -> f32 {
        unsafe { *self.sigma.at(c as usize) }
    }

    /// Write cell `c`'s colour and density; `tree` is the tree the values
    /// were taken from (to check, in debug builds, that its journal holds
    /// the cell's before-record).
    ///
    /// # Safety
    /// No other thread reads or writes cell `c` meanwhile, and the tree is
    /// not written otherwise while this value is used.
    #[inline]
    pub unsafe fn set(self, tree: &Tree, c: u32, rgb: [u8; 3], sigma: f32) {
        debug_assert!(tree.journal.as_ref().is_none_or(|j| !j.needs_save(c)), "cell {c} written in place before it was journalled");
        let _ = tree;
        unsafe {
            *self.rgb.at(c as usize) = rgb;
            *self.sigma.at(c as usize) = sigma;
        }
    }
}

impl Tree {
    /// The tree to read and its values to write in place, for a parallel
    /// pass (the module's contract). The returned tree must be the only
    /// access to it while the values are written.
    pub fn in_place_values(&mut self) -> (&Tree, InPlaceValues) {
        let values = InPlaceValues { rgb: Disjoint::new(&mut self.rgb), sigma: Disjoint::new(&mut self.sigma) };
        (self, values)
    }

    /// Block `b` (of [`BLOCK_CELLS`] cells) was written in place: marked
    /// dirty, as every other writer marks its cells' blocks.
    #[inline]
    pub fn mark_block_written(&mut self, b: u32) {
        self.changes.mark_block(b * BLOCK_CELLS);
    }
}

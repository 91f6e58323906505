//! The writes of a cell's colour and density alone (painting, a merge, an
//! export's copy): journalled and marked as every write of the pools
//! (mod.rs), and listed for the interior values' next update (spec 4.4,
//! [`crate::prefilter`]).

use super::{NONE, Tree};

impl Tree {
    /// Write a cell's colour and density (painting); its ancestors' values
    /// follow at the next [`Tree::update_prefilter`].
    #[inline]
    pub fn set_value(&mut self, c: u32, rgb: [u8; 3], sigma: f32) {
        self.touch(c);
        self.rgb[c as usize] = rgb;
        self.sigma[c as usize] = sigma;
        // A leaf's unit stands for it (crate::prefilter): a stroke's first
        // writes come unit by unit.
        let due = if self.first_child[c as usize] == NONE { c & !7 } else { c };
        self.list_written(due);
    }

    /// Write the value of a cell that `make_children` made in this step:
    /// its journal entry and dirty block are in place already, and no
    /// publication has been taken since.
    #[inline]
    pub fn set_new_child_value(&mut self, c: u32, rgb: [u8; 3], sigma: f32) {
        debug_assert!(self.journal.as_ref().is_none_or(|j| !j.needs_save(c)));
        self.rgb[c as usize] = rgb;
        self.sigma[c as usize] = sigma;
        self.list_written(c & !7);
    }

    /// Every cell's density through `f` (a copy for export scaled by its
    /// layer's opacity): not journalled, and the next publication covers
    /// everything.
    pub fn map_sigma(&mut self, f: impl Fn(f32) -> f32) {
        for s in &mut self.sigma {
            *s = f(*s);
        }
        // f of a mean is not the mean of f: the interior values again from
        // the leaves (spec 4.4).
        self.prefilter_all();
        self.mark_everything_dirty();
    }
}

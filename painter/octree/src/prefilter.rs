//! Interior values (spec 4.4): every cell with children holds the
//! prefilter of its 8 children, the density their mean and the colour
//! their density-weighted mean. Reference twin:
//! reference/octopaint_ref/prefilter.py, which computes them whole when a
//! dump reads them; here they are kept current as cells change.
//!
//! The values are a function of the leaves and the topology alone, so they
//! need no journal of their own: the pools' value writes ([`Tree::set_value`],
//! the new children a round paints, the paint pass's in-place writes handed
//! over with [`Tree::note_values_written`]) list their cells, and
//! [`Tree::update_prefilter`] recomputes those cells' ancestors, each once,
//! bottom up, stopping where a value comes out unchanged. Its writes go
//! through the journalled writer like any other (an undo restores them with
//! the rest) and mark their blocks (the GPU sees them). It runs at every
//! publication ([`Tree::take_publication`]) and at the end of every
//! stroke, import, undo and redo; a reader inside a stroke (a snapshot)
//! calls it first. A stroke's samples rewrite the same ancestors again and
//! again, so between publications their updates wait for the stroke's end
//! (at every sample they took a sixth of `bench tree`'s time).
//!
//! Refinement (spec 4.1: eight copies of the leaf) and coarsening (spec
//! 4.3: the value of eight equal children, or of eight empty ones whose
//! octant 0 gives the colour) write no value that differs from the
//! prefilter, so neither lists a cell.

use crate::par;
use crate::pool::{FREE, NONE, Tree, UNIT};

/// The prefilter of a unit of children (spec 4.4), in octant order: exact
/// f64, the density rounded once to f32 and each channel once to a byte;
/// octant 0's colour when all eight are empty. The four sums (density and
/// the three density-weighted channels) go side by side, in the spec's
/// order (pairs, then pairs of pairs), so that they share vector lanes.
pub fn unit_value(rgb: &[[u8; 3]; 8], sigma: &[f32; 8]) -> ([u8; 3], f32) {
    let x: [[f64; 4]; 8] = std::array::from_fn(|k| {
        let s = f64::from(sigma[k]);
        [s, s * f64::from(rgb[k][0]), s * f64::from(rgb[k][1]), s * f64::from(rgb[k][2])]
    });
    let add = |a: [f64; 4], b: [f64; 4]| [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]];
    let sum = add(add(add(x[0], x[1]), add(x[2], x[3])), add(add(x[4], x[5]), add(x[6], x[7])));
    let w = sum[0];
    let mean = (w * 0.125) as f32;
    if !(w > 0.0) {
        return (rgb[0], mean);
    }
    let channel = |m: f64| (m / w + 0.5).floor().clamp(0.0, 255.0) as u8;
    ([channel(sum[1]), channel(sum[2]), channel(sum[3])], mean)
}

/// Room kept in the list of written cells between updates (an update of
/// more gives the rest back).
const SPARE_DUE: usize = 1 << 16;

impl Tree {
    /// List `due` for the interior values' next update, unless it is the
    /// entry listed last.
    #[inline]
    pub(crate) fn list_written(&mut self, due: u32) {
        if self.prefilter_due.last() != Some(&due) {
            self.prefilter_due.push(due);
        }
    }

    /// Write an interior cell's prefiltered value (spec 4.4): journalled and
    /// marked, not listed (its ancestors are the update's own work).
    #[inline]
    pub(crate) fn write_interior_value(&mut self, c: u32, rgb: [u8; 3], sigma: f32) {
        self.touch(c);
        self.rgb[c as usize] = rgb;
        self.sigma[c as usize] = sigma;
    }

    /// The prefilter of `p`'s children when it is not the value `p` holds
    /// (sigma by its bits); None when it is (`p` has children).
    #[inline]
    fn fresh_value(&self, p: u32) -> Option<([u8; 3], f32)> {
        let fc = self.first_child[p as usize] as usize;
        let u = UNIT as usize;
        let rgb: &[[u8; 3]; 8] = self.rgb[fc..fc + u].try_into().expect("a unit is 8 cells");
        let sigma: &[f32; 8] = self.sigma[fc..fc + u].try_into().expect("a unit is 8 cells");
        let (rgb, sigma) = unit_value(rgb, sigma);
        let i = p as usize;
        (rgb != self.rgb[i] || sigma.to_bits() != self.sigma[i].to_bits()).then_some((rgb, sigma))
    }

    /// Cells whose values a parallel pass wrote in place
    /// ([`crate::pool::InPlaceValues`]): their ancestors are due for the
    /// next [`Tree::update_prefilter`]. A listed cell stands for itself
    /// when it has children and for its parent's value in any case, so a
    /// leaf may be listed by its unit's first cell (the same parent; the
    /// first cell's own value, when it has children, is recomputed to no
    /// change), and a root leaf by any root (it has no ancestor).
    pub fn note_values_written(&mut self, cells: &[u32]) {
        self.prefilter_due.extend_from_slice(cells);
    }

    /// Whether every value written since the last update has its ancestors
    /// updated: what a publication or a dump needs.
    pub fn prefilter_is_current(&self) -> bool {
        self.prefilter_due.is_empty()
    }

    /// Bring the interior values over every cell written since the last
    /// call up to date (spec 4.4): each listed cell itself when it has
    /// children, and its ancestors, each at most once, deepest first; an
    /// ancestor whose value comes out as it was stops the climb there.
    /// Returns the cells rewritten.
    pub fn update_prefilter(&mut self) -> usize {
        if self.prefilter_due.is_empty() {
            return 0;
        }
        let mut due = std::mem::take(&mut self.prefilter_due);
        let mut levels = std::mem::take(&mut self.prefilter_levels);
        levels.resize_with(self.lat.max_depth as usize + 1, Vec::new);
        let n = self.parent.len();
        for &c in &due {
            self.changes.value(c);
            let i = c as usize;
            if i >= n || self.depth[i] == FREE {
                continue;
            }
            let d = self.depth[i] as usize;
            if self.first_child[i] != NONE {
                levels[d].push(c);
            }
            if self.parent[i] != NONE {
                levels[d - 1].push(self.parent[i]);
            }
        }
        let mut rewritten = 0;
        for d in (0..levels.len()).rev() {
            let mut cells = std::mem::take(&mut levels[d]);
            par::sort_dedup(&mut cells);
            for &p in &cells {
                if self.first_child[p as usize] == NONE {
                    continue;
                }
                let Some((rgb, sigma)) = self.fresh_value(p) else { continue };
                self.write_interior_value(p, rgb, sigma);
                self.changes.value(p);
                rewritten += 1;
                if d > 0 {
                    levels[d - 1].push(self.parent[p as usize]);
                }
            }
            cells.clear();
            levels[d] = cells;
        }
        due.clear();
        due.shrink_to(SPARE_DUE);
        self.prefilter_due = due;
        self.prefilter_levels = levels;
        rewritten
    }

    /// Every interior value computed afresh from the leaves up (a tree
    /// read from a file, whose values may predate spec 4.4, or whose
    /// densities were all mapped). Journalled and marked as any write.
    /// Returns the cells rewritten.
    pub fn prefilter_all(&mut self) -> usize {
        self.prefilter_due.clear();
        let mut levels: Vec<Vec<u32>> = vec![Vec::new(); self.lat.max_depth as usize + 1];
        for c in 0..self.parent.len() {
            if self.depth[c] != FREE && self.first_child[c] != NONE {
                levels[self.depth[c] as usize].push(c as u32);
            }
        }
        let mut rewritten = 0;
        for cells in levels.iter().rev() {
            for &p in cells {
                if let Some((rgb, sigma)) = self.fresh_value(p) {
                    self.write_interior_value(p, rgb, sigma);
                    self.changes.value(p);
                    rewritten += 1;
                }
            }
        }
        rewritten
    }

    /// The cells with children whose stored value is not the prefilter of
    /// their children's stored values (sigma by its bits): empty in a tree
    /// that keeps spec 4.4. The tree's structure must be valid.
    pub fn stale_interior_cells(&self) -> Vec<u32> {
        (0..self.n_used()).filter(|&c| self.depth[c as usize] != FREE && self.first_child[c as usize] != NONE && self.fresh_value(c).is_some()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_equal_children_give_their_own_value() {
        for (rgb, sigma) in [([0, 0, 0], 0.0f32), ([255, 7, 128], 1e-45), ([1, 2, 3], 3.4028235e38), ([200, 100, 50], 0.37)] {
            assert_eq!(unit_value(&[rgb; 8], &[sigma; 8]), (rgb, sigma));
        }
    }

    #[test]
    fn density_is_the_mean_and_colour_the_density_weighted_mean() {
        let mut rgb = [[0u8; 3]; 8];
        let mut sigma = [0.0f32; 8];
        rgb[1] = [255, 0, 10];
        sigma[1] = 3.0;
        rgb[6] = [0, 255, 20];
        sigma[6] = 1.0;
        rgb[0] = [9, 9, 9]; // empty: no weight
        let (c, s) = unit_value(&rgb, &sigma);
        assert_eq!(s, 0.5);
        // (3·255 + 0)/4 = 191.25; (0 + 255)/4 = 63.75; (30 + 20)/4 = 12.5 -> 13.
        assert_eq!(c, [191, 64, 13]);
    }

    #[test]
    fn all_empty_children_give_octant_zeros_colour() {
        let rgb = std::array::from_fn(|k| [k as u8 * 30, 1, 2]);
        assert_eq!(unit_value(&rgb, &[0.0; 8]), ([0, 1, 2], 0.0));
        let mut rgb = rgb;
        rgb[0] = [77, 66, 55];
        assert_eq!(unit_value(&rgb, &[0.0; 8]), ([77, 66, 55], 0.0));
    }

    /// Roots 2x1x1, root 0 refined twice down (its octant 0, at the corner
    /// of the canvas, so that the tree stays balanced).
    fn deep_tree() -> (Tree, u32, u32) {
        let canvas = octopaint_model::Canvas { roots: [2, 1, 1], max_depth: 4, root_size: 0.5, capacity: 256 };
        let mut t = Tree::new(&canvas);
        let u = t.allocate_unit().unwrap();
        t.make_children(0, u);
        let v = t.allocate_unit().unwrap();
        t.make_children(u, v);
        (t, u, v)
    }

    #[test]
    fn a_write_reaches_every_ancestor_and_the_check_sees_one_that_did_not() {
        let (mut t, u, v) = deep_tree();
        assert!(t.stale_interior_cells().is_empty(), "refinement keeps the rule");
        t.set_value(v + 5, [200, 0, 0], 8.0);
        assert!(!t.prefilter_is_current());
        assert_eq!(t.stale_interior_cells(), [u], "only the parent reads its children");
        assert_eq!(t.update_prefilter(), 2, "the parent and the root");
        assert!(t.prefilter_is_current() && t.stale_interior_cells().is_empty());
        assert_eq!((t.rgb[u as usize], t.sigma[u as usize]), ([200, 0, 0], 1.0));
        assert_eq!((t.rgb[0], t.sigma[0]), ([200, 0, 0], 0.125));
        // A value written as it was stops the climb at the parent.
        t.set_value(v + 5, [200, 0, 0], 8.0);
        assert_eq!(t.update_prefilter(), 0);
        // An interior cell written directly is put right, and the check of
        // spec 11.2 names it meanwhile.
        t.set_value(0, [1, 2, 3], 9.0);
        assert!(crate::check::check_tree(&t).iter().any(|p| p.contains("prefilter") && p.contains("first 0")));
        assert_eq!(t.update_prefilter(), 1);
        assert!(crate::check::check_tree(&t).is_empty());
    }

    #[test]
    fn the_whole_tree_afresh_equals_the_updates() {
        let (mut t, u, v) = deep_tree();
        for (k, c) in [v + 1, v + 6, u + 7, 1].into_iter().enumerate() {
            t.set_value(c, [k as u8 * 60, 255 - k as u8, 7], k as f32 + 0.5);
        }
        t.update_prefilter();
        let kept = (t.rgb.clone(), t.sigma.clone());
        for c in [0, u] {
            t.write_interior_value(c, [9, 9, 9], 123.0);
        }
        assert_eq!(t.stale_interior_cells(), [0, u]);
        assert_eq!(t.prefilter_all(), 2);
        assert_eq!((t.rgb.clone(), t.sigma.clone()), kept);
    }

    #[test]
    fn the_mean_rounds_once_to_f32() {
        // 1 + 2^-23 and 1 (adjacent f32): their mean needs the f64 sum
        // (f32 sums would round at 7 of the 8 additions).
        let a = 1.0f32 + f32::EPSILON;
        let sigma = [a, a, a, 1.0, 1.0, 1.0, 1.0, 1.0];
        let want = ((3.0 * f64::from(a) + 5.0) / 8.0) as f32;
        assert_eq!(unit_value(&[[1, 1, 1]; 8], &sigma).1.to_bits(), want.to_bits());
    }
}

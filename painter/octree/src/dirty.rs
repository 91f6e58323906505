//! What changed since the last publication, in the two forms the GPU side
//! consumes (spec 3.4, 3.5): dirty blocks (65,536-cell ranges whose pool
//! bytes changed, to be staged and uploaded) and dirty cells (cells whose g3
//! must be recomputed), folded into the 64×32 neighbour mask with the cells
//! whose shading vector may change (rule 3: the GPU's g3 pass recomputes
//! both over the regions the mask marks).
//!
//! Writes mark blocks as they happen (pool/changes.rs). Topology changes are
//! recorded as "cell X gained or lost children" plus "unit U was created or
//! freed"; the dirty cells are derived from them when a publication is
//! taken, against the tree as it is then (spec 3.4 rules 1 and 2).

pub use crate::pool::changes::BLOCK_CELLS;

use crate::lattice::FACES;
use crate::pool::{FREE, NONE, Tree, UNIT};

/// Neighbour mask: 64 columns × 32 rows of regions.
pub const MASK_COLUMNS: usize = 64;
pub const MASK_ROWS: usize = 32;
pub const REGIONS: usize = MASK_COLUMNS * MASK_ROWS;

/// The 64×32 neighbour mask, 256 bytes: region `i` is row `i / 64`,
/// column `i % 64`, bit `column` of `rows[row]`.
///
/// ```text
///           col 0   1   2  ...  63
///  row 0   [  0 |  1 |  2 | ... | 63 ]
///  row 1   [ 64 | 65 | ...      |127 ]
///   ...
///  row 31  [1984| ...           |2047]
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct NeighbourMask {
    pub rows: [u64; MASK_ROWS],
}

impl NeighbourMask {
    pub fn set(&mut self, region: usize) {
        self.rows[region / MASK_COLUMNS] |= 1 << (region % MASK_COLUMNS);
    }

    pub fn get(&self, region: usize) -> bool {
        self.rows[region / MASK_COLUMNS] >> (region % MASK_COLUMNS) & 1 == 1
    }

    pub fn count(&self) -> u32 {
        self.rows.iter().map(|r| r.count_ones()).sum()
    }

    pub fn union(&mut self, o: &NeighbourMask) {
        for (a, b) in self.rows.iter_mut().zip(o.rows.iter()) {
            *a |= b;
        }
    }
}

/// Cells per region for a capacity: `ceil(capacity / 2048)`.
pub fn region_cells(capacity: u32) -> u32 {
    capacity.div_ceil(REGIONS as u32)
}

/// One publication: everything the GPU must refresh.
#[derive(Clone, Debug, Default)]
pub struct Publication {
    /// Dirty blocks, ascending.
    pub blocks: Vec<u32>,
    /// Cells whose g3 must be recomputed, ascending.
    pub dirty_cells: Vec<u32>,
    pub mask: NeighbourMask,
}

impl Tree {
    /// Make the next publication cover every block and every cell: for a
    /// consumer that starts from nothing (a GPU attached to a painted tree).
    pub fn mark_everything_dirty(&mut self) {
        self.changes.everything = true;
    }

    /// Everything changed since the last call: dirty blocks, dirty cells and
    /// the neighbour mask (spec 3.4, 3.5). The interior values are brought
    /// up to date first (spec 4.4), so that what is published keeps the rule
    /// and their blocks are among the dirty ones.
    pub fn take_publication(&mut self) -> Publication {
        self.update_prefilter();
        let ch = &mut self.changes;
        let mut blocks = Vec::new();
        if ch.any_block {
            for (w, word) in ch.blocks.iter_mut().enumerate() {
                let mut bits = std::mem::take(word);
                while bits != 0 {
                    blocks.push((w * 64) as u32 + bits.trailing_zeros());
                    bits &= bits - 1;
                }
            }
            ch.any_block = false;
        }
        let size = region_cells(self.capacity);
        let mut mask = NeighbourMask::default();
        if std::mem::take(&mut ch.everything) {
            // Every cell is dirty: what was recorded cell by cell is
            // contained in that, and can be large (a whole painting made
            // before a GPU attached: sorting it took a minute at 134 M
            // cells). Every block and every cell in use, every region they
            // lie in, and blocks past the used cells that were written (a
            // pool that shrank: the GPU must see them free again).
            ch.direct = Vec::new();
            ch.topo_cells = Vec::new();
            ch.topo_units = Vec::new();
            ch.values = Vec::new();
            let n = self.n_used();
            let used_blocks = n.div_ceil(BLOCK_CELLS);
            let beyond: Vec<u32> = blocks.into_iter().filter(|&b| b >= used_blocks).collect();
            let mut regions = |first: u32, end: u32| {
                if end > first {
                    for region in (first / size) as usize..=((end - 1) / size) as usize {
                        mask.set(region);
                    }
                }
            };
            regions(0, n);
            for &b in &beyond {
                regions(b * BLOCK_CELLS, (b + 1).saturating_mul(BLOCK_CELLS).min(self.capacity));
            }
            let blocks: Vec<u32> = (0..used_blocks).chain(beyond).collect();
            return Publication { blocks, dirty_cells: (0..n).collect(), mask };
        }
        let mut cells = std::mem::take(&mut ch.direct);
        let mut groups = std::mem::take(&mut ch.values);
        for u in std::mem::take(&mut ch.topo_units) {
            cells.extend(u..u + UNIT);
            groups.push(u);
        }
        let topo = std::mem::take(&mut ch.topo_cells);
        groups.extend(topo.iter().map(|&x| x & !7));
        for x in topo {
            if (x as usize) >= self.depth.len() || self.depth[x as usize] == FREE {
                continue;
            }
            for f in 0..FACES.len() {
                let m = self.internal_same_depth_neighbour(x, f);
                if m != NONE {
                    cells.extend(self.facing_children(m, f));
                }
            }
        }
        cells.sort_unstable();
        cells.dedup();
        for &c in &cells {
            mask.set((c / size) as usize);
        }
        groups.sort_unstable();
        groups.dedup();
        for g in groups {
            self.shading_readers(g, |c| mask.set((c / size) as usize));
        }
        Publication { blocks, dirty_cells: cells, mask }
    }

    /// Every cell whose stored shading vector may read a value of group `g`
    /// (spec 3.4 rule 3): a unit and its parent, or up to eight roots
    /// each standing for itself. Free cells are skipped.
    fn shading_readers(&self, g: u32, mut mark: impl FnMut(u32)) {
        let n = self.depth.len() as u32;
        let live = |c: u32| c < n && self.depth[c as usize] != FREE;
        let children = |c: u32, mark: &mut dyn FnMut(u32)| {
            let fc = self.first_child[c as usize];
            if fc != NONE {
                (fc..fc + UNIT).for_each(&mut *mark);
            }
        };
        // One family: `x` (a unit's parent, or a root) whose cells `own`
        // are the group's.
        let family = |x: u32, own: std::ops::Range<u32>, mark: &mut dyn FnMut(u32)| {
            for c in own {
                if live(c) {
                    mark(c);
                    children(c, mark);
                }
            }
            for f in 0..FACES.len() {
                let nb = self.neighbour(x, f);
                if nb == NONE {
                    continue;
                }
                mark(nb);
                if self.depth[nb as usize] != self.depth[x as usize] || self.first_child[nb as usize] == NONE {
                    continue;
                }
                for k in self.facing_children(nb, f) {
                    mark(k);
                    if self.first_child[k as usize] != NONE {
                        self.facing_children(k, f).into_iter().for_each(&mut *mark);
                    }
                }
            }
        };
        if g < self.lat.n_roots {
            for r in g..(g + UNIT).min(self.lat.n_roots) {
                family(r, r..r + 1, &mut mark);
            }
        } else if live(g) {
            let p = self.parent[g as usize];
            if p != NONE {
                family(p, g..g + UNIT, &mut mark);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use octopaint_model::Canvas;

    #[test]
    fn nothing_is_recorded_cell_by_cell_until_a_publication_is_taken() {
        let mut tree = Tree::new(&Canvas { roots: [2, 1, 1], max_depth: 4, root_size: 0.5, capacity: 256 });
        let root = 0;
        let unit = tree.allocate_unit().expect("a unit");
        tree.make_children(root, unit);
        tree.changes.direct(3);
        assert!(tree.changes.topo_cells.is_empty() && tree.changes.direct.is_empty(), "nobody has published yet");
        // The first publication covers every cell and block in use.
        let p = tree.take_publication();
        let n = tree.n_used();
        assert_eq!(p.dirty_cells, (0..n).collect::<Vec<_>>());
        assert_eq!(p.blocks, (0..n.div_ceil(BLOCK_CELLS)).collect::<Vec<_>>());
        // From then on, cell by cell: a unit's children and the cells whose
        // g3 they change, not every cell.
        let unit2 = tree.allocate_unit().expect("a unit");
        tree.make_children(unit, unit2);
        assert_eq!(tree.changes.topo_cells, [unit]);
        let p = tree.take_publication();
        assert!((unit2..unit2 + UNIT).all(|c| p.dirty_cells.contains(&c)), "{:?}", p.dirty_cells);
        assert!(p.dirty_cells.len() < tree.n_used() as usize, "{:?}", p.dirty_cells);
        // A consumer attaching marks everything again: no lists meanwhile.
        tree.mark_everything_dirty();
        tree.changes.direct(1);
        assert!(tree.changes.direct.is_empty());
        assert_eq!(tree.take_publication().dirty_cells.len(), tree.n_used() as usize);
    }
}

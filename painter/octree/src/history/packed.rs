//! A step's tail packed: the records of consecutive cells with their
//! parent and depth once a span and first_child only where there is one
//! (about 9 bytes a cell where the pools take 16).

use crate::pool::{CellRecord, NONE, Tree};

/// The records of consecutive cells, packed: rgb and sigma for every cell,
/// the parent and depth once for each span of cells that share them (a
/// unit's 8 siblings do), and first_child only where it is not NONE (most
/// cells a stroke makes are leaves). About 9 bytes a cell for a stroke's new
/// units, where the pools take 16.
#[derive(Clone, Debug, Default)]
pub(super) struct Packed {
    rgb: Vec<[u8; 3]>,
    sigma: Vec<f32>,
    /// Each span's first cell (its index in the run), parent and depth;
    /// a span runs to the next one's first cell.
    pub(super) span_at: Vec<u32>,
    span_parent: Vec<u32>,
    span_depth: Vec<u8>,
    /// The cells whose first_child is not NONE, ascending, and theirs.
    pub(super) child_at: Vec<u32>,
    child: Vec<u32>,
}

impl Packed {
    pub(super) fn len(&self) -> usize {
        self.rgb.len()
    }

    pub(super) fn push(&mut self, r: CellRecord) {
        let i = self.rgb.len() as u32;
        if self.span_parent.last() != Some(&r.parent) || self.span_depth.last() != Some(&r.depth) {
            self.open_span(i, r.parent, r.depth);
        }
        if r.first_child != NONE {
            self.add_child(i, r.first_child);
        }
        self.rgb.push(r.rgb);
        self.sigma.push(r.sigma);
    }

    /// A span of cells with this parent and depth starts at cell `i`.
    #[inline]
    pub(super) fn open_span(&mut self, i: u32, parent: u32, depth: u8) {
        self.span_at.push(i);
        self.span_parent.push(parent);
        self.span_depth.push(depth);
    }

    /// Cell `i`'s first_child is `fc` (not NONE).
    #[inline]
    pub(super) fn add_child(&mut self, i: u32, fc: u32) {
        self.child_at.push(i);
        self.child.push(fc);
    }

    /// The pools' records of `cells`: rgb and sigma copied slice by slice,
    /// the spans and children found by a scan of their columns each (the
    /// last span kept in a local: this runs over every new cell of a
    /// stroke).
    pub(super) fn from_pools(tree: &Tree, cells: std::ops::Range<usize>) -> Packed {
        let mut p = Packed { rgb: tree.rgb[cells.clone()].to_vec(), sigma: tree.sigma[cells.clone()].to_vec(), ..Packed::default() };
        let mut last = None;
        for (i, (&parent, &depth)) in tree.parent[cells.clone()].iter().zip(&tree.depth[cells.clone()]).enumerate() {
            if last != Some((parent, depth)) {
                last = Some((parent, depth));
                p.open_span(i as u32, parent, depth);
            }
        }
        for (i, &fc) in tree.first_child[cells].iter().enumerate() {
            if fc != NONE {
                p.add_child(i as u32, fc);
            }
        }
        p
    }

    /// Every record in order.
    pub(super) fn records(&self) -> impl Iterator<Item = CellRecord> + '_ {
        let (mut span, mut child) = (0usize, 0usize);
        (0..self.len()).map(move |i| {
            let at = i as u32;
            while span + 1 < self.span_at.len() && self.span_at[span + 1] <= at {
                span += 1;
            }
            let first_child = if self.child_at.get(child) == Some(&at) {
                child += 1;
                self.child[child - 1]
            } else {
                NONE
            };
            CellRecord { parent: self.span_parent[span], first_child, depth: self.span_depth[span], rgb: self.rgb[i], sigma: self.sigma[i] }
        })
    }

    /// How many records are `CellRecord::FREE` bit for bit: looked for only
    /// in the spans whose parent and depth are a free record's.
    pub(super) fn free_records(&self) -> usize {
        let free = CellRecord::FREE;
        let mut n = 0;
        for (k, (&parent, &depth)) in self.span_parent.iter().zip(&self.span_depth).enumerate() {
            if (parent, depth) != (free.parent, free.depth) {
                continue;
            }
            let from = self.span_at[k] as usize;
            let to = self.span_at.get(k + 1).map_or(self.len(), |&e| e as usize);
            let (lo, hi) = (self.child_at.partition_point(|&i| (i as usize) < from), self.child_at.partition_point(|&i| (i as usize) < to));
            let with_children = &self.child_at[lo..hi];
            n += (from..to)
                .filter(|&i| self.rgb[i] == free.rgb && self.sigma[i].to_bits() == free.sigma.to_bits() && with_children.binary_search(&(i as u32)).is_err())
                .count();
        }
        n
    }

    /// What the vectors hold, in bytes.
    pub(super) fn bytes(&self) -> usize {
        self.len() * (3 + 4) + self.span_at.len() * (4 + 4 + 1) + self.child_at.len() * (4 + 4)
    }

    pub(super) fn shrink(&mut self) {
        self.rgb.shrink_to_fit();
        self.sigma.shrink_to_fit();
        self.span_at.shrink_to_fit();
        self.span_parent.shrink_to_fit();
        self.span_depth.shrink_to_fit();
        self.child_at.shrink_to_fit();
        self.child.shrink_to_fit();
    }
}

/// Consecutive cells of a step's tail: the first and their records.
#[derive(Clone, Debug)]
pub(super) struct CellRun {
    pub(super) first: u32,
    pub(super) cols: Packed,
}

impl CellRun {
    pub(super) fn end(&self) -> u32 {
        self.first + self.cols.len() as u32
    }
}

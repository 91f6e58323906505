//! Where each layer lives in the GPU's pages (docs/architecture.md,
//! "Documents of layers"): a range of cells of its own, its tree's cells at
//! their own indices from the range's first cell (spec 6.2: the ray caster
//! and the g3 pass offset every read by it), so each layer's dirty blocks
//! are uploaded into its range and nothing else is written when one layer
//! changes.
//!
//! Ranges are whole 65,536-cell blocks. A layer that outgrows its range
//! grows in place when the cells after it are free (always for the last
//! range: a one-tree painting never moves), else moves to the first free
//! gap large enough, with room to double; when no gap is left the ranges
//! are packed from cell 0. A move is a copy on the GPU (cells and g3: g3
//! holds the tree's own indices, so it stays valid), never an upload.
//!
//! Ranges never shrink on their own (a layer that shrank by undo grows
//! back by redo), but the pages never shrink at all: so when a fit would
//! grow them, the ranges are packed instead, each keeping its room when
//! they all fit in the pages so, else each cut to the cells its layer
//! uses ([`Layout::set_length`]), and the pages grow only by what the
//! layers themselves need beyond them. Without the cut, reserves doubled
//! over a long session held twice the cells the layers used (bench soak).

use std::collections::{BTreeMap, HashMap};

use octopaint_tree::dirty::BLOCK_CELLS;

/// A range of cells to copy on the GPU: `cells` cells from `from` to `to`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Move {
    pub from: u64,
    pub to: u64,
    pub cells: u64,
}

#[derive(Clone, Debug, Default)]
pub struct Layout {
    /// By first cell: (layer id, cells reserved).
    ranges: BTreeMap<u64, (u32, u64)>,
    /// The cells the pages can ever hold.
    limit: u64,
    /// The cells the pages hold now ([`Layout::hold`]): a fit that would
    /// reach past them packs the ranges instead when they fit in them
    /// packed, so that layers added, deleted and grown over a long
    /// session do not grow the pages (which never shrink) with gaps.
    held: u64,
    /// Per layer: the cells its tree uses, as the caller last said.
    lengths: HashMap<u32, u64>,
}

fn whole_blocks(cells: u64) -> u64 {
    cells.max(1).div_ceil(u64::from(BLOCK_CELLS)) * u64::from(BLOCK_CELLS)
}

impl Layout {
    pub fn new(limit: u64) -> Layout {
        Layout { ranges: BTreeMap::new(), limit, held: 0, lengths: HashMap::new() }
    }

    /// The pages hold `cells` cells now.
    pub fn hold(&mut self, cells: u64) {
        self.held = cells;
    }

    /// Cells reserved over all ranges.
    fn reserved(&self) -> u64 {
        self.ranges.values().map(|&(_, r)| r).sum()
    }

    fn find(&self, id: u32) -> Option<(u64, u64)> {
        self.ranges.iter().find(|(_, (i, _))| *i == id).map(|(&b, &(_, r))| (b, r))
    }

    /// Layer `id`'s first cell and the cells it has, if it has a range.
    pub fn range(&self, id: u32) -> Option<(u64, u64)> {
        self.find(id)
    }

    /// One past the last reserved cell.
    pub fn end(&self) -> u64 {
        self.ranges.iter().next_back().map_or(0, |(&b, &(_, r))| b + r)
    }

    /// Layer `id` uses `cells` cells now: what its range is cut to when
    /// the ranges are packed tight. The caller says so before fitting the
    /// layer's copies, counting every copy it is about to write.
    pub fn set_length(&mut self, id: u32, cells: u64) {
        self.lengths.insert(id, cells);
    }

    /// Forget layer `id`'s range (no longer listed).
    pub fn free(&mut self, id: u32) {
        if let Some((b, _)) = self.find(id) {
            self.ranges.remove(&b);
        }
        self.lengths.remove(&id);
    }

    /// The layers that have ranges.
    pub fn ids(&self) -> Vec<u32> {
        self.ranges.values().map(|&(id, _)| id).collect()
    }

    /// The first cell of the first gap of `cells` cells, from `at` on
    /// (ranges other than `skip`'s count as taken).
    fn gap(&self, cells: u64, skip: Option<u64>) -> Option<u64> {
        let mut at = 0u64;
        for (&b, &(_, r)) in &self.ranges {
            if Some(b) == skip {
                continue;
            }
            if b >= at + cells {
                return Some(at);
            }
            at = at.max(b + r);
        }
        (at + cells <= self.limit).then_some(at)
    }

    /// Make layer `id`'s range hold `cells` cells. Returns the copies to
    /// make on the GPU, all sources read before any destination is written
    /// (`GpuPools::move_ranges`); Err when the pages cannot hold every
    /// layer even packed tight.
    pub fn fit(&mut self, id: u32, cells: u64) -> Result<Vec<Move>, String> {
        let before = self.clone();
        let tried = self.fit_somewhere(id, cells);
        if tried.is_ok() && self.end() <= self.held.max(before.end()) {
            return tried;
        }
        // The pages would grow: packed, every range keeping its room if
        // that fits in the pages; else cut to its layer's cells, unless
        // that grows the pages no less than the fit did.
        let fitted = std::mem::replace(self, before);
        let cells = whole_blocks(cells);
        if self.packed_adding(id, cells, false) <= self.held {
            return self.pack_adding(id, cells, false);
        }
        let tight = self.packed_adding(id, cells, true);
        if let Ok(moves) = tried
            && fitted.end() <= tight
        {
            *self = fitted;
            return Ok(moves);
        }
        if tight > self.limit {
            return Err(self.full(tight));
        }
        self.pack_adding(id, cells, true)
    }

    /// Cells [`Layout::pack_adding`] packs the ranges into.
    fn packed_adding(&self, id: u32, cells: u64, tight: bool) -> u64 {
        match self.find(id) {
            Some(_) => self.packed(Some((id, cells)), tight),
            None => self.packed(None, tight) + cells,
        }
    }

    /// [`Layout::pack`], layer `id` last with `cells` cells (added after
    /// the others when it has no range yet).
    fn pack_adding(&mut self, id: u32, cells: u64, tight: bool) -> Result<Vec<Move>, String> {
        if self.find(id).is_some() {
            return self.pack(Some((id, cells)), tight);
        }
        let moves = self.pack(None, tight)?;
        let at = self.end();
        self.ranges.insert(at, (id, cells));
        Ok(moves)
    }

    /// [`Layout::fit`] without regard to the pages held: in place, a gap,
    /// past the end, or packed when nothing else is left.
    fn fit_somewhere(&mut self, id: u32, cells: u64) -> Result<Vec<Move>, String> {
        let cells = whole_blocks(cells);
        let Some((base, have)) = self.find(id) else {
            let used = self.reserved();
            if used + cells > self.limit {
                return Err(self.full(used + cells));
            }
            let (at, moves) = match self.gap(cells, None) {
                Some(at) => (at, Vec::new()),
                None => {
                    let moves = self.pack(None, false)?;
                    (self.end(), moves)
                }
            };
            self.ranges.insert(at, (id, cells));
            return Ok(moves);
        };
        if cells <= have {
            return Ok(Vec::new());
        }
        let next = self.ranges.range(base + 1..).next().map_or(self.limit, |(&b, _)| b);
        let last = next == self.limit;
        // Room to double, so that a growing layer moves rarely; the last
        // range grows exactly (the pages themselves grow by powers of two).
        let want = if last { cells } else { whole_blocks(cells.max(2 * have)) };
        if base + want <= next {
            self.ranges.insert(base, (id, want));
            return Ok(Vec::new());
        }
        if let Some(to) = self.gap(want, Some(base)) {
            self.ranges.remove(&base);
            self.ranges.insert(to, (id, want));
            return Ok(vec![Move { from: base, to, cells: have }]);
        }
        self.pack(Some((id, cells)), false)
    }

    /// The size of layer `id`'s range of `reserved` cells once packed:
    /// its reserve, or (`tight`) the whole blocks its layer uses; `grow`'s
    /// layer at least its new size.
    fn packed_size(&self, id: u32, reserved: u64, grow: Option<(u32, u64)>, tight: bool) -> u64 {
        let kept = if tight { self.lengths.get(&id).map_or(reserved, |&n| whole_blocks(n).min(reserved)) } else { reserved };
        match grow {
            Some((g, cells)) if g == id => kept.max(cells),
            _ => kept,
        }
    }

    /// Cells every range takes packed ([`Layout::pack`]).
    fn packed(&self, grow: Option<(u32, u64)>, tight: bool) -> u64 {
        self.ranges.values().map(|&(id, r)| self.packed_size(id, r, grow, tight)).sum()
    }

    /// Pack every range from cell 0 in order, `grow`'s layer last with its
    /// new size; `tight`, each cut to the cells its layer uses (only those
    /// are copied).
    fn pack(&mut self, grow: Option<(u32, u64)>, tight: bool) -> Result<Vec<Move>, String> {
        let mut order: Vec<(u64, u32, u64)> = self.ranges.iter().map(|(&b, &(id, r))| (b, id, r)).collect();
        if let Some((gid, _)) = grow {
            let k = order.iter().position(|o| o.1 == gid).expect("growing a layer with a range");
            let g = order.remove(k);
            order.push(g);
        }
        let total = self.packed(grow, tight);
        if total > self.limit {
            return Err(self.full(total));
        }
        let sizes: Vec<u64> = order.iter().map(|&(_, id, r)| self.packed_size(id, r, grow, tight)).collect();
        let mut moves = Vec::new();
        let mut at = 0u64;
        self.ranges.clear();
        for ((b, id, r), size) in order.into_iter().zip(sizes) {
            if b != at {
                moves.push(Move { from: b, to: at, cells: r.min(size) });
            }
            self.ranges.insert(at, (id, size));
            at += size;
        }
        Ok(moves)
    }

    fn full(&self, cells: u64) -> String {
        format!("the document's layers need {cells} cells on the GPU, more than its pages hold ({})", self.limit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const B: u64 = BLOCK_CELLS as u64;

    /// No two ranges overlap, every range fits under the limit.
    fn disjoint(l: &Layout) {
        let mut end = 0;
        for (&b, &(_, r)) in &l.ranges {
            assert!(b >= end && b + r <= l.limit, "{:?}", l.ranges);
            end = b + r;
        }
    }

    #[test]
    fn the_last_range_grows_in_place_and_others_move_or_pack() {
        let mut l = Layout::new(16 * B);
        l.hold(16 * B);
        assert_eq!(l.fit(0, 10), Ok(vec![]));
        assert_eq!(l.range(0), Some((0, B)));
        // One tree: always in place, however far it grows.
        assert_eq!(l.fit(0, 3 * B + 1), Ok(vec![]));
        assert_eq!(l.range(0), Some((0, 4 * B)));
        // A second layer after it; then the first grows: it moves past the
        // second with room to double, a copy of what it had.
        assert_eq!(l.fit(1, B), Ok(vec![]));
        assert_eq!(l.range(1), Some((4 * B, B)));
        assert_eq!(l.fit(0, 5 * B), Ok(vec![Move { from: 0, to: 5 * B, cells: 4 * B }]));
        assert_eq!(l.range(0), Some((5 * B, 8 * B)));
        disjoint(&l);
        // A third layer takes the gap the move left.
        assert_eq!(l.fit(2, 2 * B), Ok(vec![]));
        assert_eq!(l.range(2), Some((0, 2 * B)));
        disjoint(&l);
        // Layer 2 grows past every gap: everything is packed, it last.
        l.free(1);
        let moves = l.fit(2, 7 * B).unwrap();
        disjoint(&l);
        assert_eq!(l.range(0), Some((0, 8 * B)));
        assert_eq!(l.range(2), Some((8 * B, 7 * B)));
        assert_eq!(moves, vec![Move { from: 5 * B, to: 0, cells: 8 * B }, Move { from: 0, to: 8 * B, cells: 2 * B }]);
        // More than the pages hold: refused, nothing changed.
        assert!(l.fit(3, 2 * B).unwrap_err().contains("more than its pages hold"));
        assert_eq!(l.ids(), vec![0, 2]);
        disjoint(&l);
    }

    #[test]
    fn layers_that_come_and_go_do_not_grow_the_pages_they_fit_in() {
        // Pages holding 8 blocks; layers added, grown and freed in turn
        // (a long session's duplicates and deletes): whenever they fit in
        // the pages packed, no range reaches past them.
        let mut l = Layout::new(64 * B);
        l.hold(8 * B);
        for round in 0..50u32 {
            let id = 10 + round;
            l.fit(id, 2 * B).unwrap();
            l.fit(id, 3 * B).unwrap();
            disjoint(&l);
            if l.reserved() <= 8 * B {
                assert!(l.end() <= 8 * B, "round {round}: {:?}", l.ranges);
            }
            if round >= 1 {
                l.free(id - 1);
            }
        }
        // More than the pages hold, packed: past them, as it must.
        l.fit(100, 6 * B).unwrap();
        assert!(l.end() > 8 * B);
        disjoint(&l);
    }

    #[test]
    fn ranges_are_cut_to_their_layers_cells_rather_than_grow_the_pages() {
        // A layer that grew to 6 blocks, then shrank (undo) to half a
        // block; a new layer of 4 does not fit after it in the 8 blocks
        // held: the first is cut to its one block, in place.
        let mut l = Layout::new(64 * B);
        l.hold(8 * B);
        l.fit(0, 6 * B).unwrap();
        l.set_length(0, B / 2);
        assert_eq!(l.fit(1, 4 * B), Ok(vec![]));
        assert_eq!((l.range(0), l.range(1), l.end()), (Some((0, B)), Some((B, 4 * B)), 5 * B));
        // Two layers fill the pages; the first grows when the second uses
        // a block of its five: packed, the second cut to its block and
        // only that copied, the grower last.
        let mut l = Layout::new(64 * B);
        l.hold(8 * B);
        l.fit(0, 2 * B).unwrap();
        l.fit(1, 5 * B).unwrap();
        l.set_length(1, B);
        l.set_length(0, 4 * B);
        let moves = l.fit(0, 4 * B).unwrap();
        assert_eq!(moves, vec![Move { from: 2 * B, to: 0, cells: B }, Move { from: 0, to: B, cells: 2 * B }]);
        assert_eq!((l.range(1), l.range(0), l.end()), (Some((0, B)), Some((B, 4 * B)), 5 * B));
        // With room in the pages, reserves are kept: the second layer's
        // five blocks stay though it uses one.
        let mut l = Layout::new(64 * B);
        l.hold(16 * B);
        l.fit(0, 2 * B).unwrap();
        l.fit(1, 5 * B).unwrap();
        l.set_length(1, B);
        l.fit(0, 4 * B).unwrap();
        assert_eq!(l.range(1), Some((2 * B, 5 * B)));
        disjoint(&l);
    }

    /// A long session on a model of the pages: layers added, grown,
    /// shrunk (undo) and deleted at random, each fit's moves applied to
    /// the model (sources read before destinations written) before the
    /// next, the pages growing exactly to the ranges' end. Every layer's
    /// cells stay where its range says, and the pages never hold more than
    /// the most the layers used at once, in whole blocks.
    #[test]
    fn a_long_session_keeps_every_layer_and_the_pages_within_what_layers_use() {
        let mut l = Layout::new(1 << 30);
        let mut pages: Vec<(u32, u64)> = Vec::new();
        let mut lengths: BTreeMap<u32, u64> = BTreeMap::new();
        let (mut seed, mut most, mut cut) = (7u64, 0u64, 0);
        let mut next = |n: u64| {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 33) % n
        };
        for round in 0..1500u32 {
            let id = next(6) as u32;
            let n = match lengths.get(&id) {
                Some(&n) if next(4) == 0 => n / 2,
                Some(&n) => n + next(2 * B),
                None => 1 + next(2 * B),
            };
            if next(40) == 0 && lengths.len() > 1 {
                lengths.remove(&id);
                l.free(id);
                continue;
            }
            lengths.insert(id, n);
            l.set_length(id, n);
            most = most.max(lengths.values().map(|&n| whole_blocks(n)).sum());
            let packed_before = l.reserved();
            let moves = l.fit(id, n).unwrap();
            if l.reserved() < packed_before {
                cut += 1;
            }
            let read: Vec<Vec<(u32, u64)>> = moves.iter().map(|m| pages[m.from as usize..(m.from + m.cells) as usize].to_vec()).collect();
            if l.end() > pages.len() as u64 {
                pages.resize(l.end() as usize, (u32::MAX, 0));
            }
            for (m, cells) in moves.iter().zip(read) {
                pages[m.to as usize..(m.to + m.cells) as usize].copy_from_slice(&cells);
            }
            // The layer's cells are written at its range (an upload).
            let (base, have) = l.range(id).unwrap();
            assert!(have >= n);
            for k in 0..n {
                pages[(base + k) as usize] = (id, k);
            }
            l.hold(pages.len() as u64);
            disjoint(&l);
            for (&lid, &ln) in &lengths {
                let (b, r) = l.range(lid).unwrap();
                assert!(r >= ln, "round {round}: layer {lid} has {r} cells for {ln}");
                assert!((0..ln).all(|k| pages[(b + k) as usize] == (lid, k)), "round {round}: layer {lid} lost a cell");
            }
            assert!(pages.len() as u64 <= most, "round {round}: the pages hold {} cells, the layers used at most {most}", pages.len());
        }
        assert!(cut > 0, "the session never cut a range to its layer's cells");
    }
}

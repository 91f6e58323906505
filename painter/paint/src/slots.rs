//! The stroke's map from cell to slot (paint/), in pages.
//!
//! A stroke looks up every cell it visits, so the map must answer at once;
//! but it touches a small part of the pools, and a map as long as the
//! pools (4 bytes a cell) would add a quarter to their 16 bytes a cell for
//! the whole canvas. Here the cells are cut into pages of [`PAGE`]; a page
//! gets its entries when the stroke gives one of its cells a slot, and at
//! the stroke's end every page goes back to a free list (its entries reset
//! to NONE) for the next stroke. The map takes memory for the pages one
//! stroke touches, not for the canvas.

use octopaint_octree::pool::NONE;

/// Cells a page: 4 KiB of entries.
pub const PAGE: usize = 1024;

/// Pages are reset whole when they hold at least PAGE / DENSE slots on
/// average: a fill of a page costs about as much as this many scattered
/// stores.
const DENSE: usize = 16;

/// A page not in use.
const NO_PAGE: u32 = u32::MAX;

#[derive(Clone, Default)]
pub struct SlotMap {
    /// Page number -> its place in `entries` (in pages), NO_PAGE when it
    /// has none; as long as the highest page given an entry.
    page_at: Vec<u32>,
    /// The pages' entries, PAGE a page: a slot or NONE.
    entries: Vec<u32>,
    /// Places in `entries` whose entries are all NONE, for the next page.
    free: Vec<u32>,
    /// The page numbers given a place since the last `clear`.
    in_use: Vec<u32>,
}

impl SlotMap {
    /// Where `c`'s entry lies in `entries`, None when its page has no place.
    #[inline(always)]
    fn entry(&self, c: u32) -> Option<usize> {
        match self.page_at.get(c as usize / PAGE) {
            Some(&at) if at != NO_PAGE => Some(at as usize * PAGE + c as usize % PAGE),
            _ => None,
        }
    }

    /// Where `c`'s entry lies in `entries`, its page given a place if it
    /// has none.
    #[inline(always)]
    fn entry_or_new(&mut self, c: u32) -> usize {
        let p = c as usize / PAGE;
        let at = match self.page_at.get(p) {
            Some(&at) if at != NO_PAGE => at,
            _ => self.new_page(p),
        };
        at as usize * PAGE + c as usize % PAGE
    }

    /// `c`'s slot, NONE when it has none.
    #[inline(always)]
    pub fn get(&self, c: u32) -> u32 {
        self.entry(c).map_or(NONE, |e| self.entries[e])
    }

    /// The slots of the 8 cells of `unit` (a multiple of 8), None when
    /// none of them has one: one page lookup for the 8 (a page is a whole
    /// number of units).
    #[inline(always)]
    pub fn unit(&self, unit: u32) -> Option<&[u32; 8]> {
        const { assert!(PAGE.is_multiple_of(8)) };
        debug_assert!(unit.is_multiple_of(8));
        self.entry(unit).map(|e| (&self.entries[e..][..8]).try_into().expect("8 entries"))
    }

    /// Give `c` the slot `s` (not NONE).
    #[inline]
    pub fn set(&mut self, c: u32, s: u32) {
        let e = self.entry_or_new(c);
        self.entries[e] = s;
    }

    /// Give the 8 cells of `unit` (a multiple of 8) the slots `s..s + 8`,
    /// with one page lookup.
    #[inline]
    pub fn set_unit(&mut self, unit: u32, s: u32) {
        const { assert!(PAGE.is_multiple_of(8)) };
        debug_assert!(unit.is_multiple_of(8));
        let e = self.entry_or_new(unit);
        let unit_entries: &mut [u32; 8] = (&mut self.entries[e..][..8]).try_into().expect("8 entries");
        *unit_entries = std::array::from_fn(|k| s + k as u32);
    }

    /// A place for page `p`: a free one, else a new one at the end.
    #[cold]
    fn new_page(&mut self, p: usize) -> u32 {
        if p >= self.page_at.len() {
            self.page_at.resize(p + 1, NO_PAGE);
        }
        let at = self.free.pop().unwrap_or_else(|| {
            let at = (self.entries.len() / PAGE) as u32;
            self.entries.resize(self.entries.len() + PAGE, NONE);
            at
        });
        self.page_at[p] = at;
        self.in_use.push(p as u32);
        at
    }

    /// Forget every slot: `cells` are the cells given one (their entries
    /// go back to NONE), and every page goes to the free list. Where the
    /// cells fill their pages densely (a stroke's new units lie side by
    /// side), each page is reset whole, a fill of 4 KiB, rather than one
    /// scattered store a cell.
    pub fn clear(&mut self, cells: impl ExactSizeIterator<Item = u32>) {
        let whole_pages = cells.len() >= self.in_use.len() * (PAGE / DENSE);
        if !whole_pages {
            for c in cells {
                let e = self.entry(c).expect("a cell given a slot has a page");
                self.entries[e] = NONE;
            }
        }
        for &p in &self.in_use {
            let at = std::mem::replace(&mut self.page_at[p as usize], NO_PAGE);
            if whole_pages {
                self.entries[at as usize * PAGE..][..PAGE].fill(NONE);
            }
            debug_assert!(self.entries[at as usize * PAGE..][..PAGE].iter().all(|&e| e == NONE), "a page went back with a slot in it");
            self.free.push(at);
        }
        self.in_use.clear();
    }

    /// Bytes the map holds (its vectors' capacity).
    pub fn bytes(&self) -> usize {
        (self.page_at.capacity() + self.entries.capacity() + self.free.capacity() + self.in_use.capacity()) * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_come_back_and_pages_are_reused() {
        let mut m = SlotMap::default();
        assert_eq!(m.get(0), NONE);
        assert_eq!(m.get(u32::MAX - 1), NONE);
        let cells = [5u32, 6, 1023, 1024, 70_000, 3 * PAGE as u32 + 7];
        for (s, &c) in cells.iter().enumerate() {
            m.set(c, s as u32);
        }
        for (s, &c) in cells.iter().enumerate() {
            assert_eq!(m.get(c), s as u32);
        }
        assert_eq!(m.get(7), NONE, "a neighbour on a page in use");
        assert_eq!(m.get(2 * PAGE as u32), NONE, "a page never used");
        let pages = m.entries.len() / PAGE;
        assert_eq!(pages, 4, "pages 0, 1, 3 and 68");
        m.clear(cells.into_iter());
        // A unit's 8 slots at once, on a page of its own and on one in use.
        m.set(16 * PAGE as u32 + 3, 99);
        m.set_unit(16 * PAGE as u32 + 8, 40);
        m.set_unit(40 * PAGE as u32 + 1016, 50);
        for k in 0..8 {
            assert_eq!(m.get(16 * PAGE as u32 + 8 + k), 40 + k);
            assert_eq!(m.get(40 * PAGE as u32 + 1016 + k), 50 + k);
        }
        assert_eq!(m.unit(16 * PAGE as u32 + 8), Some(&[40, 41, 42, 43, 44, 45, 46, 47]));
        assert_eq!(m.unit(16 * PAGE as u32), Some(&[NONE, NONE, NONE, 99, NONE, NONE, NONE, NONE]));
        assert_eq!(m.unit(17 * PAGE as u32), None, "a page not in use");
        assert_eq!(m.get(16 * PAGE as u32 + 3), 99);
        assert_eq!(m.get(16 * PAGE as u32 + 16), NONE);
        assert_eq!(m.get(41 * PAGE as u32), NONE);
        let given: Vec<u32> =
            (0..8).map(|k| 16 * PAGE as u32 + 8 + k).chain([16 * PAGE as u32 + 3]).chain((0..8).map(|k| 40 * PAGE as u32 + 1016 + k)).collect();
        m.clear(given.into_iter());
        for &c in &cells {
            assert_eq!(m.get(c), NONE);
        }
        // The next stroke's pages come from the free list.
        for (s, c) in (10_000..10_000 + 4 * PAGE as u32).step_by(PAGE).enumerate() {
            m.set(c, s as u32);
        }
        assert_eq!(m.entries.len() / PAGE, pages, "no new page while free ones remain");
        assert_eq!(m.get(10_000 + PAGE as u32), 1);
        assert_eq!(m.get(5), NONE, "an old page's entry does not come back");
    }

    #[test]
    fn pages_filled_densely_are_reset_whole_and_come_back_empty() {
        let mut m = SlotMap::default();
        // Two pages nearly full and one with a single slot: dense enough
        // for the whole-page reset.
        let cells: Vec<u32> = (0..2 * PAGE as u32 - 3).chain([5 * PAGE as u32 + 9]).collect();
        for (s, &c) in cells.iter().enumerate() {
            m.set(c, s as u32);
        }
        assert!(cells.len() >= m.in_use.len() * (PAGE / DENSE), "the dense path is taken");
        m.clear(cells.iter().copied());
        assert!(m.entries.iter().all(|&e| e == NONE), "every entry reset");
        for &c in &cells {
            assert_eq!(m.get(c), NONE);
        }
        // A sparse stroke next: one slot a page, reset one by one, on the
        // pages the dense one gave back.
        let sparse = [7u32, PAGE as u32 + 7, 9 * PAGE as u32 + 7];
        for (s, &c) in sparse.iter().enumerate() {
            m.set(c, s as u32);
        }
        assert_eq!(m.entries.len() / PAGE, 3, "pages reused");
        assert_eq!(m.get(9 * PAGE as u32 + 7), 2);
        assert_eq!(m.get(9 * PAGE as u32 + 8), NONE);
        m.clear(sparse.into_iter());
        assert!(m.entries.iter().all(|&e| e == NONE), "every entry reset");
    }
}

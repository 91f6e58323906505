//! The octree's pools and the allocator (spec 2). Reference twin:
//! reference/octopaint_ref/tree.py (pools, allocator); both must produce
//! identical indices.
//!
//! One pool per field, structure of arrays (spec 2.2): cell `c` is entry
//! `c` of each of five vectors, 16 bytes a cell in all. A [`CellRecord`]
//! holds one cell's five fields together where they travel as one (the
//! undo journal, a history step); the GPU's cell is another layout
//! (docs/buffer-layouts.md).
//!
//! ```text
//!  pool         element     bytes a cell
//!  parent       u32         4
//!  first_child  u32         4
//!  depth        u8          1    (FREE = 255)
//!  rgb          [u8; 3]     3
//!  sigma        f32         4
//! ```
//!
//! Every pool is exactly `n_used` long: the used length of spec 2.3, so
//! cells at or past it are free by construction. Origins are not stored: a
//! cell's origin follows from its parent chain ([`Tree::origin`]).
//!
//! The tree's writes tell two observers of change, kept here beside the
//! pools: the undo journal ([`journal`]) saves a cell's old record before
//! its first write in a stroke, and the change log ([`changes`]) marks the
//! cell's block dirty and records topology changes for g3. The writes
//! through this module's methods do both, and the pools are private to
//! the crate: painting (octopaint-paint) writes through them. One writer
//! does neither itself: [`InPlaceValues`] ([`in_place`]), through which
//! the paint pass's runs write on several threads, in place, the colour
//! and density of leaves the stroke has journalled already; they hand back
//! their blocks and the leaves' first writes, which the pass marks
//! ([`Tree::mark_block_written`]) and writes ([`Tree::set_value`]) in
//! order on one thread.

pub(crate) mod changes;
pub mod in_place;
pub(crate) mod journal;
mod values;

pub use in_place::InPlaceValues;

use std::collections::BTreeSet;

use changes::Changes;
use journal::Journal;

use crate::lattice::Lattice;
use crate::pager::{Pager, spare};
use octopaint_model::Canvas;

/// "No cell".
pub const NONE: u32 = u32::MAX;
/// `depth` of a free cell.
pub const FREE: u8 = 255;
/// Cells per allocation unit.
pub const UNIT: u32 = 8;

/// One cell's 16 bytes, as the pools hold them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellRecord {
    pub parent: u32,
    pub first_child: u32,
    pub depth: u8,
    pub rgb: [u8; 3],
    pub sigma: f32,
}

impl CellRecord {
    pub const FREE: CellRecord = CellRecord { parent: NONE, first_child: NONE, depth: FREE, rgb: [0; 3], sigma: 0.0 };

    /// Equal bit for bit (sigma compared by bits, so -0.0 != 0.0).
    pub fn same_bits(&self, o: &CellRecord) -> bool {
        self.parent == o.parent && self.first_child == o.first_child && self.depth == o.depth && self.rgb == o.rgb && self.sigma.to_bits() == o.sigma.to_bits()
    }
}

/// Why a unit could not be allocated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The trace's cell budget (spec 2.4).
    Capacity,
    /// The machine could not give the pools more memory.
    Memory,
}

impl Refusal {
    /// The warning a refused refinement gives, once per stroke or import
    /// (spec 2.4; `line` the event's line, `tree` the refusing tree).
    pub fn warning(self, line: usize, tree: &Tree) -> String {
        match self {
            Refusal::Capacity => {
                format!("line {line}: the cell budget of {} cells is exhausted: refinement refused, painting goes on at the resolution reached", tree.capacity)
            }
            Refusal::Memory => format!(
                "line {line}: the machine has no memory for more than {} cells: refinement refused, painting goes on at the resolution reached",
                tree.n_used()
            ),
        }
    }
}

/// Pool growths of at least this many cells (4 MiB of the pools) have
/// their new pages mapped in by the pager ([`crate::pager`]).
const PAGER_CELLS: usize = 1 << 18;

/// A root array of octrees with pooled cells.
#[derive(Clone)]
pub struct Tree {
    /// First, so that it is dropped (waiting for its job) before the pools.
    pub(crate) pager: Pager,
    pub lat: Lattice,
    /// The cell budget: `n_used + 8 <= capacity` after any allocation.
    pub capacity: u32,
    /// The five pools: private to the crate, whose writes keep the undo
    /// journal and the change log; read elsewhere through [`Tree::parent`]
    /// and its siblings.
    pub(crate) parent: Vec<u32>,
    pub(crate) first_child: Vec<u32>,
    pub(crate) depth: Vec<u8>,
    pub(crate) rgb: Vec<[u8; 3]>,
    pub(crate) sigma: Vec<f32>,
    /// Free units below the used length (first cells), lowest first.
    pub(crate) free_units: BTreeSet<u32>,
    pub(crate) changes: Changes,
    pub(crate) journal: Option<Journal>,
    /// The last journal's vectors, empty, for the next stroke's.
    pub(crate) spare_journal: Journal,
    /// Cells whose values were written since the interior values were last
    /// brought up to date, and the per-depth lists that update climbs with,
    /// kept empty between updates (spec 4.4, [`crate::prefilter`]).
    pub(crate) prefilter_due: Vec<u32>,
    pub(crate) prefilter_levels: Vec<Vec<u32>>,
}

impl Tree {
    pub fn new(canvas: &Canvas) -> Self {
        let lat = Lattice::new(canvas);
        let p = lat.padded as usize;
        let mut t = Tree {
            pager: Pager::default(),
            capacity: canvas.capacity,
            parent: vec![NONE; p],
            first_child: vec![NONE; p],
            depth: vec![FREE; p],
            rgb: vec![[0; 3]; p],
            sigma: vec![0.0; p],
            free_units: BTreeSet::new(),
            changes: Changes::new(canvas.capacity),
            journal: None,
            spare_journal: Journal::default(),
            prefilter_due: Vec::new(),
            prefilter_levels: Vec::new(),
            lat,
        };
        for r in 0..t.lat.n_roots as usize {
            t.depth[r] = 0;
        }
        t
    }

    /// Each cell's parent (NONE for a root or a free cell), `n_used` long.
    #[inline]
    pub fn parent(&self) -> &[u32] {
        &self.parent
    }

    /// Each cell's first child (NONE for a leaf or a free cell).
    #[inline]
    pub fn first_child(&self) -> &[u32] {
        &self.first_child
    }

    /// Each cell's depth (FREE for a free cell).
    #[inline]
    pub fn depth(&self) -> &[u8] {
        &self.depth
    }

    /// Each cell's stored colour (spec 5).
    #[inline]
    pub fn rgb(&self) -> &[[u8; 3]] {
        &self.rgb
    }

    /// Each cell's stored density (spec 5).
    #[inline]
    pub fn sigma(&self) -> &[f32] {
        &self.sigma
    }

    /// The cells the pools have room for before they grow again.
    pub fn pool_capacity(&self) -> usize {
        self.parent.capacity()
    }

    /// Point cell `c` at `parent` without any check, leaving a tree that
    /// is not valid: for the tests of the readers that must survive one
    /// (a half-finished upload: the ray casters skip such cells alike).
    #[doc(hidden)]
    pub fn break_parent_link(&mut self, c: u32, parent: u32) {
        self.touch(c);
        self.parent[c as usize] = parent;
    }

    /// A tree with this one's records and lattice and nothing else: no
    /// free-unit list, journal or change marks. What a dump reads (spec
    /// 11.1), for a thread that writes one while painting goes on, and what
    /// [`crate::history::History::full_steps`] undoes steps on; not a tree
    /// to paint on.
    pub fn records_copy(&self) -> Tree {
        Tree {
            pager: Pager::default(),
            lat: self.lat.clone(),
            capacity: self.capacity,
            parent: self.parent.clone(),
            first_child: self.first_child.clone(),
            depth: self.depth.clone(),
            rgb: self.rgb.clone(),
            sigma: self.sigma.clone(),
            free_units: BTreeSet::new(),
            changes: Changes::new(0),
            journal: None,
            spare_journal: Journal::default(),
            prefilter_due: Vec::new(),
            prefilter_levels: Vec::new(),
        }
    }

    /// The box (canvas units) around every painted leaf, or the whole
    /// canvas when nothing is painted: what a view frames first.
    pub fn painted_bounds(&self) -> (glam::DVec3, glam::DVec3) {
        let mut lo = glam::DVec3::splat(f64::INFINITY);
        let mut hi = glam::DVec3::splat(f64::NEG_INFINITY);
        for c in 0..self.n_used() {
            let i = c as usize;
            if self.depth[i] != FREE && self.first_child[i] == NONE && self.sigma[i] > 0.0 {
                let s = self.lat.size_canvas[self.depth[i] as usize];
                let o = glam::DVec3::from_array(self.origin(c).map(|v| f64::from(v) * self.lat.lattice_unit));
                lo = lo.min(o);
                hi = hi.max(o + glam::DVec3::splat(s));
            }
        }
        if !lo.is_finite() {
            lo = glam::DVec3::ZERO;
            hi = glam::DVec3::from_array(self.lat.roots.map(|r| f64::from(r) * self.lat.root_size));
        }
        (lo, hi)
    }

    /// The used length N (spec 2.3).
    #[inline]
    pub fn n_used(&self) -> u32 {
        self.parent.len() as u32
    }

    #[inline]
    pub fn is_leaf(&self, c: u32) -> bool {
        self.first_child[c as usize] == NONE
    }

    #[inline]
    pub fn is_live(&self, c: u32) -> bool {
        self.depth[c as usize] != FREE
    }

    pub fn record(&self, c: u32) -> CellRecord {
        let i = c as usize;
        if i >= self.parent.len() {
            return CellRecord::FREE;
        }
        CellRecord { parent: self.parent[i], first_child: self.first_child[i], depth: self.depth[i], rgb: self.rgb[i], sigma: self.sigma[i] }
    }

    /// Units still available under the budget (spec 2.4).
    pub fn available_units(&self) -> u64 {
        self.free_units.len() as u64 + u64::from(self.capacity - self.n_used()) / u64::from(UNIT)
    }

    /// Lattice origin of a live cell, from its parent chain (spec 1.2).
    pub fn origin(&self, c: u32) -> [u32; 3] {
        let mut o = [0u32; 3];
        let mut x = c;
        loop {
            let d = u32::from(self.depth[x as usize]);
            if d == 0 {
                let r = self.lat.root_origin(x);
                return [o[0] + r[0], o[1] + r[1], o[2] + r[2]];
            }
            let edge = self.lat.edge_lattice(d);
            for (a, v) in o.iter_mut().enumerate() {
                *v += ((x >> a) & 1) * edge;
            }
            x = self.parent[x as usize];
        }
    }

    /// Origin of child octant `k` of a cell with origin `o` and depth `d`.
    #[inline]
    pub fn child_origin(&self, o: [u32; 3], d: u32, k: u32) -> [u32; 3] {
        let half = self.lat.edge_lattice(d + 1);
        [o[0] + (k & 1) * half, o[1] + ((k >> 1) & 1) * half, o[2] + ((k >> 2) & 1) * half]
    }

    /// Centre of a live cell in canvas units.
    pub fn centre(&self, c: u32) -> glam::DVec3 {
        self.lat.centre(self.origin(c), u32::from(self.depth[c as usize]))
    }

    /// The cell containing lattice point `q` of the greatest depth `<= m`
    /// (spec 1.3: a point on a boundary belongs to the higher cell).
    pub fn cell_at(&self, q: [u32; 3], m: u32) -> u32 {
        let d0 = self.lat.max_depth;
        let mut c = self.lat.root_index(q.map(|v| v >> d0));
        let mut o = self.lat.root_origin(c);
        loop {
            let fc = self.first_child[c as usize];
            let d = u32::from(self.depth[c as usize]);
            if fc == NONE || d >= m {
                return c;
            }
            let half = self.lat.edge_lattice(d + 1);
            let mut k = 0;
            for a in 0..3 {
                if q[a] - o[a] >= half {
                    k |= 1 << a;
                }
            }
            o = self.child_origin(o, d, k);
            c = fc + k;
        }
    }

    /// The leaf containing a canvas point, or None outside the canvas.
    pub fn leaf_at(&self, p: [f64; 3]) -> Option<u32> {
        self.lat.lattice_point(p).map(|q| self.cell_at(q, self.lat.max_depth))
    }

    // ---------------------------------------------------------- writes

    /// Tell the journal and the change log that `c` is about to change.
    #[inline]
    pub(crate) fn touch(&mut self, c: u32) {
        if let Some(j) = self.journal.as_mut()
            && j.needs_save(c)
        {
            let rec = if (c as usize) < self.parent.len() {
                CellRecord {
                    parent: self.parent[c as usize],
                    first_child: self.first_child[c as usize],
                    depth: self.depth[c as usize],
                    rgb: self.rgb[c as usize],
                    sigma: self.sigma[c as usize],
                }
            } else {
                CellRecord::FREE
            };
            j.save(c, rec);
        }
        self.changes.mark_block(c);
    }

    /// Overwrite a whole cell (undo/redo).
    pub(crate) fn write_record(&mut self, c: u32, r: CellRecord) {
        self.touch(c);
        self.put_record(c, &r);
    }

    /// Write `c`'s record as it is, with no journal entry or change mark
    /// (a copy of the records that history.rs undoes steps on).
    #[inline]
    pub(crate) fn put_record(&mut self, c: u32, r: &CellRecord) {
        let i = c as usize;
        self.parent[i] = r.parent;
        self.first_child[i] = r.first_child;
        self.depth[i] = r.depth;
        self.rgb[i] = r.rgb;
        self.sigma[i] = r.sigma;
    }

    /// Allocate one unit (spec 2.3): the lowest free unit, else a new unit
    /// at the end of the pools. Refused at the budget, or when the machine
    /// has no memory for bigger pools; nothing changes then.
    pub fn allocate_unit(&mut self) -> Result<u32, Refusal> {
        if let Some(u) = self.free_units.pop_first() {
            return Ok(u);
        }
        let n = self.n_used();
        if u64::from(n) + u64::from(UNIT) > u64::from(self.capacity) {
            return Err(Refusal::Capacity);
        }
        // The new cells are free, as they were before: nothing to journal
        // or publish until they are written (make_children).
        self.grow_by_unit().map_err(|_| Refusal::Memory)?;
        Ok(n)
    }

    /// The cells every pool holds without reallocating.
    fn pools_capacity(&self) -> usize {
        let caps = [self.parent.capacity(), self.first_child.capacity(), self.depth.capacity(), self.rgb.capacity(), self.sigma.capacity()];
        caps.into_iter().min().unwrap_or(0)
    }

    /// Grow by one unit. A full pool grows by a quarter of its length (at
    /// least a unit), not Vec's doubling, so the pools never allocate more
    /// than 1.25 times the cells in use (big reallocations move pages
    /// rather than copy them).
    fn grow_by_unit(&mut self) -> Result<(), std::collections::TryReserveError> {
        let u = UNIT as usize;
        if self.parent.len() + u > self.pools_capacity() {
            let extra = (self.parent.len() / 4).max(u);
            self.pager.wait();
            self.parent.try_reserve_exact(extra)?;
            self.first_child.try_reserve_exact(extra)?;
            self.depth.try_reserve_exact(extra)?;
            self.rgb.try_reserve_exact(extra)?;
            self.sigma.try_reserve_exact(extra)?;
            // New capacity worth a thread's start (tens of microseconds) is
            // mapped in ahead when passes may use more than one thread.
            if octopaint_platform::memory::POPULATES && crate::par::threads() > 1 && extra >= PAGER_CELLS {
                let ranges = vec![spare(&self.parent), spare(&self.first_child), spare(&self.depth), spare(&self.rgb), spare(&self.sigma)];
                self.pager.populate(ranges);
            }
        }
        self.parent.extend_from_slice(&[NONE; UNIT as usize]);
        self.first_child.extend_from_slice(&[NONE; UNIT as usize]);
        self.depth.extend_from_slice(&[FREE; UNIT as usize]);
        self.rgb.extend_from_slice(&[[0; 3]; UNIT as usize]);
        self.sigma.extend_from_slice(&[0.0; UNIT as usize]);
        Ok(())
    }

    /// Make the 8 children of leaf `l` in `unit` (spec 4.1): values copied
    /// from `l`, which keeps its own (unused) values.
    pub fn make_children(&mut self, l: u32, unit: u32) {
        let li = l as usize;
        let d = self.depth[li] + 1;
        let (rgb, sigma) = (self.rgb[li], self.sigma[li]);
        if self.journal.as_ref().is_none_or(|j| j.unit_is_new(unit)) {
            // Nothing to save, and a unit lies in one dirty block (blocks
            // hold a whole number of units).
            const { assert!(changes::BLOCK_CELLS.is_multiple_of(UNIT)) };
            self.changes.mark_block(unit);
        } else {
            for c in unit..unit + UNIT {
                self.touch(c);
            }
        }
        // Whole units as arrays of 8: stores of known size, where a slice's
        // fill of a length the compiler cannot see calls memset.
        fn unit_of<T>(v: &mut [T], unit: u32) -> &mut [T; UNIT as usize] {
            let at = unit as usize;
            (&mut v[at..at + UNIT as usize]).try_into().expect("a unit is 8 cells")
        }
        *unit_of(&mut self.parent, unit) = [l; UNIT as usize];
        *unit_of(&mut self.first_child, unit) = [NONE; UNIT as usize];
        *unit_of(&mut self.depth, unit) = [d; UNIT as usize];
        *unit_of(&mut self.rgb, unit) = [rgb; UNIT as usize];
        *unit_of(&mut self.sigma, unit) = [sigma; UNIT as usize];
        self.touch(l);
        self.first_child[li] = unit;
        self.changes.topology(l, unit);
    }

    /// Collapse the 8 leaf children of `p` into it (spec 4.3): `p` takes
    /// child octant 0's values and the unit is freed. The caller has checked
    /// that the children are leaves and that balance allows it.
    pub fn coarsen(&mut self, p: u32) {
        let pi = p as usize;
        let unit = self.first_child[pi];
        let (rgb, sigma) = (self.rgb[unit as usize], self.sigma[unit as usize]);
        self.touch(p);
        self.rgb[pi] = rgb;
        self.sigma[pi] = sigma;
        self.first_child[pi] = NONE;
        self.changes.topology(p, unit);
        self.free_unit(unit);
    }

    /// Mark a unit's cells free and give trailing free units back (spec 2.3).
    fn free_unit(&mut self, unit: u32) {
        for c in unit..unit + UNIT {
            self.write_record(c, CellRecord::FREE);
        }
        self.free_units.insert(unit);
        self.trim();
    }

    /// While the last unit below the used length is free, shorten it.
    fn trim(&mut self) {
        let mut n = self.n_used();
        while n > self.lat.padded && self.free_units.last() == Some(&(n - UNIT)) {
            self.free_units.pop_last();
            n -= UNIT;
        }
        self.set_used_length(n);
    }

    /// Resize the pools to `n` cells (new cells free). Shrinking only drops
    /// cells that are free; growing is used by undo and redo, which restore
    /// a length the pools had before.
    pub(crate) fn set_used_length(&mut self, n: u32) {
        let n = n as usize;
        if n > self.parent.len() {
            let extra = n - self.parent.len();
            if n > self.pools_capacity() {
                self.pager.wait(); // the pools move
            }
            self.parent.reserve_exact(extra);
            self.first_child.reserve_exact(extra);
            self.depth.reserve_exact(extra);
            self.rgb.reserve_exact(extra);
            self.sigma.reserve_exact(extra);
        }
        self.parent.resize(n, NONE);
        self.first_child.resize(n, NONE);
        self.depth.resize(n, FREE);
        self.rgb.resize(n, [0; 3]);
        self.sigma.resize(n, 0.0);
        // Give memory back when the pools hold over 1.25 times what is in
        // use (cleaning, undo), keeping an eighth to grow into.
        if self.parent.capacity() > n + n / 4 + 4096 {
            let keep = n + n / 8;
            self.pager.wait(); // the pools move
            self.parent.shrink_to(keep);
            self.first_child.shrink_to(keep);
            self.depth.shrink_to(keep);
            self.rgb.shrink_to(keep);
            self.sigma.shrink_to(keep);
        }
    }

    /// Rebuild the free-unit list from the depth pool (after undo/redo).
    pub(crate) fn rebuild_free_units(&mut self) {
        self.free_units = (self.lat.padded..self.n_used()).step_by(UNIT as usize).filter(|&u| self.depth[u as usize] == FREE).collect();
    }

    /// Allocator invariants (tests): the free list is exactly the free
    /// units, no unit is partly free, and the last unit is in use.
    pub fn check_allocator(&self) -> Vec<String> {
        let mut problems = Vec::new();
        let expect: BTreeSet<u32> = (self.lat.padded..self.n_used()).step_by(UNIT as usize).filter(|&u| self.depth[u as usize] == FREE).collect();
        if expect != self.free_units {
            problems.push("free-unit list differs from the free units in the pools".to_string());
        }
        for u in (self.lat.padded..self.n_used()).step_by(UNIT as usize) {
            let free = (u..u + UNIT).filter(|&c| self.depth[c as usize] == FREE).count();
            if free != 0 && free != UNIT as usize {
                problems.push(format!("unit {u} is partly free"));
            }
        }
        if self.n_used() > self.lat.padded && self.depth[(self.n_used() - UNIT) as usize] == FREE {
            problems.push("the last unit is free but the used length was not trimmed".to_string());
        }
        problems
    }

    /// Bytes the pools hold per used cell (the core is 16).
    pub const BYTES_PER_CELL: usize = 4 + 4 + 1 + 3 + 4;

    /// Bytes allocated by the pools (capacity of the vectors, not length).
    pub fn pool_bytes_allocated(&self) -> usize {
        self.parent.capacity() * 4 + self.first_child.capacity() * 4 + self.depth.capacity() + self.rgb.capacity() * 3 + self.sigma.capacity() * 4
    }
}

/// Lattice origin of every cell (NONE for free cells), parents first.
pub fn origins(tree: &Tree) -> Vec<[u32; 3]> {
    let n = tree.n_used() as usize;
    let mut o = vec![[NONE; 3]; n];
    let mut stack: Vec<u32> = (0..tree.lat.n_roots).collect();
    for &r in &stack {
        o[r as usize] = tree.lat.root_origin(r);
    }
    while let Some(c) = stack.pop() {
        let fc = tree.first_child[c as usize];
        if fc == NONE {
            continue;
        }
        let d = u32::from(tree.depth[c as usize]);
        for k in 0..8 {
            o[(fc + k) as usize] = tree.child_origin(o[c as usize], d, k);
            stack.push(fc + k);
        }
    }
    debug_assert!((0..n).all(|c| (tree.depth[c] == FREE) == (o[c][0] == NONE)));
    o
}

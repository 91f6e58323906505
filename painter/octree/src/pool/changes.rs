//! The change log the pools' writes keep (mod.rs): the blocks written and the
//! topology changes since the last publication, which dirty.rs turns into
//! dirty blocks, dirty cells and the neighbour mask (spec 3.4, 3.5).

/// Cells per block: the staging granule.
pub const BLOCK_CELLS: u32 = 65536;
#[derive(Clone)]
pub(crate) struct Changes {
    /// Everything is dirty: a new consumer (a GPU) has seen nothing yet,
    /// or nobody has taken a publication yet. Nothing is recorded cell by
    /// cell meanwhile.
    pub(crate) everything: bool,
    /// One bit per block: written since the last publication.
    pub(crate) blocks: Vec<u64>,
    pub(crate) any_block: bool,
    /// Cell `topo_cells[i]` gained or lost the children in unit
    /// `topo_units[i]`.
    pub(crate) topo_cells: Vec<u32>,
    pub(crate) topo_units: Vec<u32>,
    /// Cells whose own g3 changed (a new or freed unit's cells are in
    /// `topo_units`).
    pub(crate) direct: Vec<u32>,
    /// Groups (a unit, or eight roots: the index with its low three bits
    /// cleared) holding a cell whose value changed, for the shading
    /// vectors (spec 3.4 rule 3); repeats allowed.
    pub(crate) values: Vec<u32>,
}

impl Changes {
    pub(crate) fn new(capacity: u32) -> Self {
        let n_blocks = capacity.div_ceil(BLOCK_CELLS) as usize;
        Changes {
            everything: true,
            blocks: vec![0; n_blocks.div_ceil(64)],
            any_block: false,
            topo_cells: Vec::new(),
            topo_units: Vec::new(),
            direct: Vec::new(),
            values: Vec::new(),
        }
    }

    #[inline]
    pub(crate) fn mark_block(&mut self, c: u32) {
        let b = (c / BLOCK_CELLS) as usize;
        self.blocks[b / 64] |= 1 << (b % 64);
        self.any_block = true;
    }

    /// Cell `x` gained or lost the children in `unit`.
    #[inline]
    pub(crate) fn topology(&mut self, x: u32, unit: u32) {
        if self.recording() {
            self.topo_cells.push(x);
            self.topo_units.push(unit);
        }
    }

    #[inline]
    pub(crate) fn direct(&mut self, c: u32) {
        if self.recording() {
            self.direct.push(c);
        }
    }

    /// A value of a cell of group `c & !7` changed (spec 3.4 rule 3).
    #[inline]
    pub(crate) fn value(&mut self, c: u32) {
        if self.recording() && self.values.last() != Some(&(c & !7)) {
            self.values.push(c & !7);
        }
    }

    /// Whether changes are recorded cell by cell: not while the next
    /// publication covers everything anyway. A tree starts that way (its
    /// first publication covers everything: nobody has seen it yet), so a
    /// tree nobody publishes (a replay without a renderer, an export, a
    /// benchmark) keeps no lists at all, where it used to keep 8 bytes for
    /// every unit it ever made.
    #[inline]
    fn recording(&self) -> bool {
        !self.everything
    }
}

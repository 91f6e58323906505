//! The pools on the GPU (docs/spec.md 2.2, docs/buffer-layouts.md): one
//! 16-byte [`GpuCell`] per cell and a 16-byte row of g3 and the shading
//! vector (spec 6.1) per cell, in pages of `2^k`
//! cells, one storage binding per page, so that capacity is not capped by
//! the largest binding (128 MiB on lavapipe: 2^23 cells). The WGSL twin is
//! shaders/shared/pools.wgsl.
//!
//! Uploads go by block (65,536 cells): [`stage_block`] copies a block out of
//! the CPU pools into the GPU layout (the staging copy the real-time
//! pipeline makes on its staging thread), and [`GpuPools::upload`] writes
//! it; the whole pool is never copied.

use bytemuck::{Pod, Zeroable};
use octopaint_tree::dirty::BLOCK_CELLS;
use octopaint_tree::pool::{FREE, NONE, Tree};

use crate::context::{Gpu, GpuError};

/// Pages per pool: one binding each (shared/pools.wgsl PAGES).
pub const PAGES: usize = 4;

/// The fewest cells a page is allocated with (16 blocks, 32 MiB with its
/// rows).
pub const FIRST_PAGE_CELLS: u64 = 1 << 20;

/// One cell's row beside the cells, 16 bytes (shared/pools.wgsl `Row`): g3
/// and the stored shading vector's word (spec 3.3, 6.1). The g3 pass
/// writes it; the API hands rows over as `[u32; 4]`, the same bytes.
///
/// ```text
///  byte 0          4          8          12         16
///       +----------+----------+----------+----------+
///       |  g3[x]   |  g3[y]   |  g3[z]   |  shade   |
///       +----------+----------+----------+----------+
/// ```
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct GpuRow {
    pub g3: [u32; 3],
    pub shade: u32,
}

/// Bytes of one [`GpuRow`].
pub const ROW_BYTES: u64 = std::mem::size_of::<GpuRow>() as u64;

/// The row of a cell no pass has written: g3 NONE, the zero vector.
fn fresh_row() -> [u8; 16] {
    bytemuck::cast(GpuRow { g3: [NONE; 3], shade: octopaint_tree::normals::ZERO })
}

/// One cell as the GPU holds it, 16 bytes (shared/pools.wgsl `Cell`):
///
/// ```text
///  byte 0          4          8                   12         16
///       +----------+----------+----+----+----+----+----------+
///       |  parent  |first_chld| r  | g  | b  |dpth|  sigma   |
///       +----------+----------+----+----+----+----+----------+
/// ```
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct GpuCell {
    pub parent: u32,
    pub first_child: u32,
    /// r | g << 8 | b << 16 | depth << 24
    pub rgbd: u32,
    pub sigma: f32,
}

impl GpuCell {
    pub const FREE: GpuCell = GpuCell { parent: NONE, first_child: NONE, rgbd: (FREE as u32) << 24, sigma: 0.0 };
}

/// Cells copied out of the CPU pools in the GPU layout, ready to upload:
/// one block (65,536 cells) in the pipeline, other sizes in benchmarks.
pub struct StagedBlock {
    pub first: u64,
    pub cells: Vec<GpuCell>,
}

/// Copy block `block` of the tree into the GPU layout; cells past the used
/// length are free.
pub fn stage_block(tree: &Tree, block: u32) -> StagedBlock {
    stage_range(tree, u64::from(block) * u64::from(BLOCK_CELLS), BLOCK_CELLS as usize)
}

/// Copy `len` cells from `first` into the GPU layout (free past the used
/// length).
pub fn stage_range(tree: &Tree, first: u64, len: usize) -> StagedBlock {
    let mut cells = Vec::with_capacity(len);
    stage_into(tree, first, len, &mut cells);
    StagedBlock { first, cells }
}

/// [`stage_range`] into a reused buffer (the staging thread's pool).
pub fn stage_into(tree: &Tree, first: u64, len: usize, cells: &mut Vec<GpuCell>) {
    cells.clear();
    let start = first as usize;
    let n = tree.n_used() as usize;
    let end = (start + len).min(n.max(start));
    for c in start..end {
        let [r, g, b] = tree.rgb()[c];
        cells.push(GpuCell {
            parent: tree.parent()[c],
            first_child: tree.first_child()[c],
            rgbd: u32::from(r) | u32::from(g) << 8 | u32::from(b) << 16 | u32::from(tree.depth()[c]) << 24,
            sigma: tree.sigma()[c],
        });
    }
    cells.resize(len, GpuCell::FREE);
}

pub struct GpuPools {
    /// Cells per page, `1 << page_shift`.
    pub page_shift: u32,
    cells: Vec<wgpu::Buffer>,
    g3: Vec<wgpu::Buffer>,
    /// Cells each allocated page holds: every page but the last is whole;
    /// the last grows by powers of two from [`FIRST_PAGE_CELLS`], so a
    /// small painting does not pay for a whole page (2^26 cells, 1.9 GB,
    /// on a GPU that binds 2 GiB).
    held: Vec<u64>,
    /// Stand-ins for pages not allocated yet: one for the read-only cell
    /// slots, one per g3 slot (a buffer bound twice read-write in one
    /// dispatch would be a usage conflict).
    dummy_cells: wgpu::Buffer,
    dummy_g3: Vec<wgpu::Buffer>,
    pub layout_cells: wgpu::BindGroupLayout,
    pub layout_g3_rw: wgpu::BindGroupLayout,
    pub layout_g3_ro: wgpu::BindGroupLayout,
    pub group_cells: wgpu::BindGroup,
    pub group_g3_rw: wgpu::BindGroup,
    pub group_g3_ro: wgpu::BindGroup,
}

fn storage_layout(gpu: &Gpu, label: &str, read_only: bool) -> wgpu::BindGroupLayout {
    let entries: Vec<wgpu::BindGroupLayoutEntry> = (0..PAGES as u32)
        .map(|binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only }, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        })
        .collect();
    gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries })
}

/// A buffer whose bytes from `from` on repeat `pattern` (FREE cells, NONE
/// g3 entries; `from` a multiple of the pattern's length). Bytes before
/// `from` are left zero: a page that replaces a smaller one gets them from
/// the GPU's copy of it, and the CPU need not fill what is overwritten.
fn filled_buffer(gpu: &Gpu, label: &str, size: u64, pattern: &[u8], from: u64) -> wgpu::Buffer {
    let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: true,
    });
    {
        // A megabyte of the pattern, copied in as often as the buffer needs.
        let reps = (1 << 20) / pattern.len();
        let block: Vec<u8> = pattern.iter().copied().cycle().take(reps * pattern.len()).collect();
        let mut view = buf.get_mapped_range_mut(..).expect("a buffer mapped at creation");
        let len = view.len();
        let mut at = from as usize;
        while at < len {
            let n = block.len().min(len - at);
            view.slice(at..at + n).copy_from_slice(&block[..n]);
            at += n;
        }
    }
    buf.unmap();
    buf
}

impl GpuPools {
    pub fn new(gpu: &Gpu) -> Result<GpuPools, GpuError> {
        let limit = gpu.limits.max_storage_buffer_binding_size.min(gpu.limits.max_buffer_size);
        // The largest power of two of 16-byte cells one binding holds.
        let cells_fit = limit / std::mem::size_of::<GpuCell>() as u64;
        if cells_fit < u64::from(BLOCK_CELLS) {
            return Err(GpuError::BindingTooSmall(limit));
        }
        let page_shift = 63 - cells_fit.leading_zeros();
        let page_shift = page_shift.min(28);
        let dummy_cells = filled_buffer(gpu, "unallocated cells page", 16, bytemuck::bytes_of(&GpuCell::FREE), 0);
        let dummy_g3: Vec<wgpu::Buffer> = (0..PAGES).map(|_| filled_buffer(gpu, "unallocated g3 page", ROW_BYTES, &fresh_row(), 0)).collect();
        let layout_cells = storage_layout(gpu, "cells pages", true);
        let layout_g3_rw = storage_layout(gpu, "g3 pages (write)", false);
        let layout_g3_ro = storage_layout(gpu, "g3 pages (read)", true);
        let (group_cells, group_g3_rw, group_g3_ro) = Self::groups(gpu, &[], &[], &dummy_cells, &dummy_g3, &layout_cells, &layout_g3_rw, &layout_g3_ro);
        Ok(GpuPools {
            page_shift,
            cells: Vec::new(),
            g3: Vec::new(),
            held: Vec::new(),
            dummy_cells,
            dummy_g3,
            layout_cells,
            layout_g3_rw,
            layout_g3_ro,
            group_cells,
            group_g3_rw,
            group_g3_ro,
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn groups(
        gpu: &Gpu,
        cells: &[wgpu::Buffer],
        g3: &[wgpu::Buffer],
        dummy_cells: &wgpu::Buffer,
        dummy_g3: &[wgpu::Buffer],
        layout_cells: &wgpu::BindGroupLayout,
        layout_g3_rw: &wgpu::BindGroupLayout,
        layout_g3_ro: &wgpu::BindGroupLayout,
    ) -> (wgpu::BindGroup, wgpu::BindGroup, wgpu::BindGroup) {
        let make = |label: &str, layout: &wgpu::BindGroupLayout, slots: &[&wgpu::Buffer]| {
            let entries: Vec<wgpu::BindGroupEntry> =
                slots.iter().enumerate().map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() }).collect();
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
        };
        let cell_slots: Vec<&wgpu::Buffer> = (0..PAGES).map(|i| cells.get(i).unwrap_or(dummy_cells)).collect();
        let g3_slots: Vec<&wgpu::Buffer> = (0..PAGES).map(|i| g3.get(i).unwrap_or(&dummy_g3[i])).collect();
        (make("cells", layout_cells, &cell_slots), make("g3 (write)", layout_g3_rw, &g3_slots), make("g3 (read)", layout_g3_ro, &g3_slots))
    }

    pub fn page_cells(&self) -> u64 {
        1u64 << self.page_shift
    }

    /// Cells the allocated pages hold (the shaders' `cells_held`: every
    /// page but the last is whole, so they are cells `0..cells_held`).
    pub fn cells_held(&self) -> u64 {
        self.held.iter().sum()
    }

    /// Bytes of GPU memory the allocated pages take (16 bytes of cell and
    /// 16 of row per cell they hold).
    pub fn allocated_bytes(&self) -> u64 {
        self.cells_held() * (16 + ROW_BYTES)
    }

    /// Make sure the pages hold `n` cells: pages are added (every cell
    /// FREE, every g3 entry NONE), and the last page, allocated at a power
    /// of two of cells, is replaced by a larger one holding a copy of it
    /// (made on the GPU, after every upload queued so far); the bind groups
    /// are rebuilt. Returns whether anything was allocated.
    pub fn ensure(&mut self, gpu: &Gpu, n: u64) -> Result<bool, GpuError> {
        let page = self.page_cells();
        let needed = n.div_ceil(page) as usize;
        if needed > PAGES {
            return Err(GpuError::Capacity { cells: n, max: PAGES as u64 * page, pages: PAGES as u32, page });
        }
        if n <= self.cells_held() {
            return Ok(false);
        }
        let mut copies = Vec::new();
        for i in 0..needed {
            // Cells page i must hold: whole pages below the last needed one.
            let want = if i + 1 < needed { page } else { n - i as u64 * page };
            let have = self.held.get(i).copied().unwrap_or(0);
            if want <= have {
                continue;
            }
            let size = want.next_power_of_two().clamp(FIRST_PAGE_CELLS.min(page), page);
            // The first `have` cells come from the GPU's copy of the old page.
            let cells = filled_buffer(gpu, &format!("cells page {i}"), size * 16, bytemuck::bytes_of(&GpuCell::FREE), have * 16);
            let g3 = filled_buffer(gpu, &format!("g3 page {i}"), size * ROW_BYTES, &fresh_row(), have * ROW_BYTES);
            if i < self.cells.len() {
                let old_cells = std::mem::replace(&mut self.cells[i], cells);
                let old_g3 = std::mem::replace(&mut self.g3[i], g3);
                copies.push((i, have, old_cells, old_g3));
                self.held[i] = size;
            } else {
                self.cells.push(cells);
                self.g3.push(g3);
                self.held.push(size);
            }
        }
        if !copies.is_empty() {
            let mut enc = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("grow a page") });
            for (i, have, old_cells, old_g3) in &copies {
                enc.copy_buffer_to_buffer(old_cells, 0, &self.cells[*i], 0, have * 16);
                enc.copy_buffer_to_buffer(old_g3, 0, &self.g3[*i], 0, have * ROW_BYTES);
            }
            gpu.queue.submit([enc.finish()]);
        }
        let (a, b, c) = Self::groups(gpu, &self.cells, &self.g3, &self.dummy_cells, &self.dummy_g3, &self.layout_cells, &self.layout_g3_rw, &self.layout_g3_ro);
        self.group_cells = a;
        self.group_g3_rw = b;
        self.group_g3_ro = c;
        Ok(true)
    }

    /// Write staged cells into their pages.
    pub fn upload(&self, gpu: &Gpu, staged: &StagedBlock) {
        self.upload_cells(gpu, staged.first, &staged.cells);
    }

    /// Write `cells` from cell `first` on, split at page boundaries (the
    /// pages must hold them: [`GpuPools::ensure`]).
    pub fn upload_cells(&self, gpu: &Gpu, first: u64, cells: &[GpuCell]) {
        self.per_page(first, cells.len(), |page, offset, range| {
            gpu.queue.write_buffer(&self.cells[page], offset * 16, bytemuck::cast_slice(&cells[range]));
        });
    }

    /// `n` items from cell `first` on, split at page boundaries: `f(page,
    /// index in the page, range of the items)` per piece.
    fn per_page(&self, first: u64, n: usize, mut f: impl FnMut(usize, u64, std::ops::Range<usize>)) {
        let page_cells = self.page_cells();
        let mut at = 0usize;
        while at < n {
            let c = first + at as u64;
            let offset = c & (page_cells - 1);
            let k = ((page_cells - offset) as usize).min(n - at);
            f((c >> self.page_shift) as usize, offset, at..at + k);
            at += k;
        }
    }

    /// Write rows of g3 and shading vectors from cell `first` on, split at
    /// page boundaries (a document's layers, whose rows the CPU port
    /// computes: spec 6.2).
    pub fn upload_g3(&self, gpu: &Gpu, first: u64, rows: &[[u32; 4]]) {
        self.per_page(first, rows.len(), |page, offset, range| {
            gpu.queue.write_buffer(&self.g3[page], offset * ROW_BYTES, bytemuck::cast_slice(&rows[range]));
        });
    }

    /// The most cells the pages can hold (every page whole).
    pub fn max_cells(&self) -> u64 {
        PAGES as u64 * self.page_cells()
    }

    /// Copy cells and g3 of ranges `(from, to, n)` on the GPU (a layer's
    /// range moved, docs/architecture.md): every source is copied out
    /// before any destination is written, so ranges may overlap one
    /// another. The pages must hold every destination ([`GpuPools::ensure`]).
    pub fn move_ranges(&self, gpu: &Gpu, moves: &[(u64, u64, u64)]) {
        if moves.is_empty() {
            return;
        }
        let mut enc = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("move ranges") });
        let temp = |label: &str, bytes: u64| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(4),
                usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let temps: Vec<(wgpu::Buffer, wgpu::Buffer)> = moves.iter().map(|&(_, _, n)| (temp("moved cells", n * 16), temp("moved g3", n * ROW_BYTES))).collect();
        for (&(from, _, n), (tc, tg)) in moves.iter().zip(&temps) {
            self.per_page(from, n as usize, |page, offset, range| {
                enc.copy_buffer_to_buffer(&self.cells[page], offset * 16, tc, range.start as u64 * 16, range.len() as u64 * 16);
                enc.copy_buffer_to_buffer(&self.g3[page], offset * ROW_BYTES, tg, range.start as u64 * ROW_BYTES, range.len() as u64 * ROW_BYTES);
            });
        }
        for (&(_, to, n), (tc, tg)) in moves.iter().zip(&temps) {
            self.per_page(to, n as usize, |page, offset, range| {
                enc.copy_buffer_to_buffer(tc, range.start as u64 * 16, &self.cells[page], offset * 16, range.len() as u64 * 16);
                enc.copy_buffer_to_buffer(tg, range.start as u64 * ROW_BYTES, &self.g3[page], offset * ROW_BYTES, range.len() as u64 * ROW_BYTES);
            });
        }
        gpu.queue.submit([enc.finish()]);
    }

    /// Cells `0..n` as the GPU holds them (tests).
    pub fn read_cells(&self, gpu: &Gpu, n: u64) -> Result<Vec<GpuCell>, GpuError> {
        let mut out = Vec::with_capacity(n as usize);
        let page = self.page_cells();
        for (i, buf) in self.cells.iter().enumerate() {
            let start = i as u64 * page;
            if start >= n {
                break;
            }
            let bytes = read_buffer(gpu, buf, (n - start).min(self.held[i]) * 16)?;
            out.extend(bytemuck::cast_slice::<u8, GpuCell>(&bytes).iter().copied());
        }
        Ok(out)
    }

    /// g3 of cells `0..n`, read back from the GPU.
    pub fn read_g3(&self, gpu: &Gpu, n: u64) -> Result<Vec<[u32; 3]>, GpuError> {
        Ok(self.read_rows(gpu, n)?.into_iter().map(|r| [r[0], r[1], r[2]]).collect())
    }

    /// The rows (g3 and the shading vector's word) of cells `0..n`, read
    /// back from the GPU.
    pub fn read_rows(&self, gpu: &Gpu, n: u64) -> Result<Vec<[u32; 4]>, GpuError> {
        let mut out = Vec::with_capacity(n as usize);
        let page = self.page_cells();
        for (i, buf) in self.g3.iter().enumerate() {
            let start = i as u64 * page;
            if start >= n {
                break;
            }
            let count = (n - start).min(self.held[i]);
            let bytes = read_buffer(gpu, buf, count * ROW_BYTES)?;
            out.extend(bytemuck::cast_slice::<u8, [u32; 4]>(&bytes).iter().copied());
        }
        Ok(out)
    }
}

/// The first `size` bytes of a buffer, through a mappable copy.
pub fn read_buffer(gpu: &Gpu, buf: &wgpu::Buffer, size: u64) -> Result<Vec<u8>, GpuError> {
    if size == 0 {
        return Ok(Vec::new());
    }
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("read-back"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    read_through(gpu, buf, size, &staging, <[u8]>::to_vec)
}

/// `f` of the first `size` bytes of `buf`, copied into `staging` (a
/// MAP_READ buffer of at least `size` bytes, which a caller may keep for
/// the next read) and mapped; `staging` is unmapped again on every path.
pub fn read_through<T>(gpu: &Gpu, buf: &wgpu::Buffer, size: u64, staging: &wgpu::Buffer, f: impl FnOnce(&[u8]) -> T) -> Result<T, GpuError> {
    let mut enc = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("read-back") });
    enc.copy_buffer_to_buffer(buf, 0, staging, 0, size);
    gpu.queue.submit([enc.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, 0..size, move |r| {
        let _ = tx.send(r);
    });
    gpu.wait();
    rx.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
    let out = staging.get_mapped_range(0..size).map(|view| f(&view)).map_err(|e| GpuError::Readback(e.to_string()));
    staging.unmap();
    out
}

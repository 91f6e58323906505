//! One frame of the GPU pipeline (docs/architecture.md): upload staged
//! blocks, the neighbour mask's g3 pass, ray casting. [`Renderer`] drives
//! it headless: `sync` brings the GPU up to date with the tree (every dirty
//! block staged and uploaded, then the g3 pass over the dirty regions),
//! `render` casts an image, `read_g3` reads g3 back for a tree dump.

use std::time::Instant;

use octopaint_tree::dirty::{BLOCK_CELLS, NeighbourMask};
use octopaint_tree::pool::Tree;
use octopaint_tree::raycast::RayParams;
use octopaint_tree::trace::Camera;

use crate::context::{Backend, Gpu, GpuError};
use crate::g3::G3Pass;
use crate::pools::{GpuPools, stage_block, stage_into};
use crate::raycast::{LayerTableGpu, RayCaster};
use crate::shaders::Precision;

/// What one `sync` or frame did.
#[derive(Clone, Copy, Debug, Default)]
pub struct SyncStats {
    /// Blocks staged and uploaded.
    pub blocks: u32,
    /// Regions the g3 pass recomputed.
    pub regions: u32,
    /// Blocks still waiting after this frame.
    pub pending: u32,
    pub stage_seconds: f64,
    pub gpu_seconds: f64,
}

pub struct Renderer {
    pub gpu: Gpu,
    pub pools: GpuPools,
    pub g3: G3Pass,
    pub ray: RayCaster,
    attached: bool,
    /// Dirty blocks not uploaded yet, and the regions whose g3 must be
    /// recomputed until they all are.
    pending_blocks: Vec<u32>,
    pending_mask: NeighbourMask,
}

impl Renderer {
    /// A renderer follows one tree: the first frame uploads all of it.
    pub fn new(backend: Backend) -> Result<Renderer, GpuError> {
        Renderer::with_gpu(Gpu::open(backend)?)
    }

    /// A renderer on a device opened elsewhere (a window's).
    pub fn with_gpu(gpu: Gpu) -> Result<Renderer, GpuError> {
        let pools = GpuPools::new(&gpu)?;
        let g3 = G3Pass::new(&gpu, &pools);
        let ray = RayCaster::new(&gpu, &pools);
        Ok(Renderer { gpu, pools, g3, ray, attached: false, pending_blocks: Vec::new(), pending_mask: NeighbourMask::default() })
    }

    /// Take a publication someone else took from the tree (a caller that
    /// needs to look at it first) into the pending set.
    pub fn apply(&mut self, publication: &octopaint_tree::dirty::Publication) {
        self.pending_blocks.extend(publication.blocks.iter().copied());
        self.pending_blocks.sort_unstable();
        self.pending_blocks.dedup();
        self.pending_mask.union(&publication.mask);
    }

    /// Take the tree's new changes into the pending set.
    fn collect(&mut self, tree: &mut Tree) {
        if !self.attached {
            tree.mark_everything_dirty();
            self.attached = true;
        }
        let publication = tree.take_publication();
        self.pending_blocks.extend(publication.blocks);
        self.pending_blocks.sort_unstable();
        self.pending_blocks.dedup();
        self.pending_mask.union(&publication.mask);
    }

    /// One frame's GPU work before ray casting (docs/architecture.md):
    /// stage and upload at most `max_blocks` pending blocks (all with None),
    /// then recompute g3 over the pending regions. The regions stay pending
    /// until every block is up, since g3 read from half-uploaded pools may
    /// be stale.
    pub fn upload_frame(&mut self, tree: &mut Tree, max_blocks: Option<usize>) -> Result<SyncStats, GpuError> {
        self.collect(tree);
        let t0 = Instant::now();
        let take = max_blocks.unwrap_or(usize::MAX).min(self.pending_blocks.len());
        let blocks: Vec<u32> = self.pending_blocks.drain(..take).collect();
        let last = blocks.iter().max().map_or(0, |&b| u64::from(b + 1) * u64::from(BLOCK_CELLS));
        self.pools.ensure(&self.gpu, last.max(u64::from(tree.n_used())))?;
        let mut stats = SyncStats::default();
        for &b in &blocks {
            let staged = stage_block(tree, b);
            self.pools.upload(&self.gpu, &staged);
            stats.blocks += 1;
        }
        stats.stage_seconds = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let mut enc = self.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame uploads") });
        stats.regions = self.g3.encode(&self.gpu, &self.pools, &mut enc, &self.pending_mask, tree.capacity, tree.lat.roots);
        self.gpu.queue.submit([enc.finish()]);
        self.gpu.wait();
        stats.gpu_seconds = t1.elapsed().as_secs_f64();
        stats.pending = self.pending_blocks.len() as u32;
        if self.pending_blocks.is_empty() {
            self.pending_mask = NeighbourMask::default();
        }
        Ok(stats)
    }

    /// Bring the GPU fully up to date with `tree`: every dirty block
    /// uploaded, g3 recomputed over every dirty region.
    pub fn sync(&mut self, tree: &mut Tree) -> Result<SyncStats, GpuError> {
        self.upload_frame(tree, None)
    }

    /// Cast an image of what the GPU holds now (no upload): `w·h·3` bytes.
    pub fn cast(&mut self, tree: &Tree, camera: &Camera, precision: Precision) -> Result<Vec<u8>, GpuError> {
        self.cast_params(&RayParams::new(&tree.lat, camera), precision)
    }

    /// [`Renderer::cast`] with the frame constants given.
    pub fn cast_params(&mut self, params: &RayParams, precision: Precision) -> Result<Vec<u8>, GpuError> {
        self.submit_cast(params, precision)?;
        self.ray.read_image(&self.gpu, params.width, params.height)
    }

    /// Cast the image `params` describe and return its digest
    /// (`digest::rgb_digest` of the image [`Renderer::cast_params`] returns).
    pub fn cast_digest(&mut self, params: &RayParams, precision: Precision) -> Result<u64, GpuError> {
        self.submit_cast(params, precision)?;
        self.ray.image_digest(&self.gpu, params.width, params.height)
    }

    /// Submit the ray cast of one image, without waiting for it.
    fn submit_cast(&mut self, params: &RayParams, precision: Precision) -> Result<(), GpuError> {
        let mut enc = self.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ray cast") });
        self.ray.encode(&self.gpu, &self.pools, &mut enc, params, precision)?;
        self.gpu.queue.submit([enc.finish()]);
        Ok(())
    }

    /// Cast one image per entry of `eyes` (a stereo frame: one per eye)
    /// and wait for the GPU, without reading anything back: what a frame's
    /// ray casting costs (benchmarks). Each cast is its own submission, so
    /// each sees its own frame constants; they share the pixel buffer.
    pub fn cast_and_wait(&mut self, eyes: &[RayParams], precision: Precision) -> Result<(), GpuError> {
        for params in eyes {
            self.submit_cast(params, precision)?;
        }
        self.gpu.wait();
        Ok(())
    }

    /// The image `camera` sees of `tree` with everything uploaded.
    pub fn render(&mut self, tree: &mut Tree, camera: &Camera, precision: Precision) -> Result<Vec<u8>, GpuError> {
        self.sync(tree)?;
        self.cast(tree, camera, precision)
    }

    /// Every pixel's ray of `camera` over `tree`, traced with everything
    /// uploaded: one probe record per ray, row by row from the top
    /// (docs/precision.md, "The GPU's f16").
    pub fn probe(&mut self, tree: &mut Tree, camera: &Camera, precision: Precision) -> Result<Vec<crate::raycast::ProbeRecord>, GpuError> {
        self.sync(tree)?;
        self.ray.probe(&self.gpu, &self.pools, &RayParams::new(&tree.lat, camera), precision)
    }

    /// The image of a document's contributing layers, bottom first, each a
    /// tree with its opacity (spec 6.2): their pools one after the other in
    /// the pages, with the g3 tables of the CPU port (g3.rs), and one march
    /// through all of them; one layer at opacity 1 is the one-tree image.
    /// The pages then hold the document, not the tree this renderer
    /// follows: its next sync uploads that tree whole again.
    pub fn render_layers(&mut self, layers: &[(&Tree, f32)], params: &RayParams, precision: Precision) -> Result<Vec<u8>, GpuError> {
        let table = self.upload_layers(layers)?;
        let mut enc = self.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ray cast layers") });
        self.ray.encode_layers(&self.gpu, &self.pools, &mut enc, params, precision, &table)?;
        self.gpu.queue.submit([enc.finish()]);
        self.ray.read_image(&self.gpu, params.width, params.height)
    }

    /// Write `layers` (each tree with its opacity) into the pages one after
    /// the other, with the CPU port's rows (g3 and shading vectors), and return the table the
    /// ray caster's `main_layers` reads (spec 6.2). The pages then no
    /// longer hold the tree this renderer follows: its next sync uploads
    /// that tree whole again.
    pub fn upload_layers(&mut self, layers: &[(&Tree, f32)]) -> Result<LayerTableGpu, GpuError> {
        let mut cells = Vec::new();
        let mut g3 = Vec::new();
        let mut bases = Vec::with_capacity(layers.len());
        let mut staged = Vec::new();
        for (tree, _) in layers {
            bases.push(u32::try_from(cells.len()).map_err(|_| GpuError::TooBig("a document of more than 2^32 cells".into()))?);
            stage_into(tree, 0, tree.n_used() as usize, &mut staged);
            cells.extend_from_slice(&staged);
            g3.extend(octopaint_tree::normals::table(tree));
        }
        self.pools.ensure(&self.gpu, cells.len() as u64)?;
        self.pools.upload_cells(&self.gpu, 0, &cells);
        self.pools.upload_g3(&self.gpu, 0, &g3);
        self.attached = false;
        self.pending_blocks.clear();
        self.pending_mask = NeighbourMask::default();
        let opacity: Vec<f32> = layers.iter().map(|(_, o)| *o).collect();
        Ok(LayerTableGpu::new(&bases, &opacity))
    }

    /// The rows (g3 and the shading vector's word, spec 6.1) of every used
    /// cell, as the GPU holds them (after a sync).
    pub fn read_rows(&mut self, tree: &mut Tree) -> Result<Vec<[u32; 4]>, GpuError> {
        self.sync(tree)?;
        self.pools.read_rows(&self.gpu, u64::from(tree.n_used()))
    }

    /// g3 of every used cell, as the GPU holds it (after a sync).
    pub fn read_g3(&mut self, tree: &mut Tree) -> Result<Vec<[u32; 3]>, GpuError> {
        self.sync(tree)?;
        self.pools.read_g3(&self.gpu, u64::from(tree.n_used()))
    }
}

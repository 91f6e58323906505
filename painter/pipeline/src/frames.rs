//! The render side of the engine (docs/architecture.md): what a front
//! end's frame loop does each frame before it casts, and after. [`Frames`]
//! never touches the tree: it takes the staged copies (at most K, newest
//! first; grouped: every staged batch), writes each into its layer's range
//! of the pages ([`crate::layout`]), recomputes g3 per layer over the
//! regions of the copies uploaded now and of those whose publication the
//! *consistent cut* passes now, and draws the newest layer list the cut
//! holds. After the cast, [`Frames::ended`] tells the ledger, which marks
//! the jobs the frame shows.

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use octopaint_gpu::raycast::LayerTableGpu;
use octopaint_gpu::{GpuError, Precision, Renderer};
use octopaint_tree::dirty::{MASK_COLUMNS, MASK_ROWS, NeighbourMask, REGIONS};
use octopaint_tree::raycast::RayParams;

use crate::engine::{Engine, LayerList, Shared};
use crate::layout::Layout;
use crate::settings::{MaskSize, Settings};
use crate::staging::StagedItem;

/// What one frame's uploads did.
#[derive(Clone, Copy, Debug, Default)]
pub struct Prepared {
    /// Staged copies written, and their cells.
    pub uploads: u32,
    pub cells_uploaded: u64,
    /// Regions whose g3 was recomputed (over every layer).
    pub regions: u32,
    /// The newest publication whose changes, with all earlier ones, are on
    /// the GPU (the consistent cut), and the newest any upload carried.
    pub cut: u64,
    pub newest_uploaded: u64,
    /// The picture of the painting changed: something was written, or the
    /// layer list drawn is another one.
    pub changed: bool,
    /// The table of the contributing layers for `encode_layers` (a
    /// document of layers); None: one tree at cell 0, cast with `encode`.
    pub layers: Option<LayerTableGpu>,
    pub upload_seconds: f64,
    pub g3_seconds: f64,
}

/// The fine 64×32 mask widened to `size` (every region of a marked coarse
/// cell), or every region for no mask.
fn widen(mask: &NeighbourMask, size: MaskSize) -> NeighbourMask {
    match size {
        MaskSize::None => {
            let mut all = NeighbourMask::default();
            if mask.count() > 0 {
                for r in 0..REGIONS {
                    all.set(r);
                }
            }
            all
        }
        MaskSize::Grid(cols, rows) if cols as usize == MASK_COLUMNS && rows as usize == MASK_ROWS => *mask,
        MaskSize::Grid(cols, rows) => {
            // Coarse cell (i, j) covers fine columns [i·64/cols, ...) and
            // rows [j·32/rows, ...).
            let (cw, rh) = (MASK_COLUMNS / cols.max(1) as usize, MASK_ROWS / rows.max(1) as usize);
            let mut out = NeighbourMask::default();
            for r in 0..REGIONS {
                if mask.get(r) {
                    let (row, col) = (r / MASK_COLUMNS, r % MASK_COLUMNS);
                    let (r0, c0) = (row / rh * rh, col / cw * cw);
                    for rr in r0..r0 + rh {
                        for cc in c0..c0 + cw {
                            out.set(rr * MASK_COLUMNS + cc);
                        }
                    }
                }
            }
            out
        }
    }
}

pub struct Frames {
    shared: Arc<Shared>,
    settings: Settings,
    /// Per (layer, group): the staging version last written.
    uploaded_version: HashMap<(u32, u32), u64>,
    newest_uploaded: u64,
    /// The g3 regions of every copy uploaded ahead of the consistent cut,
    /// with the publication it covers and its layer. Copies arrive newest
    /// first, so a copy can land before an older publication's; its
    /// regions are recomputed when it is uploaded (so the frame shows it)
    /// and once more in the frame the cut passes its publication, when
    /// every block that publication's g3 depends on is on the GPU at least
    /// as new. (Recomputing them every frame until then, as this once did,
    /// made a pipeline that had fallen behind spend its frames on g3 and
    /// fall further behind.)
    floating: Vec<(u64, u32, NeighbourMask)>,
    layout: Option<Layout>,
    /// Per layer with a range: the newest publication its copies carried.
    placed: HashMap<u32, u64>,
    /// The layer list the frames draw.
    drawn: Option<LayerList>,
}

impl Frames {
    /// The frames of `engine`'s painting (one per front end).
    pub fn new(engine: &Engine, settings: &Settings) -> Frames {
        Frames {
            shared: engine.shared.clone(),
            settings: settings.clone(),
            uploaded_version: HashMap::new(),
            newest_uploaded: 0,
            floating: Vec::new(),
            layout: None,
            placed: HashMap::new(),
            drawn: None,
        }
    }

    /// The layer ranges (tests read a layer's cells back at its range).
    pub fn range(&self, id: u32) -> Option<(u64, u64)> {
        self.layout.as_ref().and_then(|l| l.range(id))
    }

    /// Every layer's range: (id, first cell, cells).
    pub fn ranges(&self) -> Vec<(u32, u64, u64)> {
        let Some(l) = &self.layout else { return Vec::new() };
        l.ids().into_iter().filter_map(|id| l.range(id).map(|(b, n)| (id, b, n))).collect()
    }

    /// Whether the opening and everything published since have reached
    /// the GPU, and nothing is staged: a frame now would upload nothing.
    pub fn settled(&self) -> bool {
        let l = self.shared.ledger.lock().expect("ledger");
        l.last_pub > 0
            && l.cut() == l.last_pub
            && self.shared.staged.is_empty()
            && self.shared.pending.is_empty()
            && self.shared.lists.lock().expect("lists").is_empty()
    }

    /// One frame's GPU work before the cast: uploads, layer moves, g3.
    pub fn prepare(&mut self, r: &mut Renderer) -> Result<Prepared, GpuError> {
        let start = Instant::now();
        let layout = self.layout.get_or_insert_with(|| Layout::new(r.pools.max_cells()));
        layout.hold(r.pools.cells_held());
        // Grouped staging uploads every staged batch: batches are
        // consistent states only together with the ones before them (a LIFO
        // bounded by K would upload newer batches over older ones left out).
        let k = if self.settings.strategy.grouped { usize::MAX } else { self.settings.blocks_per_frame.max(1) };
        let copies: Vec<_> = self
            .shared
            .staged
            .take(k)
            .into_iter()
            .flat_map(|item| match item {
                StagedItem::One(c) => vec![c],
                StagedItem::Batch(cs) => cs,
            })
            .collect();
        // Where each copy goes: its layer's range, grown or moved first
        // (copies on the GPU), then the pages that hold them.
        let write: Vec<bool> = copies
            .iter()
            .map(|c| {
                let last = self.uploaded_version.entry((c.layer, c.group)).or_insert(0);
                let fresh = c.version > *last && !c.cells.is_empty();
                if fresh {
                    *last = c.version;
                }
                fresh
            })
            .collect();
        // What each layer uses once they are written: its newest copy's
        // tree length, and every copy written. Only grouped staging (the
        // default) says so: it uploads copies in the order they were
        // staged, so the newest length is the layer's. The LIFO order of
        // the other strategy may write an older copy last; there a range
        // keeps its room.
        let fresh = || copies.iter().zip(&write).filter(|(_, w)| **w).map(|(c, _)| c);
        if self.settings.strategy.grouped {
            // Per layer: the newest copy's version and length, the widest end.
            let mut lengths: HashMap<u32, (u64, u64, u64)> = HashMap::new();
            for c in fresh() {
                let e = lengths.entry(c.layer).or_insert((0, 0, 0));
                if c.version > e.0 {
                    (e.0, e.1) = (c.version, c.length);
                }
                e.2 = e.2.max(c.end());
            }
            for (id, (_, length, end)) in lengths {
                layout.set_length(id, length.max(end));
            }
        }
        for c in fresh() {
            let moves = layout.fit(c.layer, c.end()).map_err(GpuError::TooBig)?;
            // Each fit's moves read the ranges as the one before left them.
            if !moves.is_empty() {
                r.pools.ensure(&r.gpu, layout.end())?;
                r.pools.move_ranges(&r.gpu, &moves.iter().map(|m| (m.from, m.to, m.cells)).collect::<Vec<_>>());
            }
        }
        r.pools.ensure(&r.gpu, layout.end())?;
        self.shared.gpu_cells.store(r.pools.cells_held(), Ordering::Release);
        let (mut uploads, mut cells_uploaded) = (0u32, 0u64);
        let mut covered: Vec<(Vec<u64>, u64)> = Vec::new();
        let mut masks: HashMap<u32, NeighbourMask> = HashMap::new();
        for (c, fresh) in copies.into_iter().zip(write) {
            if fresh {
                let (base, _) = layout.range(c.layer).expect("fitted above");
                r.pools.upload_cells(&r.gpu, base + c.first, &c.cells);
                uploads += 1;
                cells_uploaded += c.cells.len() as u64;
                self.newest_uploaded = self.newest_uploaded.max(c.covered_pub);
                let p = self.placed.entry(c.layer).or_insert(0);
                *p = (*p).max(c.covered_pub);
            }
            // A copy older than one already uploaded is not written, but
            // its regions are recomputed and its changes count as on the
            // GPU: the newer copy holds them, not its regions.
            masks.entry(c.layer).or_default().union(&c.mask);
            self.floating.push((c.covered_pub, c.layer, c.mask));
            covered.push((c.blocks, c.covered_pub));
            self.shared.staged.give_back(c.cells);
        }
        // The cut after this frame's uploads: the floating regions it
        // passes are recomputed now, for the last time.
        let cut = {
            let mut l = self.shared.ledger.lock().expect("ledger");
            for (blocks, pub_no) in covered {
                for b in blocks {
                    l.uploaded(b, pub_no);
                }
            }
            l.cut()
        };
        self.floating.retain(|(p, layer, m)| {
            if *p <= cut {
                masks.entry(*layer).or_default().union(m);
            }
            *p > cut
        });
        // The newest layer list the cut holds: every block of the layers
        // it lists is on the GPU as of it. The ranges of layers it does not
        // list, written before it, are forgotten (a layer listed again is
        // published whole); a layer written after it is newer than the
        // list, not gone.
        let mut changed = uploads > 0;
        let newest = {
            let mut lists = self.shared.lists.lock().expect("lists");
            let mut newest = None;
            while lists.front().is_some_and(|(p, _)| *p <= cut) {
                newest = lists.pop_front();
            }
            newest
        };
        if let Some((list_pub, list)) = newest {
            for id in layout.ids() {
                if !list.layers.iter().any(|l| l.id == id) && self.placed.get(&id).is_none_or(|&p| p <= list_pub) {
                    layout.free(id);
                    self.placed.remove(&id);
                }
            }
            changed |= self.drawn.as_ref() != Some(&list);
            self.drawn = Some(list);
        }
        let t_up = Instant::now();
        let mut regions = 0;
        let roots = self.shared.size.roots;
        for (layer, mask) in &masks {
            let Some((base, cells)) = layout.range(*layer) else { continue };
            let mut enc = r.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame g3") });
            let (base, cells) = (base as u32, cells.min(u64::from(u32::MAX)) as u32);
            regions += r.g3.encode_layer(&r.gpu, &r.pools, &mut enc, &widen(mask, self.settings.mask), self.shared.size.capacity, roots, base, cells);
            r.gpu.queue.submit([enc.finish()]);
        }
        r.gpu.wait();
        let t_g3 = Instant::now();
        let layers = match &self.drawn {
            Some(list) if list.version == 2 => {
                let (bases, opacity): (Vec<u32>, Vec<f32>) =
                    list.layers.iter().filter(|l| l.visible && l.opacity > 0.0).filter_map(|l| layout.range(l.id).map(|(b, _)| (b as u32, l.opacity))).unzip();
                Some(LayerTableGpu::new(&bases, &opacity))
            }
            _ => None,
        };
        Ok(Prepared {
            uploads,
            cells_uploaded,
            regions,
            cut,
            newest_uploaded: self.newest_uploaded,
            changed,
            layers,
            upload_seconds: (t_up - start).as_secs_f64(),
            g3_seconds: (t_g3 - t_up).as_secs_f64(),
        })
    }

    /// Encode the cast of what the GPU holds: one tree, or the layers of
    /// `prepared`'s table.
    pub fn encode_cast(
        r: &mut Renderer,
        enc: &mut wgpu::CommandEncoder,
        params: &RayParams,
        precision: Precision,
        prepared: &Prepared,
    ) -> Result<(), GpuError> {
        match &prepared.layers {
            Some(t) => r.ray.encode_layers(&r.gpu, &r.pools, enc, params, precision, t),
            None => r.ray.encode(&r.gpu, &r.pools, enc, params, precision),
        }
    }

    /// The frame ended at `at` (presented, or cast and waited for): the
    /// jobs its cut holds are shown. Returns the newest job shown so far
    /// and how many are not shown yet.
    pub fn ended(&mut self, at: Instant) -> (u64, usize) {
        let mut l = self.shared.ledger.lock().expect("ledger");
        let index = self.shared.frames.fetch_add(1, Ordering::AcqRel) + 1;
        let shown = l.frame_ended(index, at);
        (shown, l.unshown())
    }
}

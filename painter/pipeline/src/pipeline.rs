//! The three threads of the real-time pipeline (docs/architecture.md, the
//! paper's Fig. 4):
//!
//! - the **stroke thread** takes jobs from the job queue and runs them on
//!   the painting one level (or, in aggressive staging, one part of a
//!   level) at a time; after each it publishes: the dirty blocks and the
//!   neighbour mask go into the pending set, the publication into the
//!   ledger. It holds the tree's lock for one level at a time.
//! - the **staging thread** takes the most recently dirtied group of
//!   blocks, takes the tree's lock only to copy it into a staging buffer
//!   (a short critical section: about a megabyte), and pushes the copy with
//!   the newest publication it contains.
//! - the **render thread** never touches the tree: every frame it uploads
//!   at most K staged copies, recomputes g3 over their regions, ray casts,
//!   and tells the ledger, which marks the jobs the frame shows.
//!
//! Painting never waits for rendering (the pending set merges; the staging
//! thread is the one that waits for buffers) and rendering never waits for
//! painting (it renders whatever is staged, every frame).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use octopaint_gpu::pools::{GpuCell, stage_into};
use octopaint_gpu::{GpuError, Renderer};
use octopaint_tree::dirty::{BLOCK_CELLS, MASK_COLUMNS, MASK_ROWS, NeighbourMask, REGIONS};
use octopaint_tree::lattice::Lattice;
use octopaint_tree::paint::Painting;
use octopaint_tree::raycast::RayParams;
use rayon::prelude::*;

use crate::jobs::{Job, JobQueue, SubmitError, Ticket};
use crate::ledger::Ledger;
use crate::settings::{BlockSize, MaskSize, Settings};
use crate::staging::{PendingSet, StagedCopy, StagedItem, StagedStack};

/// A gate a thread waits at while it is closed (tests stall threads with it).
#[derive(Default)]
pub struct Gate {
    closed: Mutex<bool>,
    changed: Condvar,
}

impl Gate {
    pub fn close(&self) {
        *self.closed.lock().expect("gate") = true;
    }
    pub fn open(&self) {
        *self.closed.lock().expect("gate") = false;
        self.changed.notify_all();
    }
    fn pass(&self) {
        let mut closed = self.closed.lock().expect("gate");
        while *closed {
            closed = self.changed.wait(closed).expect("gate");
        }
    }
}

/// Places where tests can stall a thread.
#[derive(Clone, Default)]
pub struct Hooks {
    /// The render thread waits here before every frame.
    pub render: Option<Arc<Gate>>,
    /// The stroke thread waits here at the start of every level, holding
    /// the tree's lock (a stalled painter, as far as staging can tell).
    pub stroke: Option<Arc<Gate>>,
}

/// One frame, as the render thread saw it.
#[derive(Clone, Debug)]
pub struct FrameRecord {
    pub index: u64,
    pub start: Instant,
    pub end: Instant,
    /// Staged copies uploaded, and their cells.
    pub uploads: u32,
    pub cells_uploaded: u64,
    /// Regions whose g3 was recomputed.
    pub regions: u32,
    /// The newest publication whose changes, with all earlier ones, are on
    /// the GPU (the consistent cut), and the newest any upload carried.
    pub cut: u64,
    pub newest_uploaded: u64,
    /// Jobs 1..=shown_jobs are fully shown.
    pub shown_jobs: u64,
    pub upload_seconds: f64,
    pub g3_seconds: f64,
    pub cast_seconds: f64,
    /// With `capture`: the digest of the frame's image (`octopaint_gpu::digest`).
    pub digest: Option<u64>,
}

impl FrameRecord {
    pub fn ms(&self) -> f64 {
        (self.end - self.start).as_secs_f64() * 1e3
    }
}

/// One staged copy, as the staging thread saw it.
#[derive(Clone, Copy, Debug)]
pub struct StagingRecord {
    pub cells: u64,
    /// Time holding the tree's lock: the copy.
    pub seconds: f64,
    /// Time waiting for the lock first.
    pub wait_seconds: f64,
}

/// What a finished pipeline hands back.
pub struct Report {
    pub painting: Painting,
    pub ledger: Ledger,
    pub frames: Vec<FrameRecord>,
    pub staging: Vec<StagingRecord>,
    pub renderer: Renderer,
    pub adapter: String,
}

#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error("the {0} thread panicked")]
    Panicked(&'static str),
}

struct Shared {
    painting: Mutex<Painting>,
    ledger: Mutex<Ledger>,
    jobs: JobQueue,
    pending: PendingSet,
    staged: StagedStack,
    frames: AtomicU64,
    finishing: AtomicBool,
}

pub struct Pipeline {
    shared: Arc<Shared>,
    stroke: JoinHandle<()>,
    staging: JoinHandle<Vec<StagingRecord>>,
    render: JoinHandle<Result<(Renderer, Vec<FrameRecord>), GpuError>>,
}

/// Cells of one staged group.
fn group_cells(block: BlockSize) -> Option<u64> {
    match block {
        BlockSize::Cells(c) => Some(u64::from(c.max(BLOCK_CELLS))),
        BlockSize::WholePool => None,
    }
}

/// First cell and length of a group's copy.
fn group_range(block: BlockSize, group: u32, n_used: u32) -> (u64, usize) {
    match group_cells(block) {
        Some(c) => (u64::from(group) * c, c as usize),
        None => (0, (n_used as usize).div_ceil(BLOCK_CELLS as usize) * BLOCK_CELLS as usize),
    }
}

fn group_of(block: BlockSize, b: u32) -> u32 {
    match group_cells(block) {
        Some(c) => (u64::from(b) * u64::from(BLOCK_CELLS) / c) as u32,
        None => 0,
    }
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

impl Pipeline {
    /// Open the GPU, upload the painting as it is, and start the threads.
    pub fn start(mut painting: Painting, settings: Settings, hooks: Hooks) -> Result<Pipeline, PipelineError> {
        let mut renderer = Renderer::new(settings.backend)?;
        renderer.sync(&mut painting.tree)?;
        let lattice = painting.tree.lat.clone();
        let capacity = painting.tree.capacity;
        let shared = Arc::new(Shared {
            painting: Mutex::new(painting),
            ledger: Mutex::new(Ledger::default()),
            jobs: JobQueue::new(settings.job_queue),
            pending: PendingSet::default(),
            staged: StagedStack::new(settings.staging_buffers),
            frames: AtomicU64::new(0),
            finishing: AtomicBool::new(false),
        });
        let stroke = {
            let (shared, settings, hooks) = (shared.clone(), settings.clone(), hooks.clone());
            std::thread::Builder::new().name("stroke".into()).spawn(move || stroke_thread(&shared, &settings, &hooks)).expect("spawn")
        };
        let staging = {
            let (shared, settings) = (shared.clone(), settings.clone());
            std::thread::Builder::new().name("staging".into()).spawn(move || staging_thread(&shared, &settings)).expect("spawn")
        };
        let render = {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("render".into())
                .spawn(move || render_thread(&shared, &settings, &hooks, renderer, lattice, capacity))
                .expect("spawn")
        };
        Ok(Pipeline { shared, stroke, staging, render })
    }

    /// Queue a job (waiting while the job queue is full).
    pub fn submit(&self, job: Job) -> Result<Ticket, SubmitError> {
        self.shared.jobs.submit(job)
    }

    /// Queue a job if the job queue has room.
    pub fn try_submit(&self, job: Job) -> Result<Ticket, (SubmitError, Job)> {
        self.shared.jobs.try_submit(job)
    }

    /// Jobs waiting in the job queue.
    pub fn queued(&self) -> usize {
        self.shared.jobs.len()
    }

    /// Frames rendered so far.
    pub fn frames(&self) -> u64 {
        self.shared.frames.load(Ordering::Acquire)
    }

    /// Jobs the stroke thread has finished.
    pub fn jobs_finished(&self) -> usize {
        self.shared.ledger.lock().expect("ledger").jobs.iter().filter(|j| j.finished.is_some()).count()
    }

    /// Jobs shown by some frame.
    pub fn jobs_shown(&self) -> usize {
        self.shared.ledger.lock().expect("ledger").jobs.iter().filter(|j| j.shown.is_some()).count()
    }

    /// Stop taking jobs, let every queued job run, every dirty block reach
    /// the GPU and a frame show it all; then join the threads.
    pub fn finish(self) -> Result<Report, PipelineError> {
        self.shared.jobs.close();
        self.shared.finishing.store(true, Ordering::Release);
        self.stroke.join().map_err(|_| PipelineError::Panicked("stroke"))?;
        let staging = self.staging.join().map_err(|_| PipelineError::Panicked("staging"))?;
        let (renderer, frames) = self.render.join().map_err(|_| PipelineError::Panicked("render"))??;
        let shared = Arc::try_unwrap(self.shared).ok().expect("every thread has ended");
        let adapter = renderer.gpu.describe();
        Ok(Report {
            painting: shared.painting.into_inner().expect("painting"),
            ledger: shared.ledger.into_inner().expect("ledger"),
            frames,
            staging,
            renderer,
            adapter,
        })
    }
}

/// The stroke thread runs the painter core on its own rayon pool of
/// `settings.core_threads` threads (the core's parallel passes, docs/
/// architecture.md), so that they never wait on threads the render and
/// staging threads have pushed off the cores.
fn stroke_thread(shared: &Shared, settings: &Settings, hooks: &Hooks) {
    let threads = settings.core_threads.max(1);
    match rayon::ThreadPoolBuilder::new().num_threads(threads).thread_name(|i| format!("stroke-core-{i}")).build() {
        Ok(pool) => pool.install(|| stroke_jobs(shared, settings, hooks)),
        // No threads to spare: the core on the caller's pool, as elsewhere.
        Err(_) => stroke_jobs(shared, settings, hooks),
    }
}

fn stroke_jobs(shared: &Shared, settings: &Settings, hooks: &Hooks) {
    let block = settings.block;
    let publish = |painting: &mut Painting, seq: u64| {
        let p = painting.tree.take_publication();
        if p.blocks.is_empty() && p.mask.count() == 0 {
            return;
        }
        let n = shared.ledger.lock().expect("ledger").published(seq, &p.blocks);
        shared.pending.merge(n, |b| group_of(block, b), &p.blocks, &p.mask);
    };
    while let Some(ticket) = shared.jobs.pop() {
        let seq = ticket.seq;
        {
            let mut l = shared.ledger.lock().expect("ledger");
            l.submitted(seq, ticket.job.name(), ticket.submitted);
            l.started(seq);
        }
        match &ticket.job {
            Job::Sample(s) => {
                let t0 = Instant::now();
                shared.painting.lock().expect("painting").begin_sample(s, 0);
                let mut painting_seconds = t0.elapsed().as_secs_f64();
                loop {
                    let mut painting = shared.painting.lock().expect("painting");
                    if let Some(g) = &hooks.stroke {
                        g.pass();
                    }
                    let t0 = Instant::now();
                    let done = painting.step(settings.strategy.aggressive_units);
                    painting_seconds += t0.elapsed().as_secs_f64();
                    publish(&mut painting, seq);
                    if done {
                        break;
                    }
                }
                shared.ledger.lock().expect("ledger").painted(seq, painting_seconds);
            }
            job => {
                let mut painting = shared.painting.lock().expect("painting");
                if let Some(g) = &hooks.stroke {
                    g.pass();
                }
                match job {
                    Job::BeginStroke(b) => painting.begin_stroke(b),
                    Job::EndStroke => painting.end_stroke(),
                    Job::Undo => {
                        painting.undo();
                    }
                    Job::Redo => {
                        painting.redo();
                    }
                    Job::Sample(_) => unreachable!(),
                }
                publish(&mut painting, seq);
            }
        }
        shared.ledger.lock().expect("ledger").finished(seq);
    }
    shared.pending.close();
}

fn staging_thread(shared: &Shared, settings: &Settings) -> Vec<StagingRecord> {
    let mut records = Vec::new();
    let mut version = 0u64;
    loop {
        if settings.strategy.grouped {
            // Grouped staging: everything pending, taken and copied under one
            // hold of the tree's lock: one consistent state.
            if !shared.pending.wait_for_work() {
                break;
            }
            let w0 = Instant::now();
            let painting = shared.painting.lock().expect("painting");
            let t0 = Instant::now();
            let taken = shared.pending.take_all_now();
            let covered = shared.ledger.lock().expect("ledger").last_pub;
            // The groups are copied in parallel: a heavy sample dirties tens
            // of blocks, and the lock is held until the last is copied (on
            // an H100 host, 16 ms at p99 one after another).
            let tree = &painting.tree;
            let n_used = tree.n_used();
            let staged: Vec<(u64, Vec<GpuCell>)> = taken
                .par_iter()
                .map(|t| {
                    let (first, len) = group_range(settings.block, t.group, n_used);
                    let mut cells = shared.staged.spare();
                    stage_into(tree, first, len, &mut cells);
                    (first, cells)
                })
                .collect();
            drop(painting);
            let mut copies = Vec::with_capacity(taken.len());
            for (t, (first, cells)) in taken.into_iter().zip(staged) {
                version += 1;
                copies.push(StagedCopy { group: t.group, first, cells, covered_pub: covered, mask: t.mask, blocks: t.blocks, version, staged_at: t0 });
            }
            let t1 = Instant::now();
            let cells: u64 = copies.iter().map(|c| c.cells.len() as u64).sum();
            records.push(StagingRecord { cells, seconds: (t1 - t0).as_secs_f64(), wait_seconds: (t0 - w0).as_secs_f64() });
            shared.staged.push(StagedItem::Batch(copies));
            continue;
        }
        let Some(t) = shared.pending.take_newest() else { break };
        let mut cells: Vec<GpuCell> = shared.staged.buffer();
        let w0 = Instant::now();
        let painting = shared.painting.lock().expect("painting");
        let t0 = Instant::now();
        let (first, len) = group_range(settings.block, t.group, painting.tree.n_used());
        stage_into(&painting.tree, first, len, &mut cells);
        // The copy holds every publication recorded so far: the stroke
        // thread records them while it holds this lock.
        let covered = shared.ledger.lock().expect("ledger").last_pub;
        drop(painting);
        let t1 = Instant::now();
        records.push(StagingRecord { cells: len as u64, seconds: (t1 - t0).as_secs_f64(), wait_seconds: (t0 - w0).as_secs_f64() });
        version += 1;
        let copies = vec![StagedCopy { group: t.group, first, cells, covered_pub: covered, mask: t.mask, blocks: t.blocks, version, staged_at: t1 }];
        for c in copies {
            shared.staged.push(StagedItem::One(c));
        }
    }
    shared.staged.close();
    records
}

fn render_thread(
    shared: &Shared,
    settings: &Settings,
    hooks: &Hooks,
    mut r: Renderer,
    lattice: Lattice,
    capacity: u32,
) -> Result<(Renderer, Vec<FrameRecord>), GpuError> {
    let mut frames = Vec::new();
    let mut uploaded_version: std::collections::HashMap<u32, u64> = std::collections::HashMap::new();
    let mut newest_uploaded = 0u64;
    // The g3 regions of every copy uploaded ahead of the consistent cut,
    // with the publication it covers. Copies arrive newest first, so a
    // copy can land before an older publication's; its regions are
    // recomputed when it is uploaded (so the frame shows it) and once more
    // in the frame the cut passes its publication, when every block that
    // publication's g3 depends on is on the GPU at least as new. (Recomputing
    // them every frame until then, as this once did, made a pipeline that
    // had fallen behind spend its frames on g3 and fall further behind.)
    let mut floating: Vec<(u64, NeighbourMask)> = Vec::new();
    let mut params = RayParams::new(&lattice, &settings.camera);
    params.skip_invalid = settings.strategy.skip_invalid;
    let period = settings.target_hz.map(|hz| Duration::from_secs_f64(1.0 / hz));
    let mut next_deadline = Instant::now();
    let mut quiet_frames = 0;
    loop {
        if let Some(g) = &hooks.render {
            g.pass();
        }
        let start = Instant::now();
        // Grouped staging uploads every staged batch: batches are
        // consistent states only together with the ones before them (a LIFO
        // bounded by K would upload newer batches over older ones left out).
        let k = if settings.strategy.grouped { usize::MAX } else { settings.blocks_per_frame.max(1) };
        let items = shared.staged.take(k);
        let (mut uploads, mut cells_uploaded) = (0u32, 0u64);
        let mut covered: Vec<(Vec<u32>, u64)> = Vec::new();
        let mut mask = NeighbourMask::default();
        for item in items {
            let copies = match item {
                StagedItem::One(c) => vec![c],
                StagedItem::Batch(cs) => cs,
            };
            for c in copies {
                let last = uploaded_version.entry(c.group).or_insert(0);
                if c.version > *last {
                    *last = c.version;
                    r.pools.ensure(&r.gpu, c.first + c.cells.len() as u64)?;
                    r.pools.upload_cells(&r.gpu, c.first, &c.cells);
                    uploads += 1;
                    cells_uploaded += c.cells.len() as u64;
                    newest_uploaded = newest_uploaded.max(c.covered_pub);
                }
                // A copy older than one already uploaded is not written, but
                // its regions are recomputed and its changes count as on the
                // GPU: the newer copy holds them, not its regions.
                mask.union(&c.mask);
                floating.push((c.covered_pub, c.mask));
                covered.push((c.blocks, c.covered_pub));
                shared.staged.give_back(c.cells);
            }
        }
        // The cut after this frame's uploads: the floating regions it
        // passes are recomputed now, for the last time.
        let cut = {
            let mut l = shared.ledger.lock().expect("ledger");
            for (blocks, pub_no) in covered {
                for b in blocks {
                    l.uploaded(b, pub_no);
                }
            }
            l.cut()
        };
        floating.retain(|(p, m)| {
            if *p <= cut {
                mask.union(m);
            }
            *p > cut
        });
        let t_up = Instant::now();
        let mut enc = r.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        let regions = r.g3.encode(&r.gpu, &r.pools, &mut enc, &widen(&mask, settings.mask), capacity, lattice.roots);
        r.gpu.queue.submit([enc.finish()]);
        r.gpu.wait();
        let t_g3 = Instant::now();
        let mut enc = r.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame cast") });
        r.ray.encode(&r.gpu, &r.pools, &mut enc, &params, settings.precision)?;
        r.gpu.queue.submit([enc.finish()]);
        let digest = if settings.capture { Some(r.ray.image_digest(&r.gpu, params.width, params.height)?) } else { None };
        r.gpu.wait();
        let end = Instant::now();
        let index = frames.len() as u64 + 1;
        let (shown_jobs, unshown) = {
            let mut l = shared.ledger.lock().expect("ledger");
            // (The cut may have moved on since the uploads, by publications
            // that changed no block; the frame's record keeps the cut its
            // image shows.)
            let shown = l.frame_ended(index, end);
            (shown, l.unshown())
        };
        frames.push(FrameRecord {
            index,
            start,
            end,
            uploads,
            cells_uploaded,
            regions,
            cut,
            newest_uploaded,
            shown_jobs,
            upload_seconds: (t_up - start).as_secs_f64(),
            g3_seconds: (t_g3 - t_up).as_secs_f64(),
            cast_seconds: (end - t_g3).as_secs_f64(),
            digest,
        });
        shared.frames.store(index, Ordering::Release);
        // Done when asked to finish and everything has reached the screen:
        // no job left unshown, nothing staged, staging closed.
        if shared.finishing.load(Ordering::Acquire)
            && shared.staged.is_closed()
            && shared.staged.is_empty()
            && shared.jobs.is_empty()
            && unshown == 0
        {
            quiet_frames += 1;
            if quiet_frames >= 1 {
                break;
            }
        }
        if let Some(p) = period {
            next_deadline += p;
            let now = Instant::now();
            if next_deadline > now {
                std::thread::sleep(next_deadline - now);
            } else {
                next_deadline = now; // a missed frame: no catching up
            }
        }
    }
    Ok((r, frames))
}

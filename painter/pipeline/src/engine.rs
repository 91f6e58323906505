//! The engine under every front end (docs/architecture.md): the stroke
//! thread, which owns the document and runs jobs on it one level at a time,
//! and the staging thread, which copies what each level dirtied. The front
//! end's own frame loop (winit's, OpenXR's, the benchmark's render thread)
//! takes the staged copies with [`crate::frames::Frames`] and never touches
//! the tree: what it shows of the painting besides the image comes from
//! the [`Status`] the stroke thread publishes after every job, and what it
//! needs of the tree (the surface under the cursor, the view that frames
//! the painting) it asks ([`Engine::ask`]).
//!
//! - the **stroke thread** takes jobs from the job queue and runs them on
//!   the document, a sample one level (or, in aggressive staging, one part
//!   of a level) at a time; after each it publishes every listed layer's
//!   dirty blocks and neighbour mask into the pending set, the publication
//!   into the ledger, and the layer list when it changed. It holds the
//!   document's lock for one level at a time, and answers questions
//!   between levels.
//! - the **staging thread** takes the most recently dirtied group of
//!   blocks (grouped: every pending group), takes the lock only to copy it
//!   into a staging buffer, and pushes the copy with the newest
//!   publication it contains.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use octopaint_gpu::pools::{GpuCell, stage_into};
use octopaint_tree::dirty::{BLOCK_CELLS, NeighbourMask, REGIONS, region_cells};
use octopaint_tree::trace::Canvas as CanvasSize;
use rayon::prelude::*;

use crate::canvas::{Canvas, Ran, Status};
use crate::jobs::{Job, JobQueue, SubmitError, Ticket, Work};

/// A question for the painting, answered on the stroke thread between two
/// levels or jobs (the closure sends its answer where the asker waits for
/// it, a channel for example).
pub type Ask = Box<dyn FnOnce(&dyn Canvas) + Send>;
use crate::ledger::Ledger;
use crate::settings::{BlockSize, Settings};
use crate::staging::{PendingSet, StagedCopy, StagedItem, StagedStack, key};

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
    pub fn pass(&self) {
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
    /// the document's lock (a stalled painter, as far as staging can tell).
    pub stroke: Option<Arc<Gate>>,
}

/// One staged copy, as the staging thread saw it.
#[derive(Clone, Copy, Debug)]
pub struct StagingRecord {
    pub cells: u64,
    /// Time holding the document's lock: the copy.
    pub seconds: f64,
    /// Time waiting for the lock first.
    pub wait_seconds: f64,
}

/// One listed layer as the frames draw it: its id, and whether and how
/// strongly it contributes (spec 6.2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Listed {
    pub id: u32,
    pub visible: bool,
    pub opacity: f32,
}

/// The document's layer list at a publication: which layers the GPU holds
/// and draws, bottom first, and the trace version (1: one tree, drawn
/// without a layer table).
#[derive(Clone, Debug, PartialEq)]
pub struct LayerList {
    pub version: u32,
    pub layers: Vec<Listed>,
}

/// What the stroke thread is busy with, for the heavy-operation indicator
/// (the paper's 8.3).
#[derive(Clone, Copy, Debug)]
pub struct Busy {
    pub what: &'static str,
    pub since: Instant,
}

pub(crate) struct Shared {
    /// The document; taken back by [`Engine::finish`] once the stroke and
    /// staging threads have ended (nothing else touches it).
    pub canvas: Mutex<Option<Box<dyn Canvas>>>,
    pub ledger: Mutex<Ledger>,
    pub jobs: JobQueue<Ask>,
    pub pending: PendingSet,
    pub staged: StagedStack,
    /// Layer lists published and not yet drawn, with their publications.
    pub lists: Mutex<VecDeque<(u64, LayerList)>>,
    pub status: Mutex<Status>,
    /// Lines for the artist (refusals, saves), oldest first.
    pub messages: Mutex<Vec<String>>,
    pub busy: Mutex<Option<Busy>>,
    pub finished_jobs: AtomicU64,
    pub frames: AtomicU64,
    pub finishing: AtomicBool,
    /// The cells the GPU's pages hold (the front end's frames set it).
    pub gpu_cells: AtomicU64,
    /// The canvas: its roots, lattice and budget (every layer's mask is
    /// kept at the budget's region size: spec 3.5).
    pub size: CanvasSize,
}

/// Queues jobs for an engine from any thread ([`Engine::submitter`]).
#[derive(Clone)]
pub struct Submitter(Arc<Shared>);

impl Submitter {
    /// Queue a job (waiting while the job queue is full).
    pub fn submit(&self, job: Job) -> Result<Ticket, SubmitError> {
        self.0.jobs.submit(job)
    }
}

pub struct Engine {
    pub(crate) shared: Arc<Shared>,
    stroke: JoinHandle<()>,
    staging: JoinHandle<Vec<StagingRecord>>,
}

/// What a finished engine hands back (the ledger stays with the frames,
/// which may still be showing the last jobs).
pub struct Finished {
    pub canvas: Box<dyn Canvas>,
    pub staging: Vec<StagingRecord>,
    /// Lines for the artist nobody took yet.
    pub messages: Vec<String>,
}

#[derive(Debug, thiserror::Error)]
#[error("the {0} thread panicked")]
pub struct Panicked(pub &'static str);

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

/// A mask of regions of `from` cells as regions of `to` cells (`to >=
/// from`): every region that shares a cell with a marked one. A layer's
/// tree may grow to its share of the budget only (spec 14.1), so its
/// masks come in smaller regions than the canvas's.
fn rescale(mask: &NeighbourMask, from: u32, to: u32) -> NeighbourMask {
    if from == to {
        return *mask;
    }
    let mut out = NeighbourMask::default();
    for r in 0..REGIONS {
        if mask.get(r) {
            let (lo, hi) = (r as u64 * u64::from(from), (r as u64 + 1) * u64::from(from) - 1);
            for s in lo / u64::from(to)..=(hi / u64::from(to)).min(REGIONS as u64 - 1) {
                out.set(s as usize);
            }
        }
    }
    out
}

impl Engine {
    /// Start the stroke and staging threads on `canvas`. Its listed layers
    /// are published whole first (nobody has seen them yet): the first
    /// frames upload them.
    pub fn start(canvas: Box<dyn Canvas>, settings: &Settings, hooks: &Hooks) -> Engine {
        let status = Status::of(&*canvas);
        let size = *canvas.document().canvas();
        let shared = Arc::new(Shared {
            canvas: Mutex::new(Some(canvas)),
            ledger: Mutex::new(settings.keep_records.map_or_else(Ledger::default, Ledger::keeping)),
            jobs: JobQueue::new(settings.job_queue),
            pending: PendingSet::default(),
            staged: StagedStack::new(settings.staging_buffers),
            lists: Mutex::new(VecDeque::new()),
            status: Mutex::new(status),
            messages: Mutex::new(Vec::new()),
            busy: Mutex::new(None),
            finished_jobs: AtomicU64::new(0),
            frames: AtomicU64::new(0),
            finishing: AtomicBool::new(false),
            gpu_cells: AtomicU64::new(0),
            size,
        });
        let stroke = {
            let (shared, settings, hooks) = (shared.clone(), settings.clone(), hooks.clone());
            std::thread::Builder::new().name("stroke".into()).spawn(move || stroke_thread(&shared, &settings, &hooks)).expect("spawn")
        };
        let staging = {
            let (shared, settings) = (shared.clone(), settings.clone());
            std::thread::Builder::new().name("staging".into()).spawn(move || staging_thread(&shared, &settings)).expect("spawn")
        };
        Engine { shared, stroke, staging }
    }

    /// Queue a job (waiting while the job queue is full).
    pub fn submit(&self, job: Job) -> Result<Ticket, SubmitError> {
        self.shared.jobs.submit(job)
    }

    /// A handle that queues jobs from another thread (a trace played at
    /// its pace).
    pub fn submitter(&self) -> Submitter {
        Submitter(self.shared.clone())
    }

    /// Queue a job if the job queue has room.
    #[expect(clippy::result_large_err, reason = "a refused job is handed back whole, for the caller to keep")]
    pub fn try_submit(&self, job: Job) -> Result<Ticket, (SubmitError, Job)> {
        self.shared.jobs.try_submit(job)
    }

    /// Ask the painting a question: `f` runs on the stroke thread before
    /// the next job or level, with the document as it is then.
    pub fn ask(&self, f: impl FnOnce(&dyn Canvas) + Send + 'static) -> Result<(), SubmitError> {
        let ask: Ask = Box::new(f);
        self.shared.jobs.ask(ask)
    }

    /// Jobs waiting in the job queue.
    pub fn queued(&self) -> usize {
        self.shared.jobs.len()
    }

    /// Jobs submitted, and jobs the stroke thread has finished.
    pub fn progress(&self) -> (u64, u64) {
        (self.shared.jobs.submitted(), self.shared.finished_jobs.load(Ordering::Acquire))
    }

    /// Every submitted job finished.
    pub fn idle(&self) -> bool {
        let (submitted, finished) = self.progress();
        submitted == finished
    }

    /// What the stroke thread published after its last job.
    pub fn status(&self) -> Status {
        self.shared.status.lock().expect("status").clone()
    }

    /// The lines for the artist since the last call.
    pub fn take_messages(&self) -> Vec<String> {
        std::mem::take(&mut *self.shared.messages.lock().expect("messages"))
    }

    /// What the stroke thread is busy with now, if anything.
    pub fn busy(&self) -> Option<Busy> {
        *self.shared.busy.lock().expect("busy")
    }

    /// The stroke-to-display latency of the newest shown job, ms.
    pub fn last_latency_ms(&self) -> Option<f64> {
        self.shared.ledger.lock().expect("ledger").shown.last_latency_ms
    }

    /// Running figures of every job shown so far (a front end's closing
    /// summary): latency quantiles, the heaviest sample.
    pub fn shown(&self) -> crate::ledger::Shown {
        self.shared.ledger.lock().expect("ledger").shown.clone()
    }

    /// Job records the ledger holds now (a live session's stay bounded:
    /// `Settings::keep_records`).
    pub fn records_held(&self) -> usize {
        self.shared.ledger.lock().expect("ledger").jobs.len()
    }

    /// The cells the GPU's pages hold, as the last frame left them (16
    /// bytes of cell and 16 of row, g3 and shading vector, each).
    pub fn gpu_cells_held(&self) -> u64 {
        self.shared.gpu_cells.load(Ordering::Acquire)
    }

    /// Frames ended so far (by the front end's [`crate::frames::Frames`]).
    pub fn frames(&self) -> u64 {
        self.shared.frames.load(Ordering::Acquire)
    }

    /// Jobs the stroke thread has finished.
    pub fn jobs_finished(&self) -> usize {
        self.shared.finished_jobs.load(Ordering::Acquire) as usize
    }

    /// Jobs shown by some frame.
    pub fn jobs_shown(&self) -> usize {
        self.shared.ledger.lock().expect("ledger").shown.jobs as usize
    }

    /// Stop taking jobs, let every queued job run and staging copy what is
    /// left; then join the two threads and hand the document back. Frames
    /// may go on uploading what was staged while this waits.
    pub fn finish(self) -> Result<Finished, Panicked> {
        self.shared.jobs.close();
        self.shared.finishing.store(true, Ordering::Release);
        self.stroke.join().map_err(|_| Panicked("stroke"))?;
        let staging = self.staging.join().map_err(|_| Panicked("staging"))?;
        let canvas = self.shared.canvas.lock().expect("canvas").take().expect("taken once");
        let messages = std::mem::take(&mut *self.shared.messages.lock().expect("messages"));
        Ok(Finished { canvas, staging, messages })
    }
}

/// The layer list of `canvas` now.
fn layer_list(canvas: &dyn Canvas) -> LayerList {
    let doc = canvas.document();
    LayerList {
        version: canvas.version(),
        layers: doc.listed_ids().iter().zip(doc.layers()).map(|(&id, l)| Listed { id, visible: l.visible, opacity: l.opacity }).collect(),
    }
}

/// The stroke thread's side of publishing: what changed since the last call.
struct Publisher {
    block: BlockSize,
    /// The layers listed at the last publication: a layer listed again
    /// (a delete or a merge undone) is published whole, since the frames
    /// forget the ranges of layers no longer listed.
    listed: Vec<u32>,
    list: Option<LayerList>,
}

impl Publisher {
    /// Publish every listed layer's changes as publication of job `seq`
    /// (0: the opening), with the layer list when it changed.
    fn publish(&mut self, shared: &Shared, canvas: &mut dyn Canvas, seq: u64) {
        let list = layer_list(canvas);
        let doc = canvas.document_mut();
        let ids = doc.listed_ids().to_vec();
        let mut parts = Vec::new();
        for (k, &id) in ids.iter().enumerate() {
            let tree = &mut doc.layer_mut(k).painting.tree;
            if !self.listed.contains(&id) {
                tree.mark_everything_dirty();
            }
            let p = tree.take_publication();
            if p.blocks.is_empty() && p.mask.count() == 0 {
                continue;
            }
            let mask = rescale(&p.mask, region_cells(tree.capacity), region_cells(shared.size.capacity));
            parts.push((id, p.blocks, mask));
        }
        self.listed = ids;
        let changed = self.list.as_ref() != Some(&list);
        if parts.is_empty() && !changed {
            return;
        }
        let keys: Vec<u64> = parts.iter().flat_map(|(id, blocks, _)| blocks.iter().map(|&b| key(*id, b))).collect();
        let n = shared.ledger.lock().expect("ledger").published(seq, &keys);
        let block = self.block;
        for (id, blocks, mask) in &parts {
            shared.pending.merge(n, *id, |b| group_of(block, b), blocks, mask);
        }
        if changed {
            shared.lists.lock().expect("lists").push_back((n, list.clone()));
            self.list = Some(list);
        }
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

/// The document under the lock (until [`Engine::finish`] takes it).
fn open(guard: &mut Option<Box<dyn Canvas>>) -> &mut dyn Canvas {
    &mut **guard.as_mut().expect("the document is there until the threads end")
}

fn answer(shared: &Shared, asks: Vec<Ask>) {
    if asks.is_empty() {
        return;
    }
    let mut guard = shared.canvas.lock().expect("canvas");
    let canvas = open(&mut guard);
    for a in asks {
        a(canvas);
    }
}

fn stroke_jobs(shared: &Shared, settings: &Settings, hooks: &Hooks) {
    let mut publisher = Publisher { block: settings.block, listed: Vec::new(), list: None };
    publisher.publish(shared, open(&mut shared.canvas.lock().expect("canvas")), 0);
    let mut status_at = Instant::now();
    let say = |m: String| shared.messages.lock().expect("messages").push(m);
    while let Some(work) = shared.jobs.pop() {
        let ticket = match work {
            Work::Ask(a) => {
                answer(shared, vec![a]);
                continue;
            }
            Work::Job(t) => t,
        };
        let seq = ticket.seq;
        {
            let mut l = shared.ledger.lock().expect("ledger");
            l.submitted(seq, ticket.job.name(), ticket.submitted);
            l.started(seq);
        }
        *shared.busy.lock().expect("busy") = Some(Busy { what: ticket.job.name(), since: Instant::now() });
        let mut guard = shared.canvas.lock().expect("canvas");
        if let Some(g) = &hooks.stroke {
            g.pass();
        }
        let t0 = Instant::now();
        let ran = open(&mut guard).run(&ticket.job, ticket.submitted);
        let mut painting_seconds = t0.elapsed().as_secs_f64();
        publisher.publish(shared, open(&mut guard), seq);
        let sample = matches!(ran, Ok(Ran::Sample));
        match ran {
            Ok(Ran::Sample) => loop {
                // Between levels: the lock is free for staging, and
                // questions are answered.
                drop(guard);
                answer(shared, shared.jobs.take_asks());
                guard = shared.canvas.lock().expect("canvas");
                if let Some(g) = &hooks.stroke {
                    g.pass();
                }
                let t0 = Instant::now();
                let done = open(&mut guard).document_mut().stroke_painting().is_none_or(|p| p.advance(settings.strategy.aggressive_units));
                painting_seconds += t0.elapsed().as_secs_f64();
                publisher.publish(shared, open(&mut guard), seq);
                if done {
                    break;
                }
            },
            Ok(Ran::Done) => {}
            Ok(Ran::Said(m)) => say(m),
            Err(e) => say(e),
        }
        let canvas = open(&mut guard);
        for w in canvas.document_mut().take_warnings() {
            say(w);
        }
        // The status after every job but samples, which come by the
        // hundred a second: for them a few times a second.
        if !sample || status_at.elapsed().as_secs_f64() > 0.1 || shared.jobs.is_empty() {
            *shared.status.lock().expect("status") = Status::of(canvas);
            status_at = Instant::now();
        }
        drop(guard);
        *shared.busy.lock().expect("busy") = None;
        {
            let mut l = shared.ledger.lock().expect("ledger");
            if matches!(ticket.job, Job::Sample(_) | Job::Aim(_)) {
                l.painted(seq, painting_seconds);
            }
            l.finished(seq);
        }
        shared.finished_jobs.fetch_add(1, Ordering::AcqRel);
    }
    // Questions asked after the last job are still answered.
    answer(shared, shared.jobs.take_asks());
    shared.pending.close();
}

fn staging_thread(shared: &Shared, settings: &Settings) -> Vec<StagingRecord> {
    let mut records = Vec::new();
    let mut version = 0u64;
    loop {
        if settings.strategy.grouped {
            // Grouped staging: everything pending, taken and copied under one
            // hold of the document's lock: one consistent state.
            if !shared.pending.wait_for_work() {
                break;
            }
            let w0 = Instant::now();
            let mut guard = shared.canvas.lock().expect("canvas");
            let canvas = open(&mut guard);
            let t0 = Instant::now();
            let taken = shared.pending.take_all_now();
            let covered = shared.ledger.lock().expect("ledger").last_pub;
            // The groups are copied in parallel: a heavy sample dirties tens
            // of blocks, and the lock is held until the last is copied (on
            // an H100 host, 16 ms at p99 one after another).
            let doc = canvas.document();
            let staged: Vec<(u64, u64, Vec<GpuCell>)> = taken
                .par_iter()
                .map(|t| {
                    let mut cells = shared.staged.spare();
                    // A layer the history no longer holds: nothing to copy
                    // (its blocks still count as uploaded).
                    let Some(layer) = doc.layer_by_id(t.layer) else { return (0, 0, cells) };
                    let tree = layer.tree();
                    let (first, len) = group_range(settings.block, t.group, tree.n_used());
                    stage_into(tree, first, len, &mut cells);
                    (first, u64::from(tree.n_used()), cells)
                })
                .collect();
            drop(guard);
            let mut copies = Vec::with_capacity(taken.len());
            for (t, (first, length, cells)) in taken.into_iter().zip(staged) {
                version += 1;
                copies.push(StagedCopy {
                    layer: t.layer,
                    group: t.group,
                    first,
                    length,
                    cells,
                    covered_pub: covered,
                    mask: t.mask,
                    blocks: t.blocks,
                    version,
                    staged_at: t0,
                });
            }
            let t1 = Instant::now();
            let cells: u64 = copies.iter().map(|c| c.cells.len() as u64).sum();
            records.push(StagingRecord { cells, seconds: (t1 - t0).as_secs_f64(), wait_seconds: (t0 - w0).as_secs_f64() });
            crate::settings::trim_records(&mut records, settings.keep_records);
            shared.staged.push(StagedItem::Batch(copies));
            continue;
        }
        let Some(t) = shared.pending.take_newest() else { break };
        let mut cells: Vec<GpuCell> = shared.staged.buffer();
        let w0 = Instant::now();
        let mut guard = shared.canvas.lock().expect("canvas");
        let t0 = Instant::now();
        let (mut first, mut len, mut length) = (0, 0, 0);
        if let Some(layer) = open(&mut guard).document().layer_by_id(t.layer) {
            length = u64::from(layer.tree().n_used());
            (first, len) = group_range(settings.block, t.group, layer.tree().n_used());
            stage_into(layer.tree(), first, len, &mut cells);
        }
        // The copy holds every publication recorded so far: the stroke
        // thread records them while it holds this lock.
        let covered = shared.ledger.lock().expect("ledger").last_pub;
        drop(guard);
        let t1 = Instant::now();
        records.push(StagingRecord { cells: len as u64, seconds: (t1 - t0).as_secs_f64(), wait_seconds: (t0 - w0).as_secs_f64() });
        crate::settings::trim_records(&mut records, settings.keep_records);
        version += 1;
        let copy =
            StagedCopy { layer: t.layer, group: t.group, first, length, cells, covered_pub: covered, mask: t.mask, blocks: t.blocks, version, staged_at: t1 };
        shared.staged.push(StagedItem::One(copy));
    }
    shared.staged.close();
    records
}

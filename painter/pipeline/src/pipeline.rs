//! The headless front end of the engine (docs/architecture.md, the paper's
//! Fig. 4): [`Pipeline`] is the engine's stroke and staging threads with a
//! render thread of its own whose frame loop is the benchmark's and the
//! protocol tests': every frame it takes the staged copies
//! ([`crate::frames::Frames`]), casts, and tells the ledger. The window and
//! the headset run the same engine under their own frame loops.
//!
//! Painting never waits for rendering (the pending set merges; the staging
//! thread is the one that waits for buffers) and rendering never waits for
//! painting (it renders whatever is staged, every frame).

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use octopaint_gpu::{GpuError, Renderer};
use octopaint_tree::paint::Painting;
use octopaint_tree::raycast::RayParams;

use crate::canvas::{Canvas, Replay};
use crate::engine::{Engine, Finished, Hooks, Panicked, StagingRecord};
use crate::frames::Frames;
use crate::jobs::{Job, SubmitError, Ticket};
use crate::ledger::Ledger;
use crate::settings::Settings;

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

/// What a finished pipeline hands back.
pub struct Report {
    pub canvas: Box<dyn Canvas>,
    pub ledger: Ledger,
    pub frames: Vec<FrameRecord>,
    pub staging: Vec<StagingRecord>,
    pub renderer: Renderer,
    /// Where each layer's cells lie in the pages, by layer id.
    pub ranges: Vec<(u32, u64, u64)>,
    pub adapter: String,
    /// The publications of the opening (the painting as the pipeline
    /// found it), before the first job's.
    pub opening_pubs: u64,
}

impl Report {
    /// The painting of a one-tree run (the selected layer's).
    pub fn painting(&self) -> &Painting {
        &self.canvas.document().current().painting
    }

    pub fn painting_mut(&mut self) -> &mut Painting {
        &mut self.canvas.document_mut().current_mut().painting
    }
}

#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Panicked(#[from] Panicked),
}

pub struct Pipeline {
    engine: Engine,
    render: JoinHandle<Result<(Renderer, Vec<FrameRecord>, Vec<(u32, u64, u64)>), GpuError>>,
    opening_pubs: u64,
}

impl Pipeline {
    /// Open the GPU and start the threads on a one-tree painting; returns
    /// once the painting as it is has reached the GPU (its upload is not
    /// part of the run).
    pub fn start(painting: Painting, settings: Settings, hooks: Hooks) -> Result<Pipeline, PipelineError> {
        Pipeline::start_on(Box::new(Replay::new(painting)), settings, hooks)
    }

    /// [`Pipeline::start`] on any canvas: a document of layers (a version
    /// 2 trace's, `Replay::of`), an open document.
    pub fn start_on(canvas: Box<dyn Canvas>, settings: Settings, hooks: Hooks) -> Result<Pipeline, PipelineError> {
        let mut renderer = Renderer::new(settings.backend)?;
        let engine = Engine::start(canvas, &settings, &hooks);
        let mut frames = Frames::new(&engine, &settings);
        // The opening, uploaded before the run starts (a fresh engine's
        // first publication covers every listed layer; the stroke thread's
        // gate applies from the first job on).
        loop {
            let prepared = frames.prepare(&mut renderer)?;
            if frames.settled() {
                // One cast, unmeasured: the ray caster's pipeline for this
                // document (one tree or layers) is compiled on first use.
                let params = RayParams::new(&octopaint_tree::lattice::Lattice::new(&engine.shared.size), &settings.camera);
                let mut enc = renderer.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("first cast") });
                Frames::encode_cast(&mut renderer, &mut enc, &params, settings.precision, &prepared)?;
                renderer.gpu.queue.submit([enc.finish()]);
                renderer.gpu.wait();
                break;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        let opening_pubs = engine.shared.ledger.lock().expect("ledger").last_pub;
        let render = {
            let shared = engine.shared.clone();
            let hooks = hooks.clone();
            std::thread::Builder::new().name("render".into()).spawn(move || render_thread(&shared, frames, &settings, &hooks, renderer)).expect("spawn")
        };
        Ok(Pipeline { engine, render, opening_pubs })
    }

    /// Queue a job (waiting while the job queue is full).
    pub fn submit(&self, job: Job) -> Result<Ticket, SubmitError> {
        self.engine.submit(job)
    }

    /// Queue a job if the job queue has room.
    #[expect(clippy::result_large_err, reason = "a refused job is handed back whole, for the caller to keep")]
    pub fn try_submit(&self, job: Job) -> Result<Ticket, (SubmitError, Job)> {
        self.engine.try_submit(job)
    }

    /// Jobs waiting in the job queue.
    pub fn queued(&self) -> usize {
        self.engine.queued()
    }

    /// Frames rendered so far.
    pub fn frames(&self) -> u64 {
        self.engine.frames()
    }

    /// Jobs the stroke thread has finished.
    pub fn jobs_finished(&self) -> usize {
        self.engine.jobs_finished()
    }

    /// Jobs shown by some frame.
    pub fn jobs_shown(&self) -> usize {
        self.engine.jobs_shown()
    }

    /// The engine under this pipeline (status, questions, messages).
    pub fn engine(&self) -> &Engine {
        &self.engine
    }

    /// Stop taking jobs, let every queued job run, every dirty block reach
    /// the GPU and a frame show it all; then join the threads.
    pub fn finish(self) -> Result<Report, PipelineError> {
        let shared = self.engine.shared.clone();
        let Finished { canvas, staging, .. } = self.engine.finish()?;
        let (renderer, frames, ranges) = self.render.join().map_err(|_| Panicked("render"))??;
        let adapter = renderer.gpu.describe();
        let ledger = std::mem::take(&mut *shared.ledger.lock().expect("ledger"));
        Ok(Report { canvas, ledger, frames, staging, renderer, ranges, adapter, opening_pubs: self.opening_pubs })
    }
}

fn render_thread(
    shared: &Arc<crate::engine::Shared>,
    mut frames: Frames,
    settings: &Settings,
    hooks: &Hooks,
    mut r: Renderer,
) -> Result<(Renderer, Vec<FrameRecord>, Vec<(u32, u64, u64)>), GpuError> {
    let mut records = Vec::new();
    let mut index = 0;
    let camera = settings.camera;
    let lat = octopaint_tree::lattice::Lattice::new(&shared.size);
    let mut params = RayParams::new(&lat, &camera);
    params.skip_invalid = settings.strategy.skip_invalid;
    let period = settings.target_hz.map(|hz| Duration::from_secs_f64(1.0 / hz));
    let mut next_deadline = Instant::now();
    loop {
        if let Some(g) = &hooks.render {
            g.pass();
        }
        let start = Instant::now();
        let prepared = frames.prepare(&mut r)?;
        let t_g3 = Instant::now();
        let mut enc = r.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame cast") });
        Frames::encode_cast(&mut r, &mut enc, &params, settings.precision, &prepared)?;
        r.gpu.queue.submit([enc.finish()]);
        let digest = if settings.capture { Some(r.ray.image_digest(&r.gpu, params.width, params.height)?) } else { None };
        r.gpu.wait();
        let end = Instant::now();
        let (shown_jobs, unshown) = frames.ended(end);
        index += 1;
        records.push(FrameRecord {
            index,
            start,
            end,
            uploads: prepared.uploads,
            cells_uploaded: prepared.cells_uploaded,
            regions: prepared.regions,
            cut: prepared.cut,
            newest_uploaded: prepared.newest_uploaded,
            shown_jobs,
            upload_seconds: prepared.upload_seconds,
            g3_seconds: prepared.g3_seconds,
            cast_seconds: (end - t_g3).as_secs_f64(),
            digest,
        });
        crate::settings::trim_records(&mut records, settings.keep_records);
        // Done when asked to finish and everything has reached the screen:
        // no job left unshown, nothing staged, staging closed.
        if shared.finishing.load(Ordering::Acquire) && shared.staged.is_closed() && shared.staged.is_empty() && shared.jobs.is_empty() && unshown == 0 {
            break;
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
    let ranges = frames.ranges();
    Ok((r, records, ranges))
}

//! The VR session (docs/vr.md): set up ([`crate::setup`]: the runtime, the
//! headset's GPU, the swapchain), then a frame loop paced by xrWaitFrame
//! that reads the controllers, turns what they do into jobs for the
//! engine, and draws each eye with its own pose and asymmetric field of
//! view ([`crate::frame`]).
//!
//! The canvas is placed in the room by a similarity transform kept in f64
//! (`Placement`): the runtime's poses (f32 metres) become canvas points in
//! f64, so any zoom of the canvas keeps its precision.
//!
//! macOS has no OpenXR runtime and wgpu has no Vulkan there: the session is
//! not built for it (`run` says so) and the rest is kept type-checked.
#![cfg_attr(target_os = "macos", allow(dead_code, unused_imports))]

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use glam::DVec3;
use octopaint_gpu::{Precision, Renderer};
use octopaint_pipeline::{Doing, Engine, Frames, Hooks, Indicator, Job, OpenDocument, Pace, Settings, View};
use octopaint_tree::lattice::Lattice;
use octopaint_tree::trace::Camera;
use openxr as xr;

use crate::XrError;
use crate::frame::{Drawer, Scene, write_side_by_side};
use crate::gestures::Live;
use crate::placement::{Bounds, Placement, head_of};
use crate::setup::{VIEW_TYPE, other, xr_call};

/// What a session did.
#[derive(Debug, Default)]
pub struct Report {
    pub frames: u64,
    pub eye_size: [u32; 2],
    pub format: String,
    /// Wall time between successive xrWaitFrame returns (ms): mean, max,
    /// median and 99th percentile.
    pub frame_ms: (f64, f64),
    pub frame_p50_p99_ms: (f64, f64),
    /// GPU work of a frame (both eyes), submit to done (ms): mean.
    pub render_ms: f64,
    /// Dynamic resolution: the share of the eye's width and height cast,
    /// mean and smallest over the frames; the frames that changed nothing,
    /// and of those the ones that cast nothing (each eye's last cast drawn
    /// again).
    pub scale: (f64, f64),
    pub still_frames: u64,
    pub reused_frames: u64,
    /// Strokes painted with the controllers.
    pub strokes: u64,
    pub adapter: String,
    /// Why the save at the session's end failed (every completed stroke
    /// is in the journal still).
    pub save_error: Option<String>,
}

pub struct Options {
    pub frames: Option<u64>,
    pub precision: Precision,
    /// Write the last frame's two eyes side by side here (PNG), read back
    /// from the runtime's swapchain image.
    pub capture: Option<PathBuf>,
    /// Scripted controller states that replace the controllers'
    /// (`input::Script`).
    pub script: Option<PathBuf>,
    /// Cast every frame at the eye's full size (no dynamic resolution).
    pub fixed_resolution: bool,
    /// Play this trace's jobs into the document at their pace from the
    /// first frame on (`octopaint_pipeline::play`); `frames` counts on
    /// until every one of them is queued.
    pub play: Option<PathBuf>,
    /// Tests: while this file exists the stroke thread waits before each
    /// level of painting.
    pub hold_painting: Option<PathBuf>,
    /// Write one CSV line per frame here (the window's frame log,
    /// docs/desktop.md).
    pub frame_log: Option<PathBuf>,
    /// The level of detail of both eyes (docs/spec.md 7): rays stop at
    /// cells no wider than this many pixels' footprints; 0: at the leaves.
    pub lod: f64,
}

/// The time both eyes' ray casts aim at: one frame of a 90 Hz headset.
pub const TARGET_FRAME_MS: f64 = octopaint_pipeline::view::HEADSET_TARGET_MS;

/// macOS: no VR (crate::platform::NO_VR_HERE says why).
#[cfg(target_os = "macos")]
pub fn run(_doc: octopaint_doc::Session, _opts: &Options) -> Result<Report, XrError> {
    Err(XrError::Unsupported(crate::platform::NO_VR_HERE))
}

/// Run a VR session on the document `doc` until the runtime ends it or
/// `frames` frames have been shown, then save it. The frame loop is the
/// render thread of the real-time engine (docs/architecture.md): the
/// controllers' strokes and layer operations are jobs for its stroke
/// thread, which owns the document, and each frame uploads what was
/// staged and casts both eyes; nothing on the frame's thread waits for
/// painting or saving. Refused before the engine starts (no runtime, no
/// headset), the document is dropped unchanged.
#[cfg(not(target_os = "macos"))]
pub fn run(doc: octopaint_doc::Session, opts: &Options) -> Result<Report, XrError> {
    let script = match &opts.script {
        Some(p) => Some(crate::input::Script::load(p)?),
        None => None,
    };
    let to_play = match &opts.play {
        Some(p) => Some(octopaint_pipeline::play::read(p, &doc).map_err(|e| other("the trace to play", e))?),
        None => None,
    };
    let view = View::new(TARGET_FRAME_MS, Pace::Measured, opts.fixed_resolution, opts.frame_log.as_deref()).map_err(XrError::Setup)?;
    let opened = crate::setup::open(opts.precision)?;
    let adapter = opened.gpu.describe();
    let renderer = Renderer::with_gpu(opened.gpu).map_err(|e| other("the renderer", e))?;
    let (xr_instance, system) = (opened.xr_instance, opened.system);
    // SAFETY: the session is made with the instance and device created
    // for this system, which outlive it (the renderer holds them).
    let (session, waiter, stream) = unsafe { xr_call("creating the session", xr_instance.create_session::<xr::Vulkan>(system, &opened.session_info))? };
    let stage = xr_call("creating the reference space", session.create_reference_space(xr::ReferenceSpaceType::LOCAL, xr::Posef::IDENTITY))?;
    let controls = crate::input::Controls::new(&xr_instance, &session)?;
    let configs = xr_call("reading the views", xr_instance.enumerate_view_configuration_views(system, VIEW_TYPE))?;
    let size = [configs[0].recommended_image_rect_width, configs[0].recommended_image_rect_height];
    let eyes = crate::setup::Eyes::create(&session, &renderer.gpu, size)?;
    // The artist's presets, as the window keeps them (read only here); a
    // file that cannot be read leaves the starting set, and says so.
    let presets = octopaint_doc::presets::Presets::open(octopaint_doc::presets::default_path());
    if let Some(e) = &presets.blocked {
        eprintln!("octopaint: {e}");
    }
    let mut painter = crate::gestures::Gestures::default();
    painter.presets = presets.list;
    if let Some(m) = doc.mirror() {
        painter.mirror = m;
    }
    // Where the painting is placed first, and the lattice the eyes are cast
    // on, before the document goes to the stroke thread.
    let bounds = Bounds::shown(&doc.doc);
    let drawer = Drawer::new(&renderer, &eyes, Lattice::new(doc.doc.canvas()), opts.precision, opts.lod, view);
    let mut settings = Settings::new(Camera { eye: [0.0; 3], q: [0.0, 0.0, 0.0, 1.0], fov: [-0.5, 0.5, 0.5, -0.5], size: [64, 64], background: [0.0; 3] });
    // A session of hours: the engine's records stay a few seconds long.
    settings.keep_records = Some(octopaint_pipeline::settings::LIVE_RECORDS);
    let gate = opts.hold_painting.as_ref().map(|_| Arc::new(octopaint_pipeline::Gate::default()));
    let engine = Engine::start(Box::new(OpenDocument::new(doc)), &settings, &Hooks { render: None, stroke: gate.clone() });
    let hold = opts.hold_painting.clone().zip(gate).map(|(path, gate)| octopaint_pipeline::play::hold_while(path, gate));
    let mut report = Report { eye_size: size, format: format!("{:?}", eyes.format), adapter, ..Default::default() };
    let frames = Frames::new(&engine, &settings);
    let status = engine.status();
    let mut lp = Loop {
        waiter,
        stream,
        eyes,
        stage,
        controls,
        session,
        renderer,
        drawer,
        frames,
        engine,
        opts,
        xr_instance: &xr_instance,
        blend: opened.blend,
        script,
        painter,
        status,
        bounds,
        placement: None,
        head0: DVec3::ZERO,
        last_input: Instant::now(),
        reframing: None,
        to_play,
        playing: None,
        running: false,
        exit_requested: false,
        last_wait: None,
        waits_ms: Vec::new(),
        gpu_sum_ms: 0.0,
    };
    let result = lp.frames(&mut report);
    // The session's end: a test's hold lets go, the open stroke ends, and
    // the document is saved on the stroke thread; ending waits for it, and
    // says so.
    if let Some(stop) = &hold {
        stop.store(true, Ordering::Release);
    }
    lp.painter.finish(&Live { engine: &lp.engine, status: &lp.status });
    let engine = lp.engine;
    if let Some(summary) = octopaint_pipeline::view::latency_summary(&engine) {
        eprintln!("octopaint: vr: {summary}");
    }
    let _ = engine.submit(Job::Save);
    eprintln!("octopaint: vr: saving the document…");
    let finished = engine.finish().map_err(|e| other("the engine", e))?;
    for m in finished.messages {
        if m.starts_with("save failed") {
            report.save_error = Some(m);
        } else {
            eprintln!("octopaint: vr: {m}");
        }
    }
    result?;
    report.strokes = lp.painter.strokes;
    if let Some(e) = &lp.painter.last_error {
        eprintln!("octopaint: vr: an input event was refused: {e}");
    }
    let waits = octopaint_pipeline::FrameStats::of_intervals(std::mem::take(&mut lp.waits_ms));
    report.frame_ms = waits.interval_mean_max();
    report.frame_p50_p99_ms = (waits.interval_quantile(0.5), waits.interval_quantile(0.99));
    let stats = &lp.drawer.view.stats;
    if report.frames > 0 {
        report.render_ms = lp.gpu_sum_ms / report.frames as f64;
    }
    report.scale = stats.scale();
    report.still_frames = stats.still_frames;
    report.reused_frames = stats.frames - stats.cast_frames;
    Ok(report)
}

/// The frame loop's state: the runtime's session, what the frames draw
/// with, the engine, the controllers' painter, and the playback. Fields
/// drop in order: the runtime's objects (the swapchain's textures, the
/// spaces, the session) before the device they were made with (the
/// renderer's), whichever way the session ends.
#[cfg(not(target_os = "macos"))]
struct Loop<'a> {
    waiter: xr::FrameWaiter,
    stream: xr::FrameStream<xr::Vulkan>,
    eyes: crate::setup::Eyes,
    stage: xr::Space,
    controls: crate::input::Controls,
    session: xr::Session<xr::Vulkan>,
    renderer: Renderer,
    drawer: Drawer,
    frames: Frames,
    engine: Engine,
    opts: &'a Options,
    xr_instance: &'a xr::Instance,
    blend: xr::EnvironmentBlendMode,
    script: Option<crate::input::Script>,
    painter: crate::gestures::Gestures,
    /// What the stroke thread published last.
    status: octopaint_pipeline::Status,
    bounds: Bounds,
    placement: Option<Placement>,
    /// The head where the first frame found it (scripts move from there).
    head0: DVec3,
    last_input: Instant,
    /// The answer to "frame the painting" (X with the left grip), when asked.
    reframing: Option<std::sync::mpsc::Receiver<Bounds>>,
    to_play: Option<Vec<(f64, Job)>>,
    playing: Option<Arc<AtomicBool>>,
    running: bool,
    exit_requested: bool,
    last_wait: Option<Instant>,
    waits_ms: Vec<f64>,
    gpu_sum_ms: f64,
}

#[cfg(not(target_os = "macos"))]
impl Loop<'_> {
    /// Frames until the runtime ends the session (or `--frames` were
    /// shown and the trace played is queued).
    fn frames(&mut self, report: &mut Report) -> Result<(), XrError> {
        let mut events = xr::EventDataBuffer::new();
        loop {
            while let Some(ev) = xr_call("polling events", self.xr_instance.poll_event(&mut events))? {
                match ev {
                    xr::Event::SessionStateChanged(e) => match e.state() {
                        xr::SessionState::READY => {
                            xr_call("beginning the session", self.session.begin(VIEW_TYPE))?;
                            self.running = true;
                        }
                        xr::SessionState::STOPPING => {
                            xr_call("ending the session", self.session.end())?;
                            self.running = false;
                        }
                        xr::SessionState::EXITING | xr::SessionState::LOSS_PENDING => return Ok(()),
                        _ => {}
                    },
                    xr::Event::InstanceLossPending(_) => return Ok(()),
                    _ => {}
                }
            }
            if !self.running {
                std::thread::sleep(std::time::Duration::from_millis(10));
                continue;
            }
            let played = self.to_play.is_none() && self.playing.as_ref().is_none_or(|done| done.load(Ordering::Acquire));
            if self.opts.frames.is_some_and(|n| report.frames >= n) && played && !self.exit_requested {
                xr_call("requesting the end", self.session.request_exit())?;
                self.exit_requested = true;
            }
            self.frame(report)?;
        }
    }

    /// One frame: wait for it, read the controllers, draw both eyes, end it.
    fn frame(&mut self, report: &mut Report) -> Result<(), XrError> {
        let state = xr_call("waiting for the frame", self.waiter.wait())?;
        if let Some(t) = self.last_wait {
            self.waits_ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
        self.last_wait = Some(Instant::now());
        xr_call("beginning the frame", self.stream.begin())?;
        if !state.should_render || self.exit_requested {
            return xr_call("ending the frame", self.stream.end(state.predicted_display_time, self.blend, &[]));
        }
        let (_, views) = xr_call("locating the views", self.session.locate_views(VIEW_TYPE, state.predicted_display_time, &self.stage))?;
        let hands = self.input(&views, state.predicted_display_time, report.frames)?;
        let doing = Doing::of(&self.engine);
        let busy = Indicator::of(&self.engine, TARGET_FRAME_MS);
        // What the frame uploads: what the engine staged, into each
        // layer's range of the pages.
        let prepared = self.frames.prepare(&mut self.renderer).map_err(|e| other("uploading", e))?;
        let image = xr_call("acquiring the image", self.eyes.swapchain.acquire_image())? as usize;
        xr_call("waiting for the image", self.eyes.swapchain.wait_image(xr::Duration::INFINITE))?;
        let capture = self.opts.capture.is_some() && self.opts.frames.is_some_and(|n| report.frames + 1 == n);
        let placement = self.placement.expect("placed by the input");
        let scene = Scene {
            views: &views,
            hands: &hands,
            painter: &self.painter,
            placement: &placement,
            status: &self.status,
            busy,
            doing,
            prepared: &prepared,
            capture,
        };
        let drawn = self.drawer.draw(&mut self.renderer, &self.eyes, image, &scene)?;
        self.frames.ended(Instant::now());
        self.gpu_sum_ms += drawn.gpu_ms;
        xr_call("releasing the image", self.eyes.swapchain.release_image())?;
        let size = self.eyes.size;
        let rect = xr::Rect2Di { offset: xr::Offset2Di { x: 0, y: 0 }, extent: xr::Extent2Di { width: size[0] as i32, height: size[1] as i32 } };
        let proj: Vec<xr::CompositionLayerProjectionView<xr::Vulkan>> = (0..2)
            .map(|eye| {
                xr::CompositionLayerProjectionView::new()
                    .pose(views[eye].pose)
                    .fov(views[eye].fov)
                    .sub_image(xr::SwapchainSubImage::new().swapchain(&self.eyes.swapchain).image_array_index(eye as u32).image_rect(rect))
            })
            .collect();
        xr_call(
            "ending the frame",
            self.stream.end(state.predicted_display_time, self.blend, &[&xr::CompositionLayerProjection::new().space(&self.stage).views(&proj)]),
        )?;
        report.frames += 1;
        if let Some(jobs) = self.to_play.take() {
            self.playing = Some(octopaint_pipeline::play::start(self.engine.submitter(), jobs));
        }
        if let (Some(path), Some(captured)) = (&self.opts.capture, &drawn.captured) {
            write_side_by_side(path, captured, size).map_err(|e| other("writing the capture", e))?;
        }
        Ok(())
    }

    /// The controllers (or the script) change the painting and the
    /// canvas's place before the frame is drawn; what the stroke thread
    /// published and said is read first.
    fn input(&mut self, views: &[xr::View], at: xr::Time, frame: u64) -> Result<[crate::input::Hand; 2], XrError> {
        // The canvas is placed in front of the head where it first is.
        if self.placement.is_none() {
            let (head, forward) = head_of(views);
            self.head0 = head;
            self.placement = Some(Placement::around(&self.bounds, head, forward));
        }
        self.status = self.engine.status();
        for m in self.engine.take_messages() {
            eprintln!("octopaint: vr: {m}");
            self.painter.last_error = Some(m);
        }
        let hands = match self.script.as_mut() {
            Some(s) => {
                // Real actions are still synced: the runtime sees an
                // application that reads its controllers.
                self.controls.read(&self.session, &self.stage, at)?;
                s.at(frame, self.head0)
            }
            None => self.controls.read(&self.session, &self.stage, at)?,
        };
        let dt = self.last_input.elapsed().as_secs_f64();
        self.last_input = Instant::now();
        let place = self.placement.as_mut().expect("placed above");
        self.painter.update(&hands, place, &Live { engine: &self.engine, status: &self.status }, dt);
        if std::mem::take(&mut self.painter.reframe) {
            // Frame the painting: asked of the stroke thread, placed in
            // front of the head where it is when the answer comes.
            let (tx, rx) = std::sync::mpsc::channel();
            if self
                .engine
                .ask(move |c| {
                    let _ = tx.send(Bounds::shown(c.document()));
                })
                .is_ok()
            {
                self.reframing = Some(rx);
            }
        }
        if let Some(b) = self.reframing.as_ref().and_then(|rx| rx.try_recv().ok()) {
            let (head, forward) = head_of(views);
            *place = Placement::around(&b, head, forward);
            self.reframing = None;
        }
        Ok(hands)
    }
}

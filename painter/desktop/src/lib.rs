//! The desktop window (docs/desktop.md): the GPU ray caster drawn into a
//! winit window, painting with the mouse on a document (every stroke
//! journalled as it ends), an orbit and fly camera, an egui panel for the
//! brush and a status line with frame rate, latency, cells, memory and
//! budget.
//!
//! The window is a front end of the real-time engine (`octopaint_pipeline`,
//! docs/architecture.md): the stroke thread owns the document (journal,
//! layers, undo, saves) and paints it level by level, the staging thread
//! copies what changed, and the event loop is the render thread: each frame
//! uploads what was staged, casts and presents, and never waits for
//! painting or saving.
//!
//! | module | what it holds |
//! | --- | --- |
//! | [`app`] | the window's state, input becoming jobs, the event loop's pacing |
//! | [`frame`] | one frame: uploads, the cast (or none when still), the panel, presenting |
//! | [`panel`] | the brush, lighting and layers panel, the status line |
//! | [`brush`] | the brush and the light as the panel edits them |
//! | [`overlay`] | the brush cursor, mirror planes, axes and scale over the view |

mod app;
mod brush;
mod frame;
mod overlay;
mod panel;

use std::path::PathBuf;

use octopaint_doc::Session;
use octopaint_gpu::Precision;
use octopaint_pipeline::{Engine, Gate, Hooks, OpenDocument, Settings, play};
use octopaint_tree::lattice::Lattice;
use winit::event_loop::EventLoop;

pub use octopaint_pipeline::view::WINDOW_TARGET_MS as TARGET_FRAME_MS;

/// What `octopaint window` was asked for.
pub struct Options {
    pub doc: PathBuf,
    pub size: [u32; 2],
    pub precision: Precision,
    /// Where F12 writes the window's picture (PNG).
    pub screenshot: PathBuf,
    /// Cast every frame at the window's full size (no dynamic resolution).
    pub fixed_resolution: bool,
    /// Write one CSV line per frame here: time, frame interval, resolution
    /// scale, cast size, whether the view was still, the mirror planes,
    /// whether rays were cast.
    pub frame_log: Option<PathBuf>,
    /// Feed this trace's events through the engine at the trace's pace
    /// (a timelapse of a session; tests and benchmarks drive the window
    /// with it).
    pub play: Option<PathBuf>,
    /// Close the window (saving) once the trace has played and painted.
    pub exit_after_play: bool,
    /// While this file exists, the stroke thread waits before each level
    /// (tests: frames must go on while painting is held).
    pub hold_painting: Option<PathBuf>,
    /// The level of detail the window starts at (docs/spec.md 7; the
    /// panel changes it): rays stop at cells no wider than this many
    /// pixels' footprints, 0 walks them to the leaves. None: 1 on a GPU,
    /// 0 on a CPU Vulkan (lavapipe), where the cut's walk costs more than
    /// it saves (docs/benchmarks.md "Level of detail").
    pub lod: Option<f64>,
}

/// Open the window on `opts.doc` and run until it is closed (closing saves).
pub fn run(opts: Options) -> Result<(), String> {
    let session = Session::open(&opts.doc).map_err(|e| e.to_string())?;
    if session.recovered > 0 {
        eprintln!("octopaint: {}: recovered {} unsaved stroke(s) from its journal", opts.doc.display(), session.recovered);
    }
    let played = match &opts.play {
        Some(p) => Some(play::read(p, &session)?),
        None => None,
    };
    let event_loop = EventLoop::new().map_err(|e| format!("cannot open a window ({e}); is there a display (DISPLAY or WAYLAND_DISPLAY)?"))?;
    let first_camera = app::frame_document(&session.doc);
    let lattice = Lattice::new(session.doc.canvas());
    let mut settings = Settings::new(first_camera.camera([64, 64], octopaint_tree::view::BACKGROUND));
    // A session of hours: the engine's records stay a few seconds long.
    settings.keep_records = Some(octopaint_pipeline::settings::LIVE_RECORDS);
    let gate = opts.hold_painting.as_ref().map(|_| std::sync::Arc::new(Gate::default()));
    let engine = Engine::start(Box::new(OpenDocument::new(session)), &settings, &Hooks { render: None, stroke: gate.clone() });
    let mut app = app::App::new(opts, engine, settings, lattice, first_camera);
    if let (Some(path), Some(gate)) = (app.opts.hold_painting.clone(), gate) {
        app.hold_stop = Some(play::hold_while(path, gate));
    }
    // Played from the first frame presented on (the window's first cast
    // compiles the ray caster: seconds on a CPU).
    app.to_play = played;
    let run = event_loop.run_app(&mut app).map_err(|e| e.to_string());
    if let Some(stop) = &app.hold_stop {
        stop.store(true, std::sync::atomic::Ordering::Release);
    }
    // The engine finishes whatever is queued (the close queued a save).
    // (It has run them: the window closes once it is idle.)
    let engine = app.engine.take().expect("the engine runs until the window closes");
    if let Some(summary) = octopaint_pipeline::view::latency_summary(&engine) {
        eprintln!("octopaint: {summary}");
    }
    let finished = engine.finish().map_err(|e| e.to_string());
    for m in finished.as_ref().map(|f| f.messages.clone()).unwrap_or_default() {
        app.note(m);
    }
    finished?;
    run?;
    match (app.error, app.save_failed) {
        (Some(e), _) => Err(e),
        (None, Some(m)) => Err(format!("{m} (every completed stroke is in the journal)")),
        (None, None) => Ok(()),
    }
}

//! The window's state and its input (docs/desktop.md): the winit event
//! loop is the render thread of the engine (docs/architecture.md). Input
//! becomes jobs for the stroke thread, which owns the document; what the
//! window needs of the painting it reads from the engine's status or asks
//! (the surface under the cursor, the view that frames the painting); a
//! frame only uploads what was staged, casts and presents ([`crate::frame`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::{Duration, Instant};

use glam::DVec3;
use octopaint_doc::presets::Presets;
use octopaint_gpu::{Blit, Gpu, Renderer};
use octopaint_pipeline::{Aim, Engine, Frames, Job, Pace, Settings, Status, View};
use octopaint_tree::Tree;
use octopaint_tree::lattice::Lattice;
use octopaint_tree::layers::Document;
use octopaint_tree::trace::{Brush, EventKind, Mode, Shape};
use octopaint_tree::view::{OrbitCamera, frame_painting, frame_trees, pick};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::keyboard::{Key, ModifiersState, NamedKey};
use winit::window::{Window, WindowId};

use crate::Options;
use crate::brush::{BrushUi, LightUi};
use crate::panel::{Action, LayersUi};

/// The shortest interval between frames while the window waits for the
/// painting (a heavy stroke in progress): it polls, it does not spin.
const POLL: Duration = Duration::from_millis(15);

/// What the window's view is made of, compared frame to frame to tell a
/// still frame: the camera, the window's size, the grid, the light, the level of detail.
pub(crate) type Look = (OrbitCamera, [u32; 2], bool, Option<octopaint_tree::trace::Light>, f64);

pub(crate) struct Running {
    pub window: Arc<Window>,
    pub surface: wgpu::Surface<'static>,
    pub config: wgpu::SurfaceConfiguration,
    pub renderer: Renderer,
    pub frames: Frames,
    pub blit: Blit,
    pub egui_ctx: egui::Context,
    pub egui_state: egui_winit::State,
    pub egui_renderer: egui_wgpu::Renderer,
    pub camera: OrbitCamera,
    pub brush: BrushUi,
    /// The artist's brush presets (docs/desktop.md "Brush presets").
    pub presets: Presets,
    /// The status line's last message.
    pub message: String,
    pub modifiers: ModifiersState,
    pub cursor: (f64, f64),
    pub painting: bool,
    pub orbiting: bool,
    pub want_screenshot: bool,
    /// Dynamic resolution, still frames, the frame log and statistics.
    pub view: View<Look>,
    pub layers: LayersUi,
    /// egui asked for another frame (an animation, a hover).
    pub egui_wants: bool,
    /// When the last frame began.
    pub last_frame: Instant,
}

pub(crate) struct App {
    pub opts: Options,
    pub engine: Option<Engine>,
    pub settings: Settings,
    pub lattice: Lattice,
    /// What the stroke thread published last.
    pub status: Status,
    pub running: Option<Running>,
    pub error: Option<String>,
    /// The view the window opens with (framing the painting as opened).
    pub first_camera: OrbitCamera,
    /// A close was asked: the save is queued, frames go on until the
    /// engine has run it.
    pub closing: Option<Instant>,
    /// The answer to "frame the painting" (F), when asked.
    pub framed: Option<Receiver<OrbitCamera>>,
    /// The surface under the cursor: answers to the questions asked, the
    /// last answer, and whether a question is out.
    pub picks: (Sender<(Aim, Option<f64>)>, Receiver<(Aim, Option<f64>)>),
    pub surface: Option<(Aim, Option<f64>)>,
    pub asking: bool,
    /// `--play`: the trace's jobs until the first frame is presented, then
    /// whether the thread feeding them is done.
    pub to_play: Option<Vec<(f64, Job)>>,
    pub playing: Option<Arc<AtomicBool>>,
    /// `--hold-painting`: the watcher's stop flag.
    pub hold_stop: Option<Arc<AtomicBool>>,
    /// The last save's failure, until a save succeeds.
    pub save_failed: Option<String>,
}

/// The view that frames everything shown: the visible layers of a document
/// of layers, the selected tree otherwise.
pub(crate) fn frame_document(doc: &Document) -> OrbitCamera {
    let shown: Vec<&Tree> = doc.layers().filter(|l| l.contributes()).map(|l| l.tree()).collect();
    if shown.is_empty() { frame_painting(doc.current().tree()) } else { frame_trees(&shown) }
}

impl App {
    pub fn new(opts: Options, engine: Engine, settings: Settings, lattice: Lattice, first_camera: OrbitCamera) -> App {
        let status = engine.status();
        App {
            opts,
            engine: Some(engine),
            settings,
            lattice,
            status,
            running: None,
            error: None,
            first_camera,
            closing: None,
            framed: None,
            picks: channel(),
            surface: None,
            asking: false,
            to_play: None,
            playing: None,
            hold_stop: None,
            save_failed: None,
        }
    }

    /// A line from the stroke thread: printed, shown in the status line,
    /// and a save's outcome remembered (closing on a failed save says so).
    pub fn note(&mut self, m: String) {
        eprintln!("octopaint: {m}");
        if m.starts_with("save failed") {
            self.save_failed = Some(m.clone());
        } else if m.starts_with("saved ") {
            self.save_failed = None;
        }
        if let Some(r) = self.running.as_mut() {
            r.message = m;
        }
    }

    /// Hand a job to the stroke thread (waiting while its queue is full:
    /// input is never dropped).
    pub fn submit(&mut self, job: Job) {
        let Some(engine) = &self.engine else { return };
        if let Err(e) = engine.submit(job)
            && let Some(r) = self.running.as_mut()
        {
            r.message = e.to_string();
        }
    }

    /// Whether `--play` is still feeding its trace (or waits for the
    /// first frame to start).
    pub fn is_playing(&self) -> bool {
        self.to_play.is_some() || self.playing.as_ref().is_some_and(|done| !done.load(Ordering::Acquire))
    }

    /// The ray under the cursor, as the stroke thread places a sample on it.
    pub fn aim(r: &Running) -> Aim {
        let (eye, dir) = r.camera.ray([r.config.width, r.config.height], r.cursor.0, r.cursor.1);
        let forward = r.camera.rotation() * DVec3::NEG_Z;
        let plane_t = r.brush.plane_depth / dir.dot(forward).max(1e-6);
        Aim { eye: eye.to_array(), dir: dir.to_array(), plane_t, on_surface: r.brush.on_surface }
    }

    /// The brush's point under the cursor for the overlay: the last
    /// surface the stroke thread found under the cursor (asked again when
    /// the ray moved), or the plane.
    pub fn brush_point(&mut self) -> Option<(DVec3, DVec3, f64)> {
        while let Ok(answer) = self.picks.1.try_recv() {
            self.surface = Some(answer);
            self.asking = false;
        }
        let r = self.running.as_ref()?;
        let aim = App::aim(r);
        if aim.on_surface && !self.asking && self.surface.is_none_or(|(a, _)| a != aim) {
            let tx = self.picks.0.clone();
            let asked = self.engine.as_ref().is_some_and(|e| {
                e.ask(move |c| {
                    let depth = pick(c.document().current().tree(), DVec3::from_array(aim.eye), DVec3::from_array(aim.dir));
                    let _ = tx.send((aim, depth));
                })
                .is_ok()
            });
            self.asking = asked;
        }
        let depth = if aim.on_surface { self.surface.and_then(|(_, d)| d).unwrap_or(aim.plane_t) } else { aim.plane_t };
        Some((DVec3::from_array(aim.eye), DVec3::from_array(aim.dir), depth))
    }

    fn begin_stroke(&mut self) {
        if self.is_playing() || self.closing.is_some() {
            return;
        }
        let Some(r) = self.running.as_mut() else { return };
        r.painting = true;
        let brush = octopaint_tree::trace::Brush { mirror: r.brush.mirror(), ..r.brush.brush() };
        self.submit(Job::BeginStroke(brush));
        self.sample();
    }

    fn sample(&mut self) {
        let Some(r) = self.running.as_ref() else { return };
        let aim = App::aim(r);
        self.submit(Job::Aim(aim));
    }

    fn end_stroke(&mut self) {
        let Some(r) = self.running.as_mut() else { return };
        if std::mem::take(&mut r.painting) {
            self.submit(Job::EndStroke);
        }
    }

    /// Back to the view that frames everything painted (F, the Frame
    /// button): asked of the stroke thread, taken when it answers.
    pub fn frame_view(&mut self) {
        let (tx, rx) = channel();
        if self.engine.as_ref().is_some_and(|e| {
            e.ask(move |c| {
                let _ = tx.send(frame_document(c.document()));
            })
            .is_ok()
        }) {
            self.framed = Some(rx);
        }
    }

    /// Save on the stroke thread at the stroke's end; frames go on.
    pub fn save(&mut self) {
        self.end_stroke();
        self.submit(Job::Save);
        if let Some(r) = self.running.as_mut() {
            r.message = "saving…".into();
        }
    }

    /// Close: the stroke ends, the document is saved, and the window
    /// closes once the stroke thread has run every job (it says so).
    pub fn close(&mut self) {
        if self.closing.is_some() {
            return;
        }
        self.save();
        self.closing = Some(Instant::now());
        if let Some(r) = self.running.as_mut() {
            r.message = "saving before closing…".into();
        }
    }

    pub fn act(&mut self, a: Action) {
        match a {
            Action::Undo => self.submit(Job::Undo),
            Action::Redo => self.submit(Job::Redo),
            Action::Save => self.save(),
            Action::Frame => self.frame_view(),
            Action::MirrorHere => {
                if let Some(r) = self.running.as_mut() {
                    r.brush.mirror_centre = r.camera.target;
                }
            }
            Action::Screenshot => {
                if let Some(r) = self.running.as_mut() {
                    r.want_screenshot = true;
                }
            }
            Action::MakeLayers => self.submit(Job::UseLayers),
            Action::Layer(op) => self.submit(Job::Event(EventKind::Layer(op))),
            Action::ApplyPreset(name) => {
                if let Some(r) = self.running.as_mut()
                    && let Some(p) = r.presets.list.iter().find(|p| p.name == name)
                {
                    r.brush.apply(&p.brush);
                    r.brush.preset = name;
                }
            }
            Action::SavePreset(name) => {
                if let Some(r) = self.running.as_mut() {
                    let brush = r.brush.brush();
                    r.message = match r.presets.put(&name, brush) {
                        Ok(()) => format!("preset {name:?} saved"),
                        Err(e) => format!("preset not saved: {e}"),
                    };
                }
            }
            Action::DeletePreset(name) => {
                if let Some(r) = self.running.as_mut() {
                    r.message = match r.presets.delete(&name) {
                        Ok(()) => format!("preset {name:?} deleted"),
                        Err(e) => format!("preset not deleted: {e}"),
                    };
                }
            }
        }
    }

    /// Whether another frame is wanted: the painting is changing or about
    /// to, the last cast was not of the still view at full size, egui
    /// animates, a question is out, a trace plays, or the window closes.
    fn wants_frame(&self) -> bool {
        let Some(r) = &self.running else { return false };
        let engine_busy = self.engine.as_ref().is_some_and(|e| !e.idle());
        self.closing.is_some()
            || engine_busy
            || !r.frames.settled()
            || !r.view.settled()
            || r.egui_wants
            || self.asking
            || self.framed.is_some()
            || self.is_playing()
    }

    fn start_window(&mut self, event_loop: &ActiveEventLoop) -> Result<Running, String> {
        let [w, h] = self.opts.size;
        let attrs =
            Window::default_attributes().with_title(format!("octopaint: {}", self.opts.doc.display())).with_inner_size(winit::dpi::PhysicalSize::new(w, h));
        let window = Arc::new(event_loop.create_window(attrs).map_err(|e| format!("cannot create a window: {e}"))?);
        let mut desc = wgpu::InstanceDescriptor::new_with_display_handle(Box::new(event_loop.owned_display_handle()));
        desc.backends = wgpu::Backends::VULKAN | wgpu::Backends::GL;
        let instance = wgpu::Instance::new(desc);
        let surface = instance.create_surface(window.clone()).map_err(|e| format!("cannot draw into the window: {e}"))?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
            apply_limit_buckets: false,
        }))
        .map_err(|e| format!("no GPU adapter can draw into the window: {e}"))?;
        let gpu = Gpu::from_adapter(&adapter).map_err(|e| e.to_string())?;
        if !gpu.supports(self.opts.precision) {
            return Err(format!("{} has no SHADER_F16 for --precision f16", gpu.describe()));
        }
        eprintln!("octopaint: window on {}", gpu.describe());
        let renderer = Renderer::with_gpu(gpu).map_err(|e| e.to_string())?;
        let caps = surface.get_capabilities(&adapter);
        let format = caps.formats.iter().copied().find(|f| !f.is_srgb()).unwrap_or(caps.formats[0]);
        let size = window.inner_size();
        let mut config =
            surface.get_default_config(&adapter, size.width.max(1), size.height.max(1)).ok_or("the window's surface is not supported by the adapter")?;
        config.format = format;
        config.present_mode = wgpu::PresentMode::AutoVsync;
        config.desired_maximum_frame_latency = 2;
        let device = &renderer.gpu.device;
        surface.configure(device, &config);
        let blit = Blit::new(&renderer.gpu, format);
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(egui_ctx.clone(), egui::ViewportId::ROOT, &window, Some(window.scale_factor() as f32), None, None);
        let egui_renderer = egui_wgpu::Renderer::new(device, format, egui_wgpu::RendererOptions::default());
        let camera = self.first_camera;
        let cpu = renderer.gpu.info.device_type == wgpu::DeviceType::Cpu;
        let brush = BrushUi {
            shape: Shape::Sphere,
            mode: Mode::Paint,
            radius: camera.distance * 0.03,
            opacity: 0.8,
            hardness: 0.6,
            colour: [0.9, 0.45, 0.15],
            on_surface: true,
            plane_depth: camera.distance,
            grid: true,
            // Lit at first on a GPU; a CPU Vulkan (lavapipe) casts a lit
            // frame about five times slower (docs/benchmarks.md), so there
            // the window starts unlit and L lights it.
            light: LightUi { on: !cpu, ..LightUi::default() },
            mirror_axes: [false; 3],
            mirror_centre: camera.target,
            // The cut at 1 on a GPU; on lavapipe its walk costs about 1.5x
            // where it trims nothing (docs/benchmarks.md), so there the
            // window starts at full depth and the panel turns it on.
            lod: self.opts.lod.unwrap_or(if cpu { 0.0 } else { octopaint_tree::raycast::DEFAULT_LOD }),
            rest: Brush::new(Shape::Sphere, Mode::Paint, 1.0, [0.0; 3], 1.0, 0.5),
            preset: String::new(),
        };
        let presets = Presets::open(octopaint_doc::presets::default_path());
        let frames = Frames::new(self.engine.as_ref().expect("the engine runs until the window closes"), &self.settings);
        Ok(Running {
            window,
            surface,
            config,
            renderer,
            frames,
            blit,
            egui_ctx,
            egui_state,
            egui_renderer,
            camera,
            brush,
            // A presets file that cannot be read is said at once.
            message: presets.blocked.as_ref().map(|e| e.to_string()).unwrap_or_default(),
            presets,
            modifiers: ModifiersState::empty(),
            cursor: (f64::from(w) / 2.0, f64::from(h) / 2.0),
            painting: false,
            orbiting: false,
            want_screenshot: false,
            layers: LayersUi::default(),
            view: View::new(crate::TARGET_FRAME_MS, Pace::Interval, self.opts.fixed_resolution, self.opts.frame_log.as_deref())?,
            egui_wants: true,
            last_frame: Instant::now(),
        })
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_some() {
            return;
        }
        match self.start_window(event_loop) {
            Ok(r) => {
                r.window.request_redraw();
                self.running = Some(r);
            }
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    /// Between bursts of events: close once the save has run; otherwise
    /// ask for the next frame when one is wanted, at most every [`POLL`].
    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.closing.is_some() && self.engine.as_ref().is_none_or(Engine::idle) {
            event_loop.exit();
            return;
        }
        // `--exit-after-play`: once played, painted and on the screen.
        if self.opts.exit_after_play
            && self.playing.is_some()
            && !self.is_playing()
            && self.engine.as_ref().is_some_and(Engine::idle)
            && self.running.as_ref().is_some_and(|r| r.frames.settled())
        {
            self.close();
        }
        if !self.wants_frame() {
            event_loop.set_control_flow(ControlFlow::Wait);
            return;
        }
        let Some(r) = &self.running else { return };
        let due = r.last_frame + POLL;
        if Instant::now() >= due {
            r.window.request_redraw();
            event_loop.set_control_flow(ControlFlow::Wait);
        } else {
            event_loop.set_control_flow(ControlFlow::WaitUntil(due));
        }
    }

    fn window_event(&mut self, _event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(r) = self.running.as_mut() else { return };
        let consumed = r.egui_state.on_window_event(&r.window, &event).consumed;
        let redraw = !matches!(event, WindowEvent::RedrawRequested);
        match event {
            WindowEvent::CloseRequested => self.close(),
            WindowEvent::Resized(size) => {
                r.config.width = size.width.max(1);
                r.config.height = size.height.max(1);
                r.surface.configure(&r.renderer.gpu.device, &r.config);
            }
            WindowEvent::ModifiersChanged(m) => r.modifiers = m.state(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame() {
                    self.error = Some(e);
                    self.close();
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                let prev = r.cursor;
                r.cursor = (position.x, position.y);
                if r.orbiting {
                    r.camera.yaw -= (position.x - prev.0) * 0.005;
                    r.camera.pitch = (r.camera.pitch - (position.y - prev.1) * 0.005).clamp(-1.55, 1.55);
                } else if r.painting {
                    self.sample();
                }
            }
            WindowEvent::MouseInput { state, button, .. } if !consumed || state == ElementState::Released => match (button, state) {
                (MouseButton::Left, ElementState::Pressed) => self.begin_stroke(),
                (MouseButton::Left, ElementState::Released) => self.end_stroke(),
                (MouseButton::Right, ElementState::Pressed) => r.orbiting = true,
                (MouseButton::Right, ElementState::Released) => r.orbiting = false,
                _ => {}
            },
            WindowEvent::MouseWheel { delta, .. } if !consumed => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => f64::from(y),
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                r.camera.distance *= 1.15f64.powf(-lines);
            }
            WindowEvent::KeyboardInput { event, .. } if !consumed && event.state == ElementState::Pressed => {
                let ctrl = r.modifiers.control_key();
                let step = r.camera.distance * 0.05;
                let rot = r.camera.rotation();
                match event.logical_key.as_ref() {
                    Key::Character("s") if ctrl => self.save(),
                    Key::Character("z") if ctrl && r.modifiers.shift_key() => self.submit(Job::Redo),
                    Key::Character("z") if ctrl => self.submit(Job::Undo),
                    Key::Character("y") if ctrl => self.submit(Job::Redo),
                    Key::Character("q") if ctrl => self.close(),
                    Key::Character("w") => r.camera.target += rot * DVec3::new(0.0, 0.0, -step),
                    Key::Character("s") => r.camera.target += rot * DVec3::new(0.0, 0.0, step),
                    Key::Character("a") => r.camera.target += rot * DVec3::new(-step, 0.0, 0.0),
                    Key::Character("d") => r.camera.target += rot * DVec3::new(step, 0.0, 0.0),
                    Key::Character("e") => r.camera.target += DVec3::new(0.0, step, 0.0),
                    Key::Character("q") => r.camera.target += DVec3::new(0.0, -step, 0.0),
                    Key::Character("]") => r.brush.radius = (r.brush.radius * 1.25).min(1e4),
                    Key::Character("[") => r.brush.radius = (r.brush.radius / 1.25).max(1e-4),
                    Key::Named(NamedKey::F12) => r.want_screenshot = true,
                    Key::Character("g") if !ctrl => r.brush.grid = !r.brush.grid,
                    Key::Character("m") if !ctrl => r.brush.mirror_axes[0] = !r.brush.mirror_axes[0],
                    Key::Character("l") if !ctrl => r.brush.light.on = !r.brush.light.on,
                    Key::Character("L") if !ctrl => {
                        r.brush.light.shadows = !r.brush.light.shadows;
                        r.brush.light.on |= r.brush.light.shadows;
                    }
                    Key::Character("f") if !ctrl => self.frame_view(),
                    _ => {}
                }
            }
            _ => {}
        }
        // Input may change the view or the painting: a frame shows it.
        if redraw && let Some(r) = self.running.as_ref() {
            r.window.request_redraw();
        }
    }
}

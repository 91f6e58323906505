//! The desktop window (docs/desktop.md): the GPU ray caster drawn into a
//! winit window, painting with the mouse on a document (every stroke
//! journalled as it ends), an orbit and fly camera, an egui panel for the
//! brush and a status line with frame rate, latency, cells, memory and
//! budget.
//!
//! One thread: input events become document events (`Session::apply`, which
//! paints the tree and journals each stroke), and every frame uploads the
//! dirty blocks, runs the g3 pass, casts the image at the window's size and
//! draws it with the panel on top.

use std::io::Write as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{DQuat, DVec3};
use octopaint_doc::Session;
use octopaint_gpu::raycast::LayerTableGpu;
use octopaint_gpu::{Blit, Gpu, Precision, Renderer};
use octopaint_tree::layers::MAX_LAYERS;
use octopaint_tree::raycast::RayParams;
use octopaint_tree::trace::{Brush, Camera, Event, EventKind, LayerOp, LayerOpKind, Light, MODES, Mirror, Mode, SHAPES, Sample, Shape};
use octopaint_tree::Tree;
use octopaint_tree::view::{BACKGROUND, OrbitCamera, axes_seen_from, follow_frame_time, frame_painting, frame_trees, length, pick};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, ModifiersState, NamedKey};
use winit::window::{Window, WindowId};

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
    /// scale, cast size, whether the view was still.
    pub frame_log: Option<PathBuf>,
}

/// The frame time the dynamic resolution aims at on the desktop (60 Hz).
pub const TARGET_FRAME_MS: f64 = 16.7;

/// What the view shows besides the camera: the grid, the light.
type Look = (bool, Option<Light>);

/// Dynamic resolution (docs/desktop.md): while the view changes (camera,
/// painting, size, grid, light), rays are cast for `scale` of the window's width
/// and height, `scale` following the frame time towards
/// [`TARGET_FRAME_MS`]; once a frame changes nothing, it is cast at full
/// size (progressive refinement: the still picture is always exact).
struct Resolution {
    scale: f64,
    /// What the last frame showed, to tell a still frame.
    last_view: Option<(OrbitCamera, [u32; 2], Look)>,
    /// When the last frame began, and whether the view was moving then
    /// (its interval then tells how long a frame at `scale` takes).
    last_frame: Option<(Instant, bool)>,
    fixed: bool,
    log: Option<(std::io::BufWriter<std::fs::File>, Instant)>,
}

impl Resolution {
    /// The cast size of this frame of a `window`-sized view, given whether
    /// the tree changed since the last one, and whether the view is still;
    /// learns from the last frame's interval when that frame was moving.
    /// `full`: cast this frame at full size anyway (a screenshot); its
    /// interval then teaches nothing.
    /// `mirror`: the mirror planes the brush has now (bit a: axis a), for
    /// the frame log only.
    fn next(&mut self, window: [u32; 2], camera: &OrbitCamera, look: Look, tree_changed: bool, full: bool, mirror: u8) -> ([u32; 2], bool) {
        let now = Instant::now();
        let view = (*camera, window, look);
        let still = !tree_changed && self.last_view == Some(view);
        self.last_view = Some(view);
        let interval = self.last_frame.map(|(t, moving)| ((now - t).as_secs_f64() * 1e3, moving));
        if let Some((ms, true)) = interval
            && !self.fixed
        {
            self.scale = follow_frame_time(self.scale, ms, TARGET_FRAME_MS);
        }
        let scale = if still || self.fixed || full { 1.0 } else { self.scale };
        let size = window.map(|v| ((f64::from(v) * scale).round() as u32).clamp(1, v.max(1)));
        self.last_frame = Some((now, !still && !full));
        if let Some((log, t0)) = self.log.as_mut() {
            let ms = interval.map_or(0.0, |(ms, _)| ms);
            let _ = writeln!(log, "{:.1},{ms:.2},{scale:.4},{},{},{},{mirror}", (now - *t0).as_secs_f64() * 1e3, size[0], size[1], u8::from(still));
            // Line by line: a script (or a test) watching the log sees each
            // frame as it is drawn. One small write a frame.
            let _ = log.flush();
        }
        (size, still)
    }
}

/// Open the window on `opts.doc` and run until it is closed (closing saves).
pub fn run(opts: Options) -> Result<(), String> {
    let session = Session::open(&opts.doc).map_err(|e| e.to_string())?;
    if session.recovered > 0 {
        eprintln!("octopaint: {}: recovered {} unsaved stroke(s) from its journal", opts.doc.display(), session.recovered);
    }
    let event_loop = EventLoop::new().map_err(|e| format!("cannot open a window ({e}); is there a display (DISPLAY or WAYLAND_DISPLAY)?"))?;
    let t_open = session.last_time();
    let mut app = App { opts, session, running: None, error: None, started: Instant::now(), t_open };
    event_loop.run_app(&mut app).map_err(|e| e.to_string())?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// The brush as the panel edits it.
struct BrushUi {
    shape: Shape,
    mode: Mode,
    /// Radius in canvas units.
    radius: f64,
    opacity: f64,
    hardness: f64,
    colour: [f32; 3],
    on_surface: bool,
    /// Distance of the painting plane from the eye along the view axis,
    /// canvas units (strokes off the surface, or with surface painting
    /// off, lie on that plane).
    plane_depth: f64,
    /// The ground grid and horizon behind the painting (G).
    grid: bool,
    /// The view's lighting (L, Shift+L).
    light: LightUi,
    /// Mirror painting (spec 8.11; M toggles x): the axes whose planes
    /// through `mirror_centre` mirror every stroke.
    mirror_axes: [bool; 3],
    mirror_centre: DVec3,
}

impl BrushUi {
    /// The mirror planes strokes paint with now; None: no copies.
    fn mirror(&self) -> Option<Mirror> {
        Mirror { axes: self.mirror_axes, centre: self.mirror_centre.to_array() }.active()
    }
}

/// The lighting of the view as the panel edits it (docs/spec.md 6.1,
/// docs/desktop.md "Lighting"): a directional light given by azimuth and
/// elevation, in the view's frame (it turns with the camera, as a studio
/// light in a sculpting tool) or in the canvas's.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LightUi {
    on: bool,
    shadows: bool,
    follows_view: bool,
    /// Degrees: azimuth from the view axis (or canvas +z) towards the
    /// right (+x), elevation above the horizontal.
    azimuth: f64,
    elevation: f64,
    intensity: f64,
    ambient: f64,
}

impl Default for LightUi {
    fn default() -> Self {
        LightUi { on: true, shadows: false, follows_view: true, azimuth: 27.0, elevation: 30.0, intensity: 0.8, ambient: 0.3 }
    }
}

impl LightUi {
    /// The light for a view turned by `view` (camera to canvas), or None
    /// when lighting is off.
    fn light(&self, view: DQuat) -> Option<Light> {
        if !self.on {
            return None;
        }
        let (az, el) = (self.azimuth.to_radians(), self.elevation.to_radians());
        let local = DVec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
        let dir = if self.follows_view { view * local } else { local };
        Some(Light { on: true, dir: dir.to_array(), intensity: self.intensity, ambient: self.ambient, shadows: self.shadows })
    }
}

impl BrushUi {
    fn brush(&self) -> Brush {
        Brush::new(self.shape, self.mode, self.radius, self.colour.map(f64::from), self.opacity, self.hardness)
    }
}

/// Where a sample under the cursor goes: the eye, the ray's direction and
/// the distance along it. With *paint on the surface*, where the ray's
/// optical depth in the paint reaches 0.7; elsewhere, and with the option
/// off, on the plane perpendicular to the view axis at the plane depth.
fn brush_point(r: &Running, tree: &Tree) -> (DVec3, DVec3, f64) {
    let (eye, dir) = r.camera.ray([r.config.width, r.config.height], r.cursor.0, r.cursor.1);
    let forward = r.camera.rotation() * DVec3::NEG_Z;
    let on_plane = r.brush.plane_depth / dir.dot(forward).max(1e-6);
    let depth = if r.brush.on_surface { pick(tree, eye, dir).unwrap_or(on_plane) } else { on_plane };
    (eye, dir, depth)
}

/// What the window draws over the view: the brush cursor, the axes and the
/// scale (docs/desktop.md, "Aids").
struct Overlay {
    /// Window pixels: the cursor, the brush's radius there, its colour and
    /// whether its shape is a box (a square ghost; a disc otherwise).
    cursor: Option<([f32; 2], f32, [f32; 3], bool)>,
    /// The canvas axes x, y, z in the view: screen direction (y down) and
    /// whether the axis points away from the viewer.
    axes: [([f32; 2], bool); 3],
    /// Canvas units per pixel at the brush's distance, the brush radius
    /// and the depth it paints at, with that depth's cell edge.
    scale: (f64, f64, u32, f64),
    /// The cursor's mirror images (spec 8.11): window pixels and radius.
    ghosts: Vec<([f32; 2], f32)>,
    /// The mirror planes as quadrilaterals in window pixels, by axis.
    planes: Vec<([[f32; 2]; 4], usize)>,
}

/// Window pixel and view depth of canvas point `p` for `camera` (spec 6's
/// pixel mapping inverted); None behind the eye.
fn project(camera: &Camera, p: DVec3) -> Option<([f32; 2], f64)> {
    let m = octopaint_tree::brush::quat_to_rows(camera.q);
    let d = p - DVec3::from_array(camera.eye);
    let v = [0, 1, 2].map(|i| m[0][i] * d.x + m[1][i] * d.y + m[2][i] * d.z);
    if v[2] >= -1e-9 {
        return None;
    }
    let (tx, ty) = (v[0] / -v[2], v[1] / -v[2]);
    let [l, r, u, dn] = camera.fov.map(f64::tan);
    let [w, h] = camera.size.map(f64::from);
    Some(([((tx - l) / (r - l) * w) as f32, ((u - ty) / (u - dn) * h) as f32], -v[2]))
}

impl Overlay {
    fn new(r: &Running, tree: &Tree) -> Overlay {
        let size = [r.config.width, r.config.height];
        let (_, dir, depth) = brush_point(r, tree);
        let rot = r.camera.rotation();
        let z = depth * dir.dot(rot * DVec3::NEG_Z);
        // Canvas units per pixel at view depth z (square pixels).
        let per_px = 2.0 * z * (r.camera.fov_y / 2.0).tan() / f64::from(size[1].max(1));
        let radius_px = (r.brush.radius / per_px).clamp(2.0, 4.0 * f64::from(size[1])) as f32;
        let inside = r.cursor.0 >= 0.0 && r.cursor.1 >= 0.0 && r.cursor.0 < f64::from(size[0]) && r.cursor.1 < f64::from(size[1]);
        let cursor = (inside && per_px.is_finite() && per_px > 0.0)
            .then(|| ([r.cursor.0 as f32, r.cursor.1 as f32], radius_px, r.brush.colour, r.brush.shape == Shape::Box));
        let axes = axes_seen_from(rot);
        let d = tree.lat.target_depth(r.brush.radius);
        // Mirror painting: the cursor's images and the planes, faint.
        let (mut ghosts, mut planes) = (Vec::new(), Vec::new());
        if let Some(m) = r.brush.mirror() {
            let camera = r.camera.camera(size, BACKGROUND);
            let (eye, _, _) = brush_point(r, tree);
            let p = eye + dir * depth;
            let px_per_unit_depth = f64::from(size[1].max(1)) / (2.0 * (r.camera.fov_y / 2.0).tan());
            if cursor.is_some() {
                for mask in m.copies() {
                    if let Some((at, z)) = project(&camera, octopaint_tree::stroke::mirrored(p, mask, m.centre)) {
                        ghosts.push((at, (r.brush.radius / z * px_per_unit_depth).clamp(2.0, 4.0 * f64::from(size[1])) as f32));
                    }
                }
            }
            let c = DVec3::from_array(m.centre);
            let s = 0.4 * r.camera.distance;
            for a in (0..3).filter(|&a| m.axes[a]) {
                let (u, v) = (DVec3::AXES[(a + 1) % 3] * s, DVec3::AXES[(a + 2) % 3] * s);
                let corners = [c - u - v, c + u - v, c + u + v, c - u + v].map(|q| project(&camera, q));
                if corners.iter().all(Option::is_some) {
                    planes.push((corners.map(|q| q.expect("checked").0), a));
                }
            }
        }
        Overlay { cursor, axes, scale: (per_px, r.brush.radius, d, tree.lat.size_canvas[d as usize]), ghosts, planes }
    }

    /// Draw the cursor and the axes over the view (`view`: the part of the
    /// window the panels leave, in points).
    fn draw(&self, ctx: &egui::Context, view: egui::Rect) {
        let painter = ctx.layer_painter(egui::LayerId::new(egui::Order::Foreground, egui::Id::unique("overlay"))).with_clip_rect(view);
        let ppp = ctx.pixels_per_point();
        let axis_colour = |a: usize, alpha: u8| [egui::Color32::from_rgba_unmultiplied(230, 60, 60, alpha), egui::Color32::from_rgba_unmultiplied(70, 200, 70, alpha), egui::Color32::from_rgba_unmultiplied(70, 120, 240, alpha)][a];
        for (quad, a) in &self.planes {
            let points: Vec<egui::Pos2> = quad.iter().map(|p| egui::pos2(p[0] / ppp, p[1] / ppp)).collect();
            painter.add(egui::Shape::convex_polygon(points, axis_colour(*a, 20), egui::Stroke::new(1.0, axis_colour(*a, 110))));
        }
        if let Some((_, _, colour, _)) = self.cursor {
            let rgb = colour.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
            for (at, radius) in &self.ghosts {
                let centre = egui::pos2(at[0] / ppp, at[1] / ppp);
                painter.circle_stroke(centre, radius / ppp, egui::Stroke::new(1.5, egui::Color32::from_rgba_unmultiplied(rgb[0], rgb[1], rgb[2], 140)));
            }
        }
        if let Some((at, radius, colour, square)) = self.cursor {
            let centre = egui::pos2(at[0] / ppp, at[1] / ppp);
            let rgb = colour.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
            let edge = egui::Color32::from_rgb(rgb[0], rgb[1], rgb[2]);
            let fill = egui::Color32::from_rgba_unmultiplied(rgb[0], rgb[1], rgb[2], 40);
            let r = radius / ppp;
            let stroke = egui::Stroke::new(2.0, edge);
            if square {
                let rect = egui::Rect::from_center_size(centre, egui::vec2(2.0 * r, 2.0 * r));
                painter.rect(rect, 0.0, fill, stroke, egui::StrokeKind::Middle);
            } else {
                painter.circle(centre, r, fill, stroke);
            }
            painter.circle_filled(centre, 1.5, edge);
        }
        // The axes, 36 points long from a corner of the view, the far ones
        // first so that the near ones are drawn over them.
        let origin = egui::pos2(view.right() - 52.0, view.bottom() - 52.0);
        painter.circle_filled(origin, 44.0, egui::Color32::from_rgba_unmultiplied(0, 0, 0, 110));
        let colours = [egui::Color32::from_rgb(230, 60, 60), egui::Color32::from_rgb(70, 200, 70), egui::Color32::from_rgb(70, 120, 240)];
        let mut order = [0usize, 1, 2];
        order.sort_by_key(|&i| !self.axes[i].1);
        for i in order {
            let (v, away) = self.axes[i];
            let tip = origin + egui::vec2(v[0], v[1]) * 36.0;
            let width = if away { 2.0 } else { 3.5 };
            painter.line_segment([origin, tip], egui::Stroke::new(width, colours[i]));
            painter.text(tip + egui::vec2(v[0], v[1]) * 8.0, egui::Align2::CENTER_CENTER, ["x", "y", "z"][i], egui::FontId::proportional(12.0), colours[i]);
        }
    }
}

struct Stats {
    frames: u64,
    fps: f64,
    fps_window: (Instant, u64),
    latency_ms: Option<f64>,
    pending_since: Option<Instant>,
    busy_ms: f64,
    message: String,
}

struct Running {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: Renderer,
    blit: Blit,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    camera: OrbitCamera,
    brush: BrushUi,
    stats: Stats,
    modifiers: ModifiersState,
    cursor: (f64, f64),
    painting: bool,
    orbiting: bool,
    want_screenshot: bool,
    resolution: Resolution,
    layers: LayersUi,
}

/// The layer panel's state (docs/desktop.md "Layers"), and what the GPU
/// holds of a document of layers: the table of the layers uploaded and the
/// settings they were uploaded with.
#[derive(Default)]
struct LayersUi {
    rename: String,
    /// The selected layer's opacity while its slider is dragged (applied,
    /// as one undo step, when the drag ends).
    opacity: Option<f32>,
    uploaded: Option<(Vec<(u32, u32, bool)>, LayerTableGpu)>,
    /// Where the last frame laid out each layer's row and drag handle
    /// (by layer index): a test drives the panel with pointer events there.
    rows: Vec<(usize, egui::Rect, egui::Rect)>,
}

/// One row of the layer panel.
struct LayerInfo {
    name: String,
    visible: bool,
    opacity: f32,
    locked: bool,
}

struct App {
    opts: Options,
    session: Session,
    running: Option<Running>,
    error: Option<String>,
    started: Instant,
    t_open: f64,
}

impl App {
    /// Event time: seconds since this window opened, after the session's
    /// last event (the trace format's clock never goes back).
    fn now(&self) -> f64 {
        self.session.last_time().max(self.t_open + self.started.elapsed().as_secs_f64())
    }

    fn apply(&mut self, kind: EventKind) {
        let t = self.now();
        let started = Instant::now();
        let result = self.session.apply(&Event { line: 0, t, kind });
        if let Some(r) = self.running.as_mut() {
            r.stats.busy_ms = started.elapsed().as_secs_f64() * 1e3;
            r.stats.pending_since.get_or_insert(started);
            if let Err(e) = result {
                r.stats.message = e.to_string();
            }
        }
    }

    fn begin_stroke(&mut self) {
        let Some(r) = self.running.as_mut() else { return };
        let brush = r.brush.brush();
        let mirror = r.brush.mirror();
        r.painting = true;
        if self.session.mirror() != mirror {
            let m = mirror.unwrap_or(Mirror { axes: [false; 3], centre: r.brush.mirror_centre.to_array() });
            self.apply(EventKind::Mirror(m));
        }
        if self.session.brush() != Some(&brush) {
            self.apply(EventKind::Brush(brush));
        }
        self.apply(EventKind::StrokeBegin);
        self.sample();
    }

    fn sample(&mut self) {
        let Some(r) = self.running.as_ref() else { return };
        let (eye, dir, depth) = brush_point(r, &self.session.painting().tree);
        let p = eye + dir * depth;
        self.apply(EventKind::Sample(Sample::at(p.to_array())));
    }

    fn end_stroke(&mut self) {
        if let Some(r) = self.running.as_mut() {
            r.painting = false;
        }
        if self.session.in_stroke() {
            self.apply(EventKind::StrokeEnd);
        }
    }

    /// Back to the view that frames everything painted (F, the Frame
    /// button).
    fn frame_view(&mut self) {
        if let Some(r) = self.running.as_mut() {
            r.camera = OrbitCamera { covered: r.camera.covered, ..frame_document(&self.session) };
            r.stats.message = "framed the painting".into();
        }
    }

    fn save(&mut self) {
        self.end_stroke();
        let msg = match self.session.save() {
            Ok(()) => format!("saved {}", self.opts.doc.display()),
            Err(e) => format!("save failed: {e}"),
        };
        eprintln!("octopaint: {msg}");
        if let Some(r) = self.running.as_mut() {
            r.stats.message = msg;
        }
    }

    fn start(&mut self, event_loop: &ActiveEventLoop) -> Result<Running, String> {
        let [w, h] = self.opts.size;
        let attrs = Window::default_attributes()
            .with_title(format!("octopaint: {}", self.opts.doc.display()))
            .with_inner_size(winit::dpi::PhysicalSize::new(w, h));
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
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or("the window's surface is not supported by the adapter")?;
        config.format = format;
        config.present_mode = wgpu::PresentMode::AutoVsync;
        config.desired_maximum_frame_latency = 2;
        let device = &renderer.gpu.device;
        surface.configure(device, &config);
        let blit = Blit::new(&renderer.gpu, format);
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(egui_ctx.clone(), egui::ViewportId::ROOT, &window, Some(window.scale_factor() as f32), None, None);
        let egui_renderer = egui_wgpu::Renderer::new(device, format, egui_wgpu::RendererOptions::default());
        let camera = frame_document(&self.session);
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
            light: LightUi { on: renderer.gpu.info.device_type != wgpu::DeviceType::Cpu, ..LightUi::default() },
            mirror_axes: [false; 3],
            mirror_centre: camera.target,
        };
        Ok(Running {
            window,
            surface,
            config,
            renderer,
            blit,
            egui_ctx,
            egui_state,
            egui_renderer,
            camera,
            brush,
            stats: Stats {
                frames: 0,
                fps: 0.0,
                fps_window: (Instant::now(), 0),
                latency_ms: None,
                pending_since: None,
                busy_ms: 0.0,
                message: String::new(),
            },
            modifiers: ModifiersState::empty(),
            cursor: (f64::from(w) / 2.0, f64::from(h) / 2.0),
            painting: false,
            orbiting: false,
            want_screenshot: false,
            layers: LayersUi::default(),
            resolution: Resolution {
                scale: 1.0,
                last_view: None,
                last_frame: None,
                fixed: self.opts.fixed_resolution,
                log: match &self.opts.frame_log {
                    Some(p) => {
                        let f = std::fs::File::create(p).map_err(|e| format!("cannot write {}: {e}", p.display()))?;
                        let mut w = std::io::BufWriter::new(f);
                        let _ = writeln!(w, "t_ms,interval_ms,scale,width,height,still,mirror");
                        Some((w, Instant::now()))
                    }
                    None => None,
                },
            },
        })
    }

    fn frame(&mut self) -> Result<(), String> {
        let precision = self.opts.precision;
        let screenshot_path = self.opts.screenshot.clone();
        let Some(r) = self.running.as_mut() else { return Ok(()) };
        // A document of layers: every contributing layer in the pages,
        // uploaded again when one of them or the list changed (spec 6.2);
        // a one-tree document: its tree, block by block.
        let layered = self.session.version == 2;
        let mut table = None;
        let tree_changed = if layered {
            let (_, order, ..) = self.session.doc.parts();
            let order = order.to_vec();
            let mut key = Vec::new();
            let mut changed = false;
            for (k, id) in order.iter().enumerate() {
                let l = self.session.doc.layer_mut(k);
                changed |= !l.painting.tree.take_publication().blocks.is_empty();
                if l.contributes() {
                    key.push((*id, l.opacity.to_bits(), l.visible));
                }
            }
            let stale = r.layers.uploaded.as_ref().is_none_or(|(k, _)| *k != key);
            if changed || stale {
                let trees: Vec<(&Tree, f32)> = self.session.doc.layers().filter(|l| l.contributes()).map(|l| (l.tree(), l.opacity)).collect();
                let t = if trees.is_empty() { LayerTableGpu::new(&[], &[]) } else { r.renderer.upload_layers(&trees).map_err(|e| e.to_string())? };
                r.layers.uploaded = Some((key, t));
            }
            table = r.layers.uploaded.as_ref().map(|(_, t)| *t);
            changed || stale
        } else {
            r.renderer.sync(&mut self.session.painting_mut().tree).map_err(|e| e.to_string())?.blocks > 0
        };
        let tree = &self.session.painting().tree;
        let size = [r.config.width, r.config.height];
        let light = r.brush.light.light(r.camera.rotation());
        // A screenshot is always of the full resolution, moving or not.
        let mirror = r.brush.mirror_axes.iter().enumerate().fold(0u8, |m, (a, &on)| m | (u8::from(on) << a));
        let (cast, _) = r.resolution.next(size, &r.camera, (r.brush.grid, light), tree_changed, r.want_screenshot, mirror);
        let camera = r.camera.camera(cast, BACKGROUND);
        let mut params = RayParams::new(&tree.lat, &camera).with_light(light.as_ref());
        if r.brush.grid {
            params = params.with_grid(camera.eye);
        }
        let overlay = Overlay::new(r, tree);
        // The panel.
        let raw = r.egui_state.take_egui_input(&r.window);
        let mut actions = Vec::new();
        let doc = &self.session.doc;
        let (undo, redo) = doc.steps();
        let info = StatusInfo {
            fps: r.stats.fps,
            resolution: f64::from(cast[0]) / f64::from(size[0].max(1)),
            latency_ms: r.stats.latency_ms,
            busy_ms: r.stats.busy_ms,
            cells: doc.used().min(u64::from(u32::MAX)) as u32,
            capacity: doc.canvas().capacity,
            bytes: doc.layers().map(|l| l.tree().pool_bytes_allocated()).sum::<usize>() + doc.history_bytes(),
            undo,
            redo,
            message: r.stats.message.clone(),
            in_stroke: self.session.in_stroke(),
            layered,
            layers: doc.layers().map(|l| LayerInfo { name: l.name.clone(), visible: l.visible, opacity: l.opacity, locked: l.locked }).collect(),
            selected: doc.selected(),
        };
        let mut view = None;
        let out = r.egui_ctx.run_ui(raw, |ui| view = Some(panel(ui, &mut r.brush, &mut r.layers, &info, &overlay, &mut actions)));
        // The next frames centre the view on the part the panel leaves.
        if let Some(v) = view {
            r.camera.covered = (f64::from(v.left() * out.pixels_per_point) / f64::from(size[0].max(1))).clamp(0.0, 0.9);
        }
        r.egui_state.handle_platform_output(&r.window, out.platform_output);
        let jobs = r.egui_ctx.tessellate(out.shapes, out.pixels_per_point);
        let screen = egui_wgpu::ScreenDescriptor { size_in_pixels: size, pixels_per_point: out.pixels_per_point };
        let gpu = &r.renderer.gpu;
        for (id, deltas) in &out.textures_delta.set {
            for delta in deltas {
                r.egui_renderer.update_texture(&gpu.device, &gpu.queue, *id, delta);
            }
        }
        let frame = match r.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f) | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            other => {
                r.surface.configure(&gpu.device, &r.config);
                return if matches!(other, wgpu::CurrentSurfaceTexture::Lost | wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded) {
                    Ok(())
                } else {
                    Err("the window's surface failed".into())
                };
            }
        };
        let mut enc = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        match &table {
            Some(t) => r.renderer.ray.encode_layers(gpu, &r.renderer.pools, &mut enc, &params, precision, t),
            None => r.renderer.ray.encode(gpu, &r.renderer.pools, &mut enc, &params, precision),
        }
        .map_err(|e| e.to_string())?;
        let pixels = r.renderer.ray.pixel_buffer().expect("cast above");
        let group = r.blit.bind_scaled(gpu, pixels, cast, size);
        r.egui_renderer.update_buffers(&gpu.device, &gpu.queue, &mut enc, &jobs, &screen);
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor::default());
        let shot = r.want_screenshot.then(|| {
            gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("screenshot"),
                size: wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: r.config.format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        });
        let targets: Vec<wgpu::TextureView> = std::iter::once(view).chain(shot.iter().map(|t| t.create_view(&Default::default()))).collect();
        for target in &targets {
            let mut pass = enc
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("window"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: target,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            r.blit.draw(&mut pass, &group);
            r.egui_renderer.render(&mut pass, &jobs, &screen);
        }
        let readback = shot.as_ref().map(|t| {
            let row = (size[0] * 4).div_ceil(256) * 256;
            let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("screenshot"),
                size: u64::from(row) * u64::from(size[1]),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            enc.copy_texture_to_buffer(
                t.as_image_copy(),
                wgpu::TexelCopyBufferInfo { buffer: &buf, layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: None } },
                wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 },
            );
            (buf, row)
        });
        gpu.queue.submit([enc.finish()]);
        r.window.pre_present_notify();
        gpu.queue.present(frame);
        for id in &out.textures_delta.free {
            r.egui_renderer.free_texture(id);
        }
        if let Some((buf, row)) = readback {
            r.want_screenshot = false;
            let msg = match write_screenshot(gpu, &buf, row, size, r.config.format, &screenshot_path) {
                Ok(()) => format!("wrote {}", screenshot_path.display()),
                Err(e) => format!("screenshot failed: {e}"),
            };
            eprintln!("octopaint: {msg}");
            r.stats.message = msg;
        }
        // Stats: a sample's latency is from its arrival to the frame that
        // first shows it.
        r.stats.frames += 1;
        if let Some(t) = r.stats.pending_since.take() {
            r.stats.latency_ms = Some(t.elapsed().as_secs_f64() * 1e3);
        }
        let (t0, f0) = r.stats.fps_window;
        if t0.elapsed() >= Duration::from_millis(500) {
            r.stats.fps = (r.stats.frames - f0) as f64 / t0.elapsed().as_secs_f64();
            r.stats.fps_window = (Instant::now(), r.stats.frames);
        }
        for a in actions {
            match a {
                Action::Undo => self.apply(EventKind::Undo),
                Action::Redo => self.apply(EventKind::Redo),
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
                Action::MakeLayers => {
                    let msg = match self.session.upgrade_to_layers() {
                        Ok(()) => "this document now has layers (saved)".to_string(),
                        Err(e) => format!("cannot make layers: {e}"),
                    };
                    if let Some(r) = self.running.as_mut() {
                        r.stats.message = msg;
                    }
                }
                Action::Layer(op) => self.apply(EventKind::Layer(op)),
            }
        }
        Ok(())
    }
}

fn write_screenshot(gpu: &Gpu, buf: &wgpu::Buffer, row: u32, size: [u32; 2], format: wgpu::TextureFormat, path: &std::path::Path) -> Result<(), String> {
    let raw = octopaint_gpu::pools::read_buffer(gpu, buf, u64::from(row) * u64::from(size[1])).map_err(|e| e.to_string())?;
    let rgb = octopaint_gpu::image::texels_to_rgb(&raw, row, size, format);
    octopaint_gpu::image::write_png(path, &rgb, size[0], size[1]).map_err(|e| e.to_string())
}

struct StatusInfo {
    fps: f64,
    /// The share of the window's width the rays were cast for.
    resolution: f64,
    latency_ms: Option<f64>,
    busy_ms: f64,
    cells: u32,
    capacity: u32,
    bytes: usize,
    undo: usize,
    redo: usize,
    message: String,
    in_stroke: bool,
    /// A document of layers (a version 2 session); else one tree.
    layered: bool,
    layers: Vec<LayerInfo>,
    selected: usize,
}

enum Action {
    Undo,
    Redo,
    Save,
    Screenshot,
    Frame,
    MirrorHere,
    /// Make this one-tree document a document of layers.
    MakeLayers,
    Layer(LayerOp),
}

/// The smallest `Layer N` not taken.
fn free_name(layers: &[LayerInfo], stem: &str) -> String {
    (1..).map(|n| format!("{stem} {n}")).find(|n| !layers.iter().any(|l| l.name == *n)).expect("some name is free")
}

fn layer_op(kind: LayerOpKind, layer: Option<&str>, name: Option<String>) -> LayerOp {
    LayerOp { layer: layer.map(String::from), name, ..LayerOp::new(kind) }
}

/// The layer panel (docs/desktop.md "Layers"): the layers top first, each
/// selectable, with its eye and its lock; the selected one's opacity and
/// name; add, duplicate, delete, merge down, move up and down. Every change
/// is a `layer` event of the document, an undo step.
fn layers_panel(ui: &mut egui::Ui, l: &mut LayersUi, s: &StatusInfo, actions: &mut Vec<Action>) {
    ui.heading("Layers");
    if !s.layered {
        ui.label("one tree");
        if ui.button("Use layers").on_hover_text("make this document a document of layers (it is saved at once)").clicked() {
            actions.push(Action::MakeLayers);
        }
        return;
    }
    let n = s.layers.len();
    l.rows.clear();
    for k in (0..n).rev() {
        let layer = &s.layers[k];
        let row = ui.horizontal(|ui| {
            // The handle: drag a layer onto another row to move it there
            // (a `move` event to that row's index).
            let handle = ui
                .dnd_drag_source(egui::Id::unique(("layer row", k)), k, |ui| ui.label("↕"))
                .response
                .on_hover_text("drag onto another layer to move it there");
            let mut visible = layer.visible;
            if ui.checkbox(&mut visible, "").on_hover_text("visible (drawn, exported)").changed() {
                actions.push(Action::Layer(LayerOp { visible: Some(visible), ..layer_op(LayerOpKind::Set, Some(&layer.name), None) }));
            }
            let mut locked = layer.locked;
            if ui.checkbox(&mut locked, "lock").on_hover_text("locked: strokes are refused").changed() {
                actions.push(Action::Layer(LayerOp { locked: Some(locked), ..layer_op(LayerOpKind::Set, Some(&layer.name), None) }));
            }
            let label = if layer.opacity < 1.0 { format!("{} ({:.0}%)", layer.name, layer.opacity * 100.0) } else { layer.name.clone() };
            if ui.selectable_label(k == s.selected, label).clicked() && k != s.selected {
                actions.push(Action::Layer(layer_op(LayerOpKind::Select, Some(&layer.name), None)));
                l.rename.clear();
                l.opacity = None;
            }
            handle.rect
        });
        let rect = row.response.rect;
        l.rows.push((k, rect, row.inner));
        if let Some(from) = row.response.dnd_hover_payload::<usize>()
            && *from != k
        {
            // Where it would go: a line on the side it comes from.
            let y = if *from < k { rect.top() } else { rect.bottom() };
            ui.painter().hline(rect.x_range(), y, egui::Stroke::new(2.0, ui.visuals().selection.stroke.color));
        }
        if let Some(from) = row.response.dnd_release_payload::<usize>()
            && *from != k
            && let Some(moved) = s.layers.get(*from)
        {
            actions.push(Action::Layer(LayerOp { to: Some(k), ..layer_op(LayerOpKind::Move, Some(&moved.name), None) }));
        }
    }
    let Some(current) = s.layers.get(s.selected) else { return };
    let name = current.name.as_str();
    let mut opacity = l.opacity.unwrap_or(current.opacity);
    let slider = ui.add(egui::Slider::new(&mut opacity, 0.0..=1.0).text("layer opacity"));
    if slider.dragged() {
        l.opacity = Some(opacity);
    } else if slider.drag_stopped() || (slider.changed() && !slider.dragged()) {
        l.opacity = None;
        if opacity != current.opacity {
            actions.push(Action::Layer(LayerOp { opacity: Some(opacity), ..layer_op(LayerOpKind::Set, Some(name), None) }));
        }
    }
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut l.rename).hint_text(name).desired_width(110.0));
        if ui.button("Rename").clicked() && !l.rename.trim().is_empty() {
            actions.push(Action::Layer(layer_op(LayerOpKind::Rename, Some(name), Some(l.rename.trim().to_string()))));
            l.rename.clear();
        }
    });
    ui.horizontal(|ui| {
        if ui.add_enabled(n < MAX_LAYERS, egui::Button::new("Add")).clicked() {
            actions.push(Action::Layer(layer_op(LayerOpKind::Add, None, Some(free_name(&s.layers, "Layer")))));
        }
        if ui.add_enabled(n < MAX_LAYERS, egui::Button::new("Duplicate")).clicked() {
            actions.push(Action::Layer(layer_op(LayerOpKind::Duplicate, Some(name), Some(free_name(&s.layers, &format!("{name} copy"))))));
        }
        if ui.add_enabled(n > 1, egui::Button::new("Delete")).clicked() {
            actions.push(Action::Layer(layer_op(LayerOpKind::Delete, Some(name), None)));
        }
    });
    ui.horizontal(|ui| {
        let below_locked = s.selected > 0 && s.layers[s.selected - 1].locked;
        if ui.add_enabled(s.selected > 0 && !current.locked && !below_locked, egui::Button::new("Merge down")).clicked() {
            actions.push(Action::Layer(layer_op(LayerOpKind::MergeDown, Some(name), None)));
        }
        if ui.add_enabled(s.selected + 1 < n, egui::Button::new("Up")).clicked() {
            actions.push(Action::Layer(LayerOp { to: Some(s.selected + 1), ..layer_op(LayerOpKind::Move, Some(name), None) }));
        }
        if ui.add_enabled(s.selected > 0, egui::Button::new("Down")).clicked() {
            actions.push(Action::Layer(LayerOp { to: Some(s.selected - 1), ..layer_op(LayerOpKind::Move, Some(name), None) }));
        }
    });
}

/// The panel, the status line and the overlay; returns the part of the
/// window they leave for the view (points).
fn panel(root: &mut egui::Ui, b: &mut BrushUi, l: &mut LayersUi, s: &StatusInfo, overlay: &Overlay, actions: &mut Vec<Action>) -> egui::Rect {
    status_line(root, s);
    egui::Panel::left("brush").resizable(false).show(root, |ui| egui::ScrollArea::vertical().show(ui, |ui| {
        ui.heading("Brush");
        egui::ComboBox::from_label("shape").selected_text(SHAPES[b.shape as usize]).show_ui(ui, |ui| {
            for (v, name) in [Shape::Sphere, Shape::Cylinder, Shape::Box, Shape::Cone, Shape::Noise].into_iter().zip(SHAPES) {
                ui.selectable_value(&mut b.shape, v, name);
            }
        });
        egui::ComboBox::from_label("mode").selected_text(MODES[b.mode as usize]).show_ui(ui, |ui| {
            for (v, name) in [Mode::Paint, Mode::Erase, Mode::Recolor, Mode::Mix, Mode::Pickup].into_iter().zip(MODES) {
                ui.selectable_value(&mut b.mode, v, name);
            }
        });
        ui.add(egui::Slider::new(&mut b.radius, 1e-4..=1e4).logarithmic(true).text("radius"));
        ui.add(egui::Slider::new(&mut b.opacity, 0.0..=1.0).text("opacity"));
        ui.add(egui::Slider::new(&mut b.hardness, 0.0..=1.0).text("hardness"));
        ui.horizontal(|ui| {
            ui.label("colour");
            ui.color_edit_button_rgb(&mut b.colour);
        });
        ui.checkbox(&mut b.on_surface, "paint on the surface under the cursor");
        ui.add(egui::Slider::new(&mut b.plane_depth, 1e-4..=1e5).logarithmic(true).text("plane depth"));
        ui.horizontal(|ui| {
            ui.label("mirror");
            for (a, name) in ["x (M)", "y", "z"].into_iter().enumerate() {
                ui.checkbox(&mut b.mirror_axes[a], name);
            }
        });
        ui.horizontal(|ui| {
            let c = b.mirror_centre;
            ui.label(format!("centre {}, {}, {}", length(c.x), length(c.y), length(c.z)));
            if ui.button("here").on_hover_text("move the mirror planes to the view's centre").clicked() {
                actions.push(Action::MirrorHere);
            }
        });
        ui.checkbox(&mut b.grid, "ground grid and horizon (G)");
        ui.horizontal(|ui| {
            ui.checkbox(&mut b.light.on, "light (L)");
            ui.add_enabled(b.light.on, egui::Checkbox::new(&mut b.light.shadows, "shadows (Shift+L)"));
        });
        ui.add_enabled_ui(b.light.on, |ui| {
            ui.checkbox(&mut b.light.follows_view, "light turns with the view");
            ui.add(egui::Slider::new(&mut b.light.azimuth, -180.0..=180.0).text("light azimuth °"));
            ui.add(egui::Slider::new(&mut b.light.elevation, -90.0..=90.0).text("light elevation °"));
            ui.add(egui::Slider::new(&mut b.light.intensity, 0.0..=2.0).text("intensity"));
            ui.add(egui::Slider::new(&mut b.light.ambient, 0.0..=1.0).text("ambient"));
        });
        let (per_px, radius, depth, edge) = overlay.scale;
        ui.label(format!("1 px = {} at the brush\nradius {} paints at depth {depth}\n(cells of {})", length(per_px), length(radius), length(edge)));
        ui.separator();
        ui.horizontal(|ui| {
            if ui.button("Undo").clicked() {
                actions.push(Action::Undo);
            }
            if ui.button("Redo").clicked() {
                actions.push(Action::Redo);
            }
            if ui.button("Save").clicked() {
                actions.push(Action::Save);
            }
            if ui.button("Screenshot").clicked() {
                actions.push(Action::Screenshot);
            }
            if ui.button("Frame").on_hover_text("frame the painting (F)").clicked() {
                actions.push(Action::Frame);
            }
        });
        ui.separator();
        layers_panel(ui, l, s, actions);
        ui.separator();
        ui.label("left drag: paint · right drag: orbit\nwheel: zoom · W A S D Q E: fly\nF: frame the painting · G: grid\nL: light · Shift+L: shadows\nM: mirror on x\n[ ]: brush size\nCtrl+Z / Ctrl+Y: undo / redo\nCtrl+S: save · F12: screenshot");
    }));
    let view = root.available_rect_before_wrap();
    overlay.draw(root.ctx(), view);
    view
}

fn status_line(root: &mut egui::Ui, s: &StatusInfo) {
    egui::Panel::bottom("status").show(root, |ui| {
        ui.horizontal(|ui| {
            ui.label(format!("{:.0} fps", s.fps));
            ui.separator();
            ui.label(format!("resolution {:.0}%", s.resolution * 100.0));
            ui.separator();
            ui.label(match s.latency_ms {
                Some(l) => format!("latency {l:.1} ms"),
                None => "latency -".into(),
            });
            ui.separator();
            let pct = 100.0 * f64::from(s.cells) / f64::from(s.capacity.max(1));
            ui.label(format!("{} cells, budget {pct:.1}% of {}", s.cells, s.capacity));
            ui.separator();
            ui.label(format!("memory {:.1} MiB", s.bytes as f64 / f64::from(1 << 20)));
            ui.separator();
            ui.label(format!("undo {} / redo {}", s.undo, s.redo));
            if s.layered
                && let Some(l) = s.layers.get(s.selected)
            {
                ui.separator();
                ui.label(format!("layer {}{}", l.name, if l.locked { " (locked)" } else { "" }));
            }
            if s.busy_ms > 50.0 || s.in_stroke {
                ui.separator();
                ui.colored_label(egui::Color32::YELLOW, format!("painting… {:.0} ms", s.busy_ms));
            }
            if pct > 90.0 {
                ui.separator();
                ui.colored_label(egui::Color32::RED, "cell budget nearly spent");
            }
            if !s.message.is_empty() {
                ui.separator();
                ui.label(&s.message);
            }
        });
    });
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_some() {
            return;
        }
        match self.start(event_loop) {
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

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(r) = self.running.as_mut() else { return };
        let consumed = r.egui_state.on_window_event(&r.window, &event).consumed;
        match event {
            WindowEvent::CloseRequested => {
                self.save();
                event_loop.exit();
            }
            WindowEvent::Resized(size) => {
                r.config.width = size.width.max(1);
                r.config.height = size.height.max(1);
                r.surface.configure(&r.renderer.gpu.device, &r.config);
            }
            WindowEvent::ModifiersChanged(m) => r.modifiers = m.state(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame() {
                    self.error = Some(e);
                    self.save();
                    event_loop.exit();
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                let prev = r.cursor;
                r.cursor = (position.x, position.y);
                if r.orbiting {
                    r.camera.yaw -= (position.x - prev.0) * 0.005;
                    r.camera.pitch = (r.camera.pitch - (position.y - prev.1) * 0.005).clamp(-1.55, 1.55);
                } else if r.painting && self.session.in_stroke() {
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
                    Key::Character("z") if ctrl && r.modifiers.shift_key() => self.apply(EventKind::Redo),
                    Key::Character("z") if ctrl => self.apply(EventKind::Undo),
                    Key::Character("y") if ctrl => self.apply(EventKind::Redo),
                    Key::Character("q") if ctrl => {
                        self.save();
                        event_loop.exit();
                    }
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
        if let Some(r) = self.running.as_ref() {
            r.window.request_redraw();
        }
    }
}

/// The view that frames everything painted: the visible layers of a
/// document of layers, the tree of a one-tree one.
fn frame_document(session: &Session) -> OrbitCamera {
    let shown: Vec<&Tree> = session.doc.layers().filter(|l| l.contributes()).map(|l| l.tree()).collect();
    if shown.is_empty() { frame_painting(&session.painting().tree) } else { frame_trees(&shown) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(names: &[&str]) -> StatusInfo {
        StatusInfo {
            fps: 0.0,
            resolution: 1.0,
            latency_ms: None,
            busy_ms: 0.0,
            cells: 8,
            capacity: 1 << 20,
            bytes: 0,
            undo: 0,
            redo: 0,
            message: String::new(),
            in_stroke: false,
            layered: true,
            layers: names.iter().map(|n| LayerInfo { name: n.to_string(), visible: true, opacity: 1.0, locked: false }).collect(),
            selected: 0,
        }
    }

    /// One frame of the panel with these pointer events; the actions it made.
    fn frame(ctx: &egui::Context, l: &mut LayersUi, s: &StatusInfo, events: Vec<egui::Event>) -> Vec<Action> {
        let raw = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(400.0, 600.0))),
            events,
            ..Default::default()
        };
        let mut actions = Vec::new();
        let _ = ctx.run_ui(raw, |ui| {
            egui::CentralPanel::default().show(ui, |ui| layers_panel(ui, l, s, &mut actions));
        });
        actions
    }

    fn pointer(at: egui::Pos2, pressed: Option<bool>) -> Vec<egui::Event> {
        let mut e = vec![egui::Event::PointerMoved(at)];
        if let Some(p) = pressed {
            e.push(egui::Event::PointerButton { pos: at, button: egui::PointerButton::Primary, pressed: p, modifiers: Default::default() });
        }
        e
    }

    #[test]
    fn dragging_a_layer_onto_another_row_moves_it_there() {
        let ctx = egui::Context::default();
        let s = info(&["bottom", "middle", "top"]);
        let mut l = LayersUi::default();
        assert!(frame(&ctx, &mut l, &s, vec![]).is_empty());
        let find = |l: &LayersUi, k: usize| *l.rows.iter().find(|r| r.0 == k).expect("a row per layer");
        let (_, _, handle) = find(&l, 0);
        let (_, target, _) = find(&l, 2);
        // Press on the bottom layer's handle, drag in steps to the top row,
        // release there.
        let mut actions = frame(&ctx, &mut l, &s, pointer(handle.center(), Some(true)));
        let (from, to) = (handle.center(), target.center());
        for i in 1..=8 {
            let t = i as f32 / 8.0;
            actions.extend(frame(&ctx, &mut l, &s, pointer(from + (to - from) * t, None)));
        }
        actions.extend(frame(&ctx, &mut l, &s, pointer(to, Some(false))));
        actions.extend(frame(&ctx, &mut l, &s, vec![]));
        let moves: Vec<&LayerOp> = actions
            .iter()
            .filter_map(|a| if let Action::Layer(op) = a { Some(op) } else { None })
            .filter(|op| op.op == LayerOpKind::Move)
            .collect();
        assert_eq!(moves.len(), 1, "one move");
        assert_eq!((moves[0].layer.as_deref(), moves[0].to), (Some("bottom"), Some(2)));
        // A click on a handle without moving is no move.
        let (_, _, handle) = find(&l, 1);
        let mut actions = frame(&ctx, &mut l, &s, pointer(handle.center(), Some(true)));
        actions.extend(frame(&ctx, &mut l, &s, pointer(handle.center(), Some(false))));
        assert!(!actions.iter().any(|a| matches!(a, Action::Layer(op) if op.op == LayerOpKind::Move)));
    }
}

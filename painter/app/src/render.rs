//! `octopaint render`: pictures of a document to share (docs/render.md). One
//! PNG from a camera (by default the view that frames everything painted,
//! the window's first view), or a turntable: N frames on a circle around the
//! painting's centre, written as PNGs and as one looping animated GIF.
//!
//! Every argument is checked and the document read before anything is
//! written; each file is written whole or not at all (a temporary file,
//! fsync, rename). An interrupted turntable leaves the frames written so far
//! and no GIF; the GIF streams into its temporary file frame by frame, so a
//! long turntable does not hold its frames in memory.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame, RgbaImage};
use indicatif::{ProgressBar, ProgressStyle};
use octopaint_doc::Session;
use octopaint_gpu::{Precision, Renderer};
use octopaint_tree::Tree;
use octopaint_tree::raycast::{LayerInput, RayInput, RayParams};
use octopaint_tree::trace::{Camera, Light, MAX_IMAGE_SIZE};
use octopaint_tree::view::{BACKGROUND, DEFAULT_LIGHT, OrbitCamera, frame_trees};

/// The most frames a turntable takes (one per 0.1°).
pub const MAX_FRAMES: u32 = 3600;

#[derive(clap::Args)]
pub struct Args {
    /// The document (.octo); it is read, never changed.
    doc: PathBuf,
    /// The camera as a trace's camera event holds it (spec 12): a JSON
    /// object with eye, q, fov, size and optionally background. Default:
    /// the view that frames everything painted. Not with --turntable.
    #[arg(long, conflicts_with = "turntable")]
    camera: Option<String>,
    /// Picture size, WxH pixels (default: the camera's, else 1280x720).
    #[arg(long)]
    size: Option<String>,
    /// Where to write: a .png, or with --turntable a folder (created if
    /// missing) that receives frame-000.png, frame-001.png, ... and
    /// turntable.gif.
    #[arg(long)]
    out: PathBuf,
    /// Render N frames around the painting's centre (one full turn, the
    /// camera looking at the centre from the framing view's distance).
    #[arg(long, value_name = "N")]
    turntable: Option<u32>,
    /// With --turntable: the camera's height above the centre, degrees
    /// (default: the framing view's, about 20, so that frame 0 is the
    /// default single picture).
    #[arg(long, allow_negative_numbers = true, requires = "turntable")]
    elevation: Option<f64>,
    /// With --turntable: how long the GIF shows each frame, ms (10..10000).
    #[arg(long, default_value_t = 50, requires = "turntable")]
    frame_ms: u32,
    /// Draw the ground grid and horizon behind the painting (the desktop
    /// window's aid; docs/desktop.md).
    #[arg(long)]
    grid: bool,
    /// Light the painting (docs/spec.md 6.1) with the desktop window's
    /// default light: from above, slightly right and in front.
    #[arg(long)]
    lit: bool,
    /// Light the painting with this light: a JSON object as a trace's
    /// light event holds it, e.g. '{"dir": [0.4, 1, 0.3], "intensity": 1,
    /// "ambient": 0.25, "shadows": true}'.
    #[arg(long, conflicts_with = "lit")]
    light: Option<String>,
    /// Cast a shadow ray per pixel (implies --lit without --light).
    #[arg(long)]
    shadows: bool,
    /// Who draws: the GPU ray caster or its CPU port.
    #[arg(long, value_enum, default_value_t = crate::RendererChoice::Gpu)]
    renderer: crate::RendererChoice,
    /// The graphics API of the GPU renderer.
    #[arg(long, value_enum, default_value_t = crate::BackendChoice::Auto)]
    backend: crate::BackendChoice,
    /// Precision of the GPU ray caster's positions.
    #[arg(long, value_enum, default_value_t = crate::PrecisionChoice::F32)]
    precision: crate::PrecisionChoice,
    /// Level of detail (docs/spec.md 7): rays stop at cells no wider than
    /// K pixels' footprints and draw their prefiltered value; 0 (the
    /// default) walks every ray to the leaves, 1 is about one cell per
    /// pixel (the window's default).
    #[arg(long, value_name = "K", default_value_t = 0.0, value_parser = crate::lod_arg)]
    lod: f64,
    /// Print nothing but errors.
    #[arg(long)]
    quiet: bool,
}

/// What to render, fully checked.
struct Plan {
    cameras: Vec<Camera>,
    /// None: unlit.
    light: Option<Light>,
    /// Some(folder) for a turntable.
    folder: Option<PathBuf>,
}

fn refuse(msg: impl AsRef<str>) -> ExitCode {
    eprintln!("octopaint: render: {}", msg.as_ref());
    ExitCode::from(2)
}

fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s.split_once('x').ok_or_else(|| format!("--size {s:?}: expected WxH, e.g. 1280x720"))?;
    let dim = |v: &str| v.trim().parse::<u32>().ok().filter(|&v| (1..=MAX_IMAGE_SIZE as u32).contains(&v));
    match (dim(w), dim(h)) {
        (Some(w), Some(h)) => Ok([w, h]),
        _ => Err(format!("--size {s:?}: each side must be a whole number from 1 to {MAX_IMAGE_SIZE}")),
    }
}

/// The turntable's cameras: `n` yaws evenly spread over one turn, starting
/// at `start`'s, at its pitch, looking at its target.
pub fn turntable(start: &OrbitCamera, n: u32, size: [u32; 2]) -> Vec<Camera> {
    (0..n)
        .map(|k| {
            let yaw = start.yaw + std::f64::consts::TAU * f64::from(k) / f64::from(n);
            OrbitCamera { yaw, ..*start }.camera(size, BACKGROUND)
        })
        .collect()
}

/// The light of --lit, --light and --shadows; None: unlit.
fn light_arg(a: &Args) -> Result<Option<Light>, String> {
    let mut light = match &a.light {
        Some(text) => Some(crate::event_arg("--light", text, octopaint_tree::trace::parse_light)?),
        None if a.lit || a.shadows => Some(DEFAULT_LIGHT),
        None => None,
    };
    if a.shadows
        && let Some(l) = light.as_mut()
    {
        l.shadows = true;
    }
    Ok(light)
}

fn plan(a: &Args, trees: &[&Tree]) -> Result<Plan, String> {
    let size = a.size.as_deref().map(parse_size).transpose()?;
    let light = light_arg(a)?;
    if let Some(n) = a.turntable {
        if !(1..=MAX_FRAMES).contains(&n) {
            return Err(format!("--turntable {n}: from 1 to {MAX_FRAMES} frames"));
        }
        // The framing view, raised to --elevation when given.
        let mut start = frame_trees(trees);
        if let Some(elevation) = a.elevation {
            if !(elevation.is_finite() && elevation.abs() < 90.0) {
                return Err(format!("--elevation {elevation}: must be strictly between -90 and 90 degrees"));
            }
            start.pitch = -elevation.to_radians();
        }
        if !(10..=10_000).contains(&a.frame_ms) {
            return Err(format!("--frame-ms {}: from 10 to 10000", a.frame_ms));
        }
        if a.out.is_file() {
            return Err(format!("--out {}: with --turntable it is a folder, and a file of that name exists", a.out.display()));
        }
        let cameras = turntable(&start, n, size.unwrap_or([1280, 720]));
        return Ok(Plan { cameras, light, folder: Some(a.out.clone()) });
    }
    if a.out.is_dir() {
        return Err(format!("--out {}: is a folder; a single picture needs a file name (.png)", a.out.display()));
    }
    let camera = match &a.camera {
        Some(text) => {
            let mut c = crate::camera_arg(text)?;
            if let Some(s) = size {
                c.size = s;
            }
            c
        }
        None => frame_trees(trees).camera(size.unwrap_or([1280, 720]), BACKGROUND),
    };
    Ok(Plan { cameras: vec![camera], light, folder: None })
}

enum Draw {
    Gpu(Box<Renderer>, Precision),
    /// The CPU port, with each layer's rows of g3 and shading vectors.
    Cpu(Vec<Vec<[u32; 4]>>),
}

impl Draw {
    /// The image of `layers` (each tree with its opacity; one at opacity 1
    /// for a one-tree document): the one-tree ray caster, or the march
    /// through every layer (spec 6.2).
    fn image(&mut self, layers: &[(&Tree, f32)], camera: &Camera, grid: bool, light: Option<&Light>, lod: f64) -> Result<Vec<u8>, String> {
        let mut params = RayParams::new(&layers[0].0.lat, camera).with_light(light).with_lod(camera, lod);
        if grid {
            params = params.with_grid(camera.eye);
        }
        // One layer at opacity 1 (a one-tree document) stays in the pages
        // between frames: the renderer follows it (synced by `drawer`).
        let one = layers.len() == 1 && layers[0].1 == 1.0;
        match self {
            Draw::Gpu(r, precision) => match if one { r.cast_params(&params, *precision) } else { r.render_layers(layers, &params, *precision) } {
                Ok(rgb) => Ok(rgb),
                // Larger than the GPU can bind: the CPU port draws this and
                // every later frame (they have the same size).
                Err(e @ (octopaint_gpu::GpuError::TooBig(_) | octopaint_gpu::GpuError::Capacity { .. })) => {
                    eprintln!("octopaint: render: {e}; drawn by the CPU port instead");
                    *self = Draw::Cpu(layers.iter().map(|(t, _)| octopaint_tree::normals::table(t)).collect());
                    self.image(layers, camera, grid, light, lod)
                }
                Err(e) => Err(e.to_string()),
            },
            Draw::Cpu(g3) => {
                let inputs: Vec<LayerInput> = layers.iter().zip(g3.iter()).map(|((t, o), g)| LayerInput { inp: RayInput::of(t, g), opacity: *o }).collect();
                Ok(octopaint_tree::raycast::render_layers(&inputs, &params))
            }
        }
    }
}

fn drawer(a: &Args, layers: &mut [&mut Tree]) -> Result<Draw, String> {
    match a.renderer {
        crate::RendererChoice::Cpu => Ok(Draw::Cpu(layers.iter().map(|t| octopaint_tree::normals::table(t)).collect())),
        crate::RendererChoice::None => Err("--renderer none draws nothing: use gpu or cpu".into()),
        crate::RendererChoice::Gpu => {
            let precision = Precision::from(a.precision);
            let mut r = Renderer::new(a.backend.into()).map_err(|e| format!("{e}; --renderer cpu draws on the CPU"))?;
            if !r.gpu.supports(precision) {
                return Err(format!("{} has no SHADER_F16 for --precision f16", r.gpu.describe()));
            }
            if !a.quiet {
                eprintln!("octopaint: rendering on {}", r.gpu.describe());
            }
            if let [tree] = layers {
                r.sync(tree).map_err(|e| e.to_string())?;
            }
            Ok(Draw::Gpu(Box::new(r), precision))
        }
    }
}

fn write_png(path: &Path, rgb: &[u8], size: [u32; 2]) -> Result<(), String> {
    octopaint_gpu::image::write_png(path, rgb, size[0], size[1])
        .map_err(|e| format!("cannot write {}: {}", path.display(), octopaint_tree::trace::io_reason(&e)))
}

pub fn run(a: &Args) -> ExitCode {
    // Read and check everything before writing anything.
    let mut session = match Session::open_read(&a.doc) {
        Ok(s) => s,
        Err(e) => return refuse(format!("{}: {e}", a.doc.display())),
    };
    // A document of layers draws its contributing ones (spec 6.2); a
    // one-tree document its tree, through the one-tree ray caster.
    let opacity: Vec<f32> = session.doc.layers().filter(|l| l.contributes()).map(|l| l.opacity).collect();
    let one_tree = session.version == 1;
    let mut trees: Vec<Tree> = if one_tree { Vec::new() } else { session.doc.layers().filter(|l| l.contributes()).map(|l| l.tree().clone()).collect() };
    let mut own = if one_tree { Some(&mut session.painting_mut().tree) } else { None };
    let mut refs: Vec<&mut Tree> = match own.take() {
        Some(t) => vec![t],
        None => trees.iter_mut().collect(),
    };
    if refs.is_empty() {
        return refuse(format!("{}: no layer is visible with an opacity above 0: nothing to draw", a.doc.display()));
    }
    let plan = {
        let shown: Vec<&Tree> = refs.iter().map(|t| &**t).collect();
        match plan(a, &shown) {
            Ok(p) => p,
            Err(e) => return refuse(e),
        }
    };
    let mut draw = match drawer(a, &mut refs) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("octopaint: render: {e}");
            return ExitCode::from(1);
        }
    };
    if let Some(dir) = &plan.folder
        && let Err(e) = std::fs::create_dir_all(dir)
    {
        eprintln!("octopaint: render: cannot create {}: {}", dir.display(), octopaint_tree::trace::io_reason(&e));
        return ExitCode::from(1);
    }
    let bar = ProgressBar::new(plan.cameras.len() as u64);
    bar.set_style(ProgressStyle::with_template("{spinner} rendering {pos}/{len} [{elapsed_precise}] {wide_bar}").expect("static template"));
    if a.quiet || plan.folder.is_none() {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let t0 = Instant::now();
    // Each frame: drawn, written as a PNG, and (turntables) encoded into
    // the GIF, which streams into a temporary file that replaces
    // turntable.gif only once every frame is in (durable::write_with).
    let mut frame = |k: usize, camera: &Camera, gif: Option<&mut GifEncoder<&mut octopaint_platform::durable::Out>>| -> Result<(), String> {
        let layers: Vec<(&Tree, f32)> = if one_tree { vec![(&*refs[0], 1.0)] } else { refs.iter().map(|t| &**t).zip(opacity.iter().copied()).collect() };
        let rgb = draw.image(&layers, camera, a.grid, plan.light.as_ref(), a.lod)?;
        let path = match &plan.folder {
            Some(dir) => dir.join(format!("frame-{k:03}.png")),
            None => a.out.clone(),
        };
        write_png(&path, &rgb, camera.size)?;
        if let Some(enc) = gif {
            let rgba: Vec<u8> = rgb.chunks_exact(3).flat_map(|p| [p[0], p[1], p[2], 255]).collect();
            let img = RgbaImage::from_raw(camera.size[0], camera.size[1], rgba).expect("w·h·4 bytes");
            enc.encode_frame(Frame::from_parts(img, 0, 0, Delay::from_numer_denom_ms(a.frame_ms, 1))).map_err(|e| format!("GIF: {e}"))?;
        }
        bar.inc(1);
        Ok(())
    };
    let gif_path = plan.folder.as_ref().map(|dir| dir.join("turntable.gif"));
    let result = match &gif_path {
        None => frame(0, &plan.cameras[0], None),
        Some(path) => {
            let mut failed = None;
            let written = octopaint_platform::durable::write_with(path, |w| {
                let mut enc = GifEncoder::new_with_speed(w, 10);
                enc.set_repeat(Repeat::Infinite).map_err(std::io::Error::other)?;
                for (k, camera) in plan.cameras.iter().enumerate() {
                    if let Err(e) = frame(k, camera, Some(&mut enc)) {
                        failed = Some(e.clone());
                        return Err(std::io::Error::other(e));
                    }
                }
                Ok(())
            });
            match (written, failed) {
                (Ok(_), _) => Ok(()),
                (Err(_), Some(e)) => Err(e),
                (Err(e), None) => Err(format!("cannot write {}: {}", path.display(), octopaint_tree::trace::io_reason(&e))),
            }
        }
    };
    bar.finish_and_clear();
    if let Err(e) = result {
        eprintln!("octopaint: render: {e}");
        return ExitCode::from(1);
    }
    let seconds = t0.elapsed().as_secs_f64();
    let [w, h] = plan.cameras[0].size;
    match &plan.folder {
        Some(dir) => {
            let path = gif_path.as_ref().expect("a turntable writes a GIF");
            if !a.quiet {
                let n = plan.cameras.len();
                eprintln!(
                    "octopaint: {n} frames of {w}x{h} in {seconds:.1} s ({:.0} ms each): {}/frame-*.png and {}",
                    seconds * 1e3 / n as f64,
                    dir.display(),
                    path.display()
                );
            }
        }
        None if !a.quiet => eprintln!("octopaint: {w}x{h} in {:.0} ms: {}", seconds * 1e3, a.out.display()),
        None => {}
    }
    ExitCode::SUCCESS
}

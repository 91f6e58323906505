//! `octopaint replay`: a trace replayed to tree dumps at its snapshot
//! events and images at its render events (spec 12.3), drawn by the GPU
//! pipeline or the CPU port of its shaders, at one or more levels of
//! detail (spec 7).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use indicatif::{ProgressBar, ProgressStyle};
use octopaint_gpu::{Precision, Renderer};
use octopaint_tree::layers::Document;
use octopaint_tree::paint::Painting;
use octopaint_tree::pool::CellRecord;
use octopaint_tree::raycast::{LayerInput, RayInput, RayParams};
use octopaint_tree::replay::{ReplayObserver, replay};
use octopaint_tree::trace::{Camera, Event, Light, read_trace};

use crate::{BackendChoice, PrecisionChoice, RendererChoice};

/// Prints warnings as they happen; shows progress on a terminal; records a
/// cell's history when asked.
struct Reporter<'a> {
    trace: &'a Path,
    bar: ProgressBar,
    history: Option<(u32, CellRecord)>,
    draw: Draw,
    /// The trace's version: 2 is a document of layers (spec 14), drawn by
    /// one march through every contributing layer (spec 6.2).
    version: u32,
    /// The levels of detail every image is drawn at (`--lod`).
    lods: Vec<(String, f64)>,
}

/// `--lod`'s value: (text as given, k) per level.
#[derive(Clone, Debug)]
pub(crate) struct Lods(pub Vec<(String, f64)>);

pub(crate) fn parse_lods_arg(text: &str) -> Result<Lods, String> {
    octopaint_tree::raycast::parse_lods(text).map(Lods)
}

/// Who draws the images and computes the dumps' g3.
enum Draw {
    Gpu(Box<Renderer>, Precision),
    Cpu,
    Nobody,
}

impl Reporter<'_> {
    /// The image of `doc` with `params` (None: this reporter draws none).
    fn draw_image(&mut self, name: &str, params: &RayParams, doc: &mut Document) -> std::io::Result<Option<Vec<u8>>> {
        if self.version == 2 {
            // A document: one march through its contributing layers (spec
            // 6.2), on the GPU with every layer's pools in the pages, or in
            // the CPU port.
            let contributing: Vec<&octopaint_tree::layers::Layer> = doc.layers().filter(|l| l.contributes()).collect();
            let cpu_layers = || {
                let g3: Vec<Vec<[u32; 4]>> = contributing.iter().map(|l| octopaint_tree::normals::table(l.tree())).collect();
                let layers: Vec<LayerInput> =
                    contributing.iter().zip(&g3).map(|(l, g3)| LayerInput { inp: RayInput::of(l.tree(), g3), opacity: l.opacity }).collect();
                octopaint_tree::raycast::render_layers(&layers, params)
            };
            let rgb = match &mut self.draw {
                Draw::Nobody => return Ok(None),
                Draw::Cpu => cpu_layers(),
                Draw::Gpu(renderer, precision) => {
                    let trees: Vec<(&octopaint_tree::Tree, f32)> = contributing.iter().map(|l| (l.tree(), l.opacity)).collect();
                    match renderer.render_layers(&trees, params, *precision) {
                        Ok(rgb) => rgb,
                        // More than one binding of pixels or the pages hold.
                        Err(e @ (octopaint_gpu::GpuError::TooBig(_) | octopaint_gpu::GpuError::Capacity { .. })) => {
                            self.bar.suspend(|| eprintln!("octopaint: render {name:?}: {e}; drawn by the CPU port instead"));
                            cpu_layers()
                        }
                        Err(e) => return Err(std::io::Error::other(format!("render {name:?}: {e}"))),
                    }
                }
            };
            return Ok(Some(rgb));
        }
        let painting = &mut doc.current_mut().painting;
        let cpu = |tree: &octopaint_tree::Tree| {
            let rows = octopaint_tree::normals::table(tree);
            let inp = RayInput::of(tree, &rows);
            octopaint_tree::raycast::render(&inp, params)
        };
        let rgb = match &mut self.draw {
            Draw::Nobody => return Ok(None),
            Draw::Gpu(renderer, precision) => match renderer.sync(&mut painting.tree).and_then(|_| renderer.cast_params(params, *precision)) {
                Ok(rgb) => rgb,
                // An image the GPU cannot hold in one binding (a trace may
                // ask for 16384 x 16384): the CPU port draws it.
                Err(octopaint_gpu::GpuError::TooBig(why)) => {
                    self.bar.suspend(|| eprintln!("octopaint: render {name:?}: {why}; drawn by the CPU port instead"));
                    cpu(&painting.tree)
                }
                Err(e) => return Err(std::io::Error::other(format!("render {name:?}: {e}"))),
            },
            Draw::Cpu => cpu(&painting.tree),
        };
        Ok(Some(rgb))
    }
}

impl ReplayObserver for Reporter<'_> {
    fn warning(&mut self, msg: &str) {
        self.bar.suspend(|| eprintln!("octopaint: warning: {}: {msg}", self.trace.display()));
    }

    fn after_event(&mut self, ev: &Event, painting: &Painting) {
        self.bar.inc(1);
        if let Some((cell, last)) = &mut self.history {
            let now = painting.tree.record(*cell);
            if !now.same_bits(last) {
                let kind = ev.kind.ev();
                println!(
                    "history: line {} {kind}: parent {} first_child {} depth {} rgb {:?} sigma {:?}",
                    ev.line,
                    now.parent,
                    now.first_child,
                    now.depth,
                    now.rgb,
                    f64::from(now.sigma)
                );
                *last = now;
            }
        }
    }

    fn render(&mut self, name: &str, camera: &Camera, light: Option<&Light>, doc: &mut Document, out_dir: Option<&Path>) -> std::io::Result<Vec<PathBuf>> {
        let [w, h] = camera.size;
        let mut written = Vec::new();
        for (text, k) in self.lods.clone() {
            let params = RayParams::new(&doc.layer(0).tree().lat, camera).with_light(light).with_lod(camera, k);
            let name = if k == 0.0 { name.to_string() } else { format!("{name}.lod{text}") };
            let Some(rgb) = self.draw_image(&name, &params, doc)? else { return Ok(written) };
            let Some(dir) = out_dir else { continue };
            let path = dir.join(format!("{name}.png"));
            octopaint_gpu::image::write_png(&path, &rgb, w, h)?;
            written.push(path);
        }
        Ok(written)
    }

    fn dump_g3(&mut self, painting: &mut Painting) -> std::io::Result<Option<Vec<[u32; 3]>>> {
        match &mut self.draw {
            Draw::Gpu(renderer, _) => renderer.read_g3(&mut painting.tree).map(Some).map_err(std::io::Error::other),
            _ => Ok(None),
        }
    }
}

pub(crate) struct DrawOptions {
    pub renderer: RendererChoice,
    pub backend: BackendChoice,
    pub precision: PrecisionChoice,
    pub lods: Vec<(String, f64)>,
}

pub(crate) fn cmd_replay(trace_path: &Path, out: &Path, quiet: bool, history: Option<u32>, opts: DrawOptions) -> ExitCode {
    let trace = match read_trace(trace_path) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("octopaint: {}: {e}", trace_path.display());
            return ExitCode::from(2);
        }
    };
    let bar = ProgressBar::new(trace.events.len() as u64);
    bar.set_style(ProgressStyle::with_template("{spinner} replaying {pos}/{len} events [{elapsed_precise}] {wide_bar}").expect("static template"));
    if quiet {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let draw = match opts.renderer {
        RendererChoice::None => Draw::Nobody,
        RendererChoice::Cpu => Draw::Cpu,
        RendererChoice::Gpu => {
            let precision = Precision::from(opts.precision);
            match Renderer::new(opts.backend.into()) {
                Ok(r) if r.gpu.supports(precision) => {
                    if !quiet {
                        eprintln!("octopaint: rendering on {}", r.gpu.describe());
                    }
                    Draw::Gpu(Box::new(r), precision)
                }
                Ok(r) => {
                    eprintln!("octopaint: {} has no SHADER_F16 for --precision f16", r.gpu.describe());
                    return ExitCode::from(1);
                }
                Err(e) => {
                    eprintln!("octopaint: {e}; --renderer cpu draws on the CPU, --renderer none skips images");
                    return ExitCode::from(1);
                }
            }
        }
    };
    let mut rep = Reporter { trace: trace_path, bar, history: history.map(|c| (c, CellRecord::FREE)), draw, version: trace.version, lods: opts.lods };
    let result = replay(&trace, Some(out), &mut rep);
    rep.bar.finish_and_clear();
    let (stats, _) = match result {
        Ok(r) => r,
        Err(e) => {
            eprintln!("octopaint: {}: cannot write to {}: {}", trace_path.display(), out.display(), octopaint_tree::trace::io_reason(&e));
            return ExitCode::from(1);
        }
    };
    if !stats.renders.is_empty() {
        eprintln!("octopaint: {} render event(s) not drawn (--renderer none)", stats.renders.len());
    }
    if !quiet {
        eprintln!(
            "replayed {} strokes, {} samples in {:.2} s: {} cells in use, deepest cell at depth {}",
            stats.strokes, stats.samples, stats.seconds, stats.cells, stats.deepest
        );
        for p in &stats.written {
            println!("{}", p.display());
        }
    }
    ExitCode::SUCCESS
}

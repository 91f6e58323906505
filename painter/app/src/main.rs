//! `octopaint`: the painter's command line: headless replay of traces to
//! tree dumps and images, trace validation, exports to other tools, and
//! the benchmarks.

mod bench_doc;
mod bench_gpu;
mod bench_realtime;
mod bench_soak;
mod bench_tree;
mod canonical;
mod document;
mod export;
mod fuzz_smoke;
mod imports;
mod probe;
mod render;
mod replay_cmd;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use octopaint_gpu::{Backend, Precision};
use octopaint_tree::trace::{Camera, read_trace};
use replay_cmd::{DrawOptions, Lods, cmd_replay, parse_lods_arg};

#[derive(Parser)]
#[command(
    name = "octopaint",
    version,
    about = "Octopaint, volumetric painting on a dynamic deep octree",
    after_help = "With no command, paints on painting.octo in the Octopaint folder of your Documents (OCTOPAINT_HOME \
                  overrides it): in the headset when an OpenXR runtime is running, else in the desktop window."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Replay a trace: write DIR/<name>.npz tree dumps at its snapshot events.
    ///
    /// The whole trace is validated first; a malformed trace is refused
    /// with a message naming its line and field, and nothing is written
    /// (exit status 2).
    Replay {
        /// A .jsonl trace (docs/spec.md section 12).
        trace: PathBuf,
        /// Output folder, created if missing.
        #[arg(long)]
        out: PathBuf,
        /// Print nothing but warnings and errors.
        #[arg(long)]
        quiet: bool,
        /// Print every change of this cell's record, event by event (the
        /// conformance report uses it to show a differing cell's history).
        #[arg(long, value_name = "CELL")]
        history: Option<u32>,
        /// Who draws the images at render events and computes g3 for the
        /// dumps: the GPU pipeline (the default), the CPU port of its
        /// shaders, or nobody (dumps only, g3 from the CPU port).
        #[arg(long, value_enum, default_value_t = RendererChoice::Gpu)]
        renderer: RendererChoice,
        /// The graphics API of the GPU renderer.
        #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
        backend: BackendChoice,
        /// Precision of the GPU ray caster's positions (f16 needs an adapter
        /// with SHADER_F16).
        #[arg(long, value_enum, default_value_t = PrecisionChoice::F32)]
        precision: PrecisionChoice,
        /// Levels of detail of every image (docs/spec.md 7): 0, the
        /// default, walks to the leaves and writes <name>.png; any other k
        /// writes <name>.lod<k>.png, k as given (for example --lod 0,1).
        #[arg(long, value_name = "K[,K...]", default_value = "0", value_parser = parse_lods_arg)]
        lod: Lods,
    },
    /// Validate traces without replaying them: print `PATH: ok` or
    /// `PATH: MESSAGE` for each (exit status 2 if any is malformed).
    Check {
        traces: Vec<PathBuf>,
        /// Print each trace as parsed, one canonical line per event (the
        /// conformance driver compares it with the reference reader's).
        #[arg(long)]
        canonical: bool,
    },
    /// Export a painting for other tools: an OpenVDB volume (density and
    /// colour grids) and iso-surface meshes (glTF binary, OBJ).
    ///
    /// Every refusal (a depth too fine for --max-mib, too many triangles,
    /// a malformed input) happens before any file is written (exit status
    /// 2); each file is written whole or not at all.
    Export(export::Args),
    /// Paint in a desktop window on a document (created with a default
    /// canvas if missing): the GPU ray caster, mouse painting, a brush
    /// panel and a status line (docs/desktop.md). Closing saves.
    Window {
        /// The document (.octo).
        doc: PathBuf,
        /// Window size, WxH pixels.
        #[arg(long, default_value = "1280x720")]
        size: String,
        /// Precision of the ray caster's positions.
        #[arg(long, value_enum, default_value_t = PrecisionChoice::F32)]
        precision: PrecisionChoice,
        /// Where F12 (or the Screenshot button) writes the window's
        /// picture. Default: DOC with .png.
        #[arg(long)]
        screenshot: Option<PathBuf>,
        /// Cast every frame at the window's size: no dynamic resolution
        /// while the view moves (docs/desktop.md).
        #[arg(long)]
        fixed_resolution: bool,
        /// Write one CSV line per frame (time, frame interval, resolution
        /// scale, cast size, still, mirror planes, whether rays were cast)
        /// to this file.
        #[arg(long, value_name = "CSV")]
        frame_log: Option<PathBuf>,
        /// Play this trace's events into the document at their recorded
        /// pace, as live input (a timelapse; the trace needs the document's
        /// canvas).
        #[arg(long, value_name = "TRACE")]
        play: Option<PathBuf>,
        /// Close the window (saving) once the played trace is painted.
        #[arg(long, requires = "play")]
        exit_after_play: bool,
        /// Tests: while this file exists the stroke thread waits before
        /// each level of painting.
        #[arg(long, value_name = "FILE", hide = true)]
        hold_painting: Option<PathBuf>,
        /// Level of detail (docs/spec.md 7): rays stop at cells no wider
        /// than K pixels' footprints; 0 walks every ray to the leaves.
        /// Default: 1, or 0 on a CPU Vulkan such as lavapipe (there the
        /// cut's walk costs more than it saves).
        #[arg(long, value_name = "K", value_parser = lod_arg)]
        lod: Option<f64>,
    },
    /// Show a document in the headset through OpenXR: each eye ray cast
    /// with its own pose and field of view, paced by the runtime
    /// (docs/vr.md). With no OpenXR runtime or headset it says so and
    /// opens the desktop window instead.
    Vr {
        /// The document (.octo).
        doc: PathBuf,
        /// Stop after this many frames (scripts and tests).
        #[arg(long)]
        frames: Option<u64>,
        /// Write the last frame's two eyes side by side (PNG); needs --frames.
        #[arg(long, requires = "frames")]
        capture: Option<PathBuf>,
        /// Precision of the ray caster's positions.
        #[arg(long, value_enum, default_value_t = PrecisionChoice::F32)]
        precision: PrecisionChoice,
        /// Exit with status 3 instead of opening the desktop window when
        /// there is no VR.
        #[arg(long)]
        no_fallback: bool,
        /// Scripted controller states to use instead of the controllers'
        /// (JSON lines; docs/vr.md): a headset without hands, a test.
        #[arg(long, value_name = "SCRIPT.jsonl")]
        script: Option<PathBuf>,
        /// Cast every frame at the eye's full size (no dynamic resolution).
        #[arg(long)]
        fixed_resolution: bool,
        /// Write one CSV line per frame (the window's frame log: time,
        /// interval, scale, cast size, still, mirror planes, whether rays
        /// were cast, what the stroke thread was doing, upload time).
        #[arg(long, value_name = "CSV")]
        frame_log: Option<PathBuf>,
        /// Play this trace's events into the document at their recorded
        /// pace, as live input (the trace needs the document's canvas);
        /// --frames counts on until all of them are painted.
        #[arg(long, value_name = "TRACE")]
        play: Option<PathBuf>,
        /// Tests: while this file exists the stroke thread waits before
        /// each level of painting.
        #[arg(long, value_name = "FILE", hide = true)]
        hold_painting: Option<PathBuf>,
        /// Level of detail (docs/spec.md 7): rays stop at cells no wider
        /// than K pixels' footprints; 1 is about a cell per pixel, 0 walks
        /// every ray to the leaves.
        #[arg(long, value_name = "K", default_value_t = octopaint_tree::raycast::DEFAULT_LOD, value_parser = lod_arg)]
        lod: f64,
    },
    /// Find the OpenXR runtime and headset and print what they offer, or
    /// exactly what is missing (exit status 3 when there is no VR here).
    XrInfo,
    /// Create an empty document (docs/documents.md).
    New(document::NewArgs),
    /// Replay a trace into a new document: its whole session, undo history
    /// included.
    Import { trace: PathBuf, doc: PathBuf },
    /// Paint an OpenVDB fog volume (density, optional colour) into a layer
    /// of a document, resampled at a chosen depth, as one undoable step
    /// (docs/documents.md, "Imports").
    ImportVdb(imports::VdbArgs),
    /// Paint a closed triangle mesh (glTF or OBJ) into a layer of a
    /// document as solid voxels with its colours, as one undoable step; a
    /// mesh with holes is refused, saying where (docs/documents.md).
    ImportMesh(imports::MeshArgs),
    /// Paint on a document with the events of a trace, as a live session:
    /// each completed stroke is journalled (synced to disk) before the next
    /// one, and the document is saved at the end.
    Paint(document::PaintArgs),
    /// Describe a document: canvas, session, tree, undo history, unsaved
    /// strokes in its journal.
    Info { doc: PathBuf },
    /// Open a document, replay the complete strokes its journal holds
    /// (after a crash) and save it.
    Recover { doc: PathBuf },
    /// Write a document's whole session as a trace that `octopaint replay`
    /// and `octopaint-ref replay` reproduce exactly (unsaved strokes in its
    /// journal included).
    Record {
        doc: PathBuf,
        /// The trace to write.
        #[arg(long)]
        out: PathBuf,
    },
    /// Write a document's tree as a dump (.npz, spec 11: what `replay`
    /// writes at snapshots; `octopaint-ref check` reads it).
    Dump {
        doc: PathBuf,
        /// The .npz to write.
        out: PathBuf,
    },
    /// Undo the last strokes of a document, and save it.
    Undo(document::StepArgs),
    /// Redo undone strokes of a document, and save it.
    Redo(document::StepArgs),
    /// Render a document to a PNG, or a turntable around the painting
    /// (PNG frames and an animated GIF) to share (docs/render.md).
    Render(render::Args),
    /// Trace every pixel's ray of a camera through a tree dump with the
    /// GPU ray caster and write one record per ray (.npz): where it
    /// stopped and why, where it started. The precision study compares
    /// them with the reference and mpmath (docs/precision.md).
    Probe(probe::Args),
    /// Run every fuzz target's body on its seeds and deterministic variants
    /// of them (CI's short fuzzing run; docs/documents.md, "Fuzzing").
    #[command(hide = true)]
    FuzzSmoke(fuzz_smoke::Args),
    /// Benchmarks that print figures (docs/benchmarks.md).
    Bench {
        #[command(subcommand)]
        which: Bench,
    },
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum RendererChoice {
    Gpu,
    Cpu,
    None,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum BackendChoice {
    Auto,
    Vulkan,
    Gl,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum PrecisionChoice {
    F32,
    F16,
}

impl From<BackendChoice> for Backend {
    fn from(c: BackendChoice) -> Backend {
        match c {
            BackendChoice::Auto => Backend::Auto,
            BackendChoice::Vulkan => Backend::Vulkan,
            BackendChoice::Gl => Backend::Gl,
        }
    }
}

impl From<PrecisionChoice> for Precision {
    fn from(c: PrecisionChoice) -> Precision {
        match c {
            PrecisionChoice::F32 => Precision::F32,
            PrecisionChoice::F16 => Precision::F16,
        }
    }
}

/// A camera given on the command line as a trace's camera event (JSON),
/// checked by the trace reader's rules.
/// An option that takes an event's fields as a trace holds them (a JSON
/// object), read by that event's parser; errors name the option.
pub(crate) fn event_arg<T>(option: &str, text: &str, parse: fn(usize, &serde_json::Value) -> Result<T, octopaint_tree::TraceError>) -> Result<T, String> {
    let v: serde_json::Value = serde_json::from_str(text).map_err(|e| format!("{option}: not JSON: {e}"))?;
    if !v.is_object() {
        return Err(format!("{option}: expected a JSON object"));
    }
    parse(0, &v).map_err(|e| format!("{option}: {}", e.message))
}

/// `--lod K` of render, window and vr: a level of detail (docs/spec.md 7).
pub(crate) fn lod_arg(text: &str) -> Result<f64, String> {
    let k: f64 = text.parse().map_err(|_| format!("{text:?} is not a number"))?;
    octopaint_tree::raycast::check_lod(k)
}

fn camera_arg(text: &str) -> Result<Camera, String> {
    event_arg("--camera", text, octopaint_tree::trace::parse_camera)
}

#[derive(Subcommand)]
enum Bench {
    /// Stamping and refinement throughput on a deterministic stroke set.
    Tree(bench_tree::Args),
    /// The GPU pipeline on a painted trace: uploads, g3 pass, ray casting.
    Gpu(bench_gpu::Args),
    /// The real-time pipeline (the paper's Table 1, Fig. 8, Fig. 9, latency).
    Realtime(bench_realtime::Args),
    /// Documents: save and open against a tree dump of the same painting.
    Doc(bench_doc::Args),
    /// Hours of painting through the window's engine: memory, journal, saves.
    Soak(bench_soak::Args),
}

fn cmd_check(traces: &[PathBuf], canonical: bool) -> ExitCode {
    let mut status = ExitCode::SUCCESS;
    for path in traces {
        let result = read_trace(path);
        if result.is_err() {
            status = ExitCode::from(2);
        }
        if canonical {
            println!("== {}", path.display());
            for line in canonical::canonical(&result) {
                println!("{line}");
            }
        } else {
            match result {
                Ok(_) => println!("{}: ok", path.display()),
                Err(e) => println!("{}: {e}", path.display()),
            }
        }
    }
    status
}

fn xr_info() -> ExitCode {
    match octopaint_xr::probe() {
        Ok(i) => {
            println!("runtime    {} {}", i.runtime, i.runtime_version);
            println!("headset    {} (vendor {:#x}), tracking: orientation {}, position {}", i.system, i.vendor_id, i.orientation_tracking, i.position_tracking);
            for (k, v) in i.views.iter().enumerate() {
                println!("eye {k}      {}x{} recommended, {}x{} at most, {} sample(s)", v.recommended[0], v.recommended[1], v.max[0], v.max[1], v.samples);
            }
            match (&i.vulkan_min, &i.vulkan_max) {
                (Some(a), Some(b)) => println!("vulkan     XR_KHR_vulkan_enable2, Vulkan {a} to {b}"),
                _ => println!("vulkan     no XR_KHR_vulkan_enable2: the painter cannot render to this runtime"),
            }
            println!("blending   {}", i.blend_modes.join(", "));
            ExitCode::SUCCESS
        }
        Err(e) if e.is_no_vr() => {
            eprintln!("octopaint: no VR here: {e}");
            ExitCode::from(3)
        }
        Err(e) => {
            eprintln!("octopaint: {e}");
            ExitCode::from(1)
        }
    }
}

fn main() -> ExitCode {
    octopaint_platform::stdio::end_quietly_on_closed_stdout();
    let cli = Cli::parse();
    let Some(command) = cli.command else {
        return document::start();
    };
    match command {
        Command::Replay { trace, out, quiet, history, renderer, backend, precision, lod } => {
            cmd_replay(&trace, &out, quiet, history, DrawOptions { renderer, backend, precision, lods: lod.0 })
        }
        Command::Check { traces, canonical } => cmd_check(&traces, canonical),
        Command::Export(args) => export::run(&args),
        Command::New(args) => document::new(&args),
        Command::XrInfo => xr_info(),
        Command::Vr { doc, frames, capture, precision, no_fallback, script, fixed_resolution, frame_log, play, hold_painting, lod } => {
            let live = document::Live { script, play, hold_painting, frame_log };
            document::vr(&doc, frames, capture, live, precision == PrecisionChoice::F16, no_fallback, fixed_resolution, lod)
        }
        Command::Window { doc, size, precision, screenshot, fixed_resolution, frame_log, play, exit_after_play, hold_painting, lod } => document::window(
            &doc,
            &size,
            precision == PrecisionChoice::F16,
            screenshot,
            document::Frames { fixed_resolution, frame_log, play, exit_after_play, hold_painting, lod },
        ),
        Command::Import { trace, doc } => document::import(&trace, &doc),
        Command::ImportVdb(args) => imports::vdb(&args),
        Command::ImportMesh(args) => imports::mesh(&args),
        Command::Paint(args) => document::paint(&args),
        Command::Info { doc } => document::info(&doc),
        Command::Recover { doc } => document::recover(&doc),
        Command::Record { doc, out } => document::record(&doc, &out),
        Command::Dump { doc, out } => document::dump(&doc, &out),
        Command::Probe(args) => probe::run(&args),
        Command::FuzzSmoke(args) => fuzz_smoke::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Undo(args) => document::step(&args, false),
        Command::Redo(args) => document::step(&args, true),
        Command::Bench { which } => {
            let (name, done) = match which {
                Bench::Tree(args) => ("tree", bench_tree::run(&args)),
                Bench::Gpu(args) => ("gpu", bench_gpu::run(&args)),
                Bench::Realtime(args) => ("realtime", bench_realtime::run(&args)),
                Bench::Doc(args) => ("doc", bench_doc::run(&args)),
                Bench::Soak(args) => ("soak", bench_soak::run(&args)),
            };
            match done {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("octopaint: bench {name}: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
    }
}

//! The document commands: `new`, `import`, `paint`, `info`, `recover`,
//! `record`, `undo`, `redo` (docs/documents.md). `paint` is a painting
//! session without a window: the events of a trace applied one by one as
//! if an artist made them (optionally at an artist's pace), each completed
//! stroke journalled before the next, the document saved at the end.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use octopaint_doc::{DocError, Session, journal_path};
use octopaint_tree::trace::{Canvas, Event, EventKind, Meta, read_trace};

#[derive(clap::Args)]
pub struct NewArgs {
    /// The document to create (refused if a file is there).
    pub doc: PathBuf,
    /// Take the canvas from this trace's header.
    #[arg(long, value_name = "TRACE", conflicts_with_all = ["roots", "max_depth", "root_size", "capacity"])]
    pub like: Option<PathBuf>,
    /// Roots per axis, X,Y,Z (canvas = roots × root size).
    #[arg(long, value_name = "X,Y,Z", default_value = "4,4,4")]
    pub roots: String,
    /// Deepest depth a cell may reach (at most 28).
    #[arg(long, default_value_t = 24)]
    pub max_depth: u32,
    /// Edge of one root, in canvas units.
    #[arg(long, default_value_t = 1.0)]
    pub root_size: f64,
    /// Cell budget (a multiple of 8).
    #[arg(long, default_value_t = 16_777_216)]
    pub capacity: u64,
    /// A title for the document's metadata.
    #[arg(long, default_value = "untitled")]
    pub title: String,
    /// A document of layers (a version 2 session, docs/spec.md 14): it
    /// starts with one layer, `Layer 1`, and takes layer events.
    #[arg(long)]
    pub layers: bool,
}

#[derive(clap::Args)]
pub struct PaintArgs {
    /// The document to paint on (its journal, if any, is recovered first).
    pub doc: PathBuf,
    /// The events to apply: a trace with the document's canvas. Its times
    /// are taken after the document's last event.
    #[arg(long, value_name = "TRACE")]
    pub input: PathBuf,
    /// Apply at most this many events per second (an artist's pace; 0: as
    /// fast as possible).
    #[arg(long, value_name = "N", default_value_t = 0.0)]
    pub events_per_second: f64,
    /// Leave the strokes in the journal only (as a session that has not
    /// saved yet); `octopaint recover` or the next session saves them.
    #[arg(long)]
    pub no_save: bool,
    /// Undo history kept, MiB (the oldest strokes beyond it can no longer
    /// be undone).
    #[arg(long, value_name = "MIB", default_value_t = 1024)]
    pub undo_mib: usize,
    /// Print nothing but errors.
    #[arg(long)]
    pub quiet: bool,
    /// On a refused event or a journal write that fails, say so and go on
    /// with the next event, as the window and the headset do (a stroke
    /// that could not be journalled stays in the session and is written
    /// with the next flush or the save); exit status 1 at the end if any
    /// failed. Without it the session stops at the first failure.
    #[arg(long)]
    pub keep_going: bool,
}

#[derive(clap::Args)]
pub struct StepArgs {
    pub doc: PathBuf,
    /// How many strokes.
    #[arg(long, default_value_t = 1)]
    pub steps: usize,
}

fn fail(e: DocError) -> ExitCode {
    eprintln!("octopaint: {e}");
    match e {
        DocError::Io { .. } => ExitCode::from(1),
        _ => ExitCode::from(2),
    }
}

fn titled(title: &str) -> Meta {
    let mut meta = Meta::new();
    meta.insert("title".into(), title.into());
    meta
}

fn parse_roots(s: &str) -> Option<[u32; 3]> {
    let v: Vec<u32> = s.split(',').map(|x| x.trim().parse().ok()).collect::<Option<_>>()?;
    v.try_into().ok()
}

pub fn new(a: &NewArgs) -> ExitCode {
    let (canvas, meta) = match &a.like {
        Some(t) => match read_trace(t) {
            Ok(t) => (t.canvas, t.meta),
            Err(e) => {
                eprintln!("octopaint: {}: {e}", t.display());
                return ExitCode::from(2);
            }
        },
        None => {
            let Some(roots) = parse_roots(&a.roots) else {
                eprintln!("octopaint: --roots {:?}: expected three positive integers X,Y,Z", a.roots);
                return ExitCode::from(2);
            };
            let Ok(capacity) = u32::try_from(a.capacity) else {
                eprintln!("octopaint: --capacity {} is too large", a.capacity);
                return ExitCode::from(2);
            };
            let meta = titled(&a.title);
            (Canvas { roots, max_depth: a.max_depth, root_size: a.root_size, capacity }, meta)
        }
    };
    let created = if a.layers { Session::create_layered(&a.doc, &canvas, &meta) } else { Session::create(&a.doc, &canvas, &meta) };
    match created {
        Ok(_) => {
            println!("{}", a.doc.display());
            ExitCode::SUCCESS
        }
        Err(e) => fail(e),
    }
}

pub fn import(trace: &Path, doc: &Path) -> ExitCode {
    let t = match read_trace(trace) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("octopaint: {}: {e}", trace.display());
            return ExitCode::from(2);
        }
    };
    let result = (|| {
        let mut s = if t.version == 2 { Session::create_layered(doc, &t.canvas, &t.meta)? } else { Session::create(doc, &t.canvas, &t.meta)? };
        for ev in &t.events {
            s.apply(ev)?;
        }
        if s.in_stroke() {
            s.apply(&Event { line: 0, t: t.events.last().map_or(0.0, |e| e.t), kind: EventKind::StrokeEnd })?;
        }
        s.save()?;
        Ok::<_, DocError>(s)
    })();
    match result {
        Ok(s) => {
            eprintln!("{}: {} events, {} cells", doc.display(), s.event_count(), s.doc.used());
            ExitCode::SUCCESS
        }
        Err(e) => {
            // Nothing half-made stays behind.
            let _ = std::fs::remove_file(doc);
            let _ = std::fs::remove_file(journal_path(doc));
            fail(e)
        }
    }
}

fn say_recovered(s: &Session) {
    if s.recovered > 0 {
        eprintln!("octopaint: {}: recovered {} stroke(s), undo(s) and redo(s) from its journal", s.path.display(), s.recovered);
    }
}

pub fn paint(a: &PaintArgs) -> ExitCode {
    let input = match read_trace(&a.input) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("octopaint: {}: {e}", a.input.display());
            return ExitCode::from(2);
        }
    };
    let mut s = match Session::open(&a.doc) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    say_recovered(&s);
    let canvas = s.painting().tree.lat.roots;
    let (dc, ic) = (
        (canvas, s.painting().tree.lat.max_depth, s.painting().tree.lat.root_size, s.painting().tree.capacity),
        (input.canvas.roots, input.canvas.max_depth, input.canvas.root_size, input.canvas.capacity),
    );
    if dc != ic {
        eprintln!("octopaint: {}: its canvas {:?} is not the document's {:?}", a.input.display(), ic, dc);
        return ExitCode::from(2);
    }
    s.undo_bytes = a.undo_mib << 20;
    let t0 = s.last_time();
    let pace = if a.events_per_second > 0.0 { Some(Duration::from_secs_f64(1.0 / a.events_per_second)) } else { None };
    let start = Instant::now();
    let mut strokes = 0;
    let mut failed = 0;
    for (i, ev) in input.events.iter().enumerate() {
        if let Some(p) = pace {
            let due = start + p * i as u32;
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        let ev = Event { t: t0 + ev.t, ..ev.clone() };
        if let Err(e) = s.apply(&ev) {
            eprintln!("octopaint: {}: line {}: {e}", a.input.display(), ev.line);
            if !a.keep_going {
                return fail_after(e, strokes);
            }
            failed += 1;
            continue;
        }
        if matches!(ev.kind, EventKind::StrokeEnd) {
            strokes += 1;
            if !a.quiet {
                eprintln!("stroke {strokes} journalled");
            }
        }
    }
    if s.in_stroke() {
        let end = Event { line: 0, t: s.last_time(), kind: EventKind::StrokeEnd };
        if let Err(e) = s.apply(&end) {
            return fail(e);
        }
        strokes += 1;
    }
    if !a.no_save
        && let Err(e) = s.save()
    {
        return fail(e);
    }
    if !a.quiet {
        eprintln!(
            "{}: {strokes} stroke(s) painted, {} cells{}",
            a.doc.display(),
            s.painting().tree.n_used(),
            if a.no_save { " (in the journal; not saved)" } else { ", saved" }
        );
    }
    if failed > 0 {
        eprintln!("octopaint: {failed} event(s) failed (above); the rest were applied{}", if a.no_save { "" } else { " and saved" });
        return ExitCode::from(1);
    }
    ExitCode::SUCCESS
}

fn fail_after(e: DocError, strokes: usize) -> ExitCode {
    eprintln!("octopaint: the {strokes} stroke(s) before it are in the journal");
    fail(e)
}

pub fn info(doc: &Path) -> ExitCode {
    let size = std::fs::metadata(doc).map(|m| m.len()).unwrap_or(0);
    let s = match Session::open_read(doc) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    let t = &s.painting().tree;
    let l = &t.lat;
    println!("document   {} ({} bytes)", doc.display(), size);
    println!(
        "canvas     roots {}x{}x{}, root size {}, max depth {}, capacity {} cells",
        l.roots[0],
        l.roots[1],
        l.roots[2],
        l.root_size,
        l.max_depth,
        s.doc.canvas().capacity
    );
    println!("session    {} events", s.event_count());
    if s.version == 2 {
        println!("layers     {} ({} cells in use), bottom first:", s.doc.len(), s.doc.used());
        for (k, layer) in s.doc.layers().enumerate() {
            println!(
                "  {}{} {:?}: {} cells, opacity {}{}{}",
                if k == s.doc.selected() { "*" } else { " " },
                k,
                layer.name,
                layer.tree().n_used(),
                layer.opacity,
                if layer.visible { "" } else { ", hidden" },
                if layer.locked { ", locked" } else { "" }
            );
        }
    } else {
        println!("tree       {} cells in use", t.n_used());
    }
    let (done, undone) = s.doc.steps();
    println!("undo       {done} step(s) to undo, {undone} to redo, {} bytes", s.doc.history_bytes());
    if s.recovered > 0 {
        println!("journal    {} stroke(s) not saved yet, recovered here (`octopaint recover` saves them)", s.recovered);
    } else {
        println!("journal    nothing unsaved");
    }
    ExitCode::SUCCESS
}

pub fn recover(doc: &Path) -> ExitCode {
    let mut s = match Session::open(doc) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    say_recovered(&s);
    match s.save() {
        Ok(()) => {
            eprintln!("{}: saved, {} events", doc.display(), s.event_count());
            ExitCode::SUCCESS
        }
        Err(e) => fail(e),
    }
}

pub fn record(doc: &Path, out: &Path) -> ExitCode {
    let s = match Session::open_read(doc) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    say_recovered(&s);
    // The voxel sets of its imports go beside the trace, where its
    // `import` events name them (spec 15.2), before the trace itself.
    let folder = out.parent().map(Path::to_path_buf).unwrap_or_default();
    for (file, data) in s.imports() {
        let path = file.split('/').fold(folder.clone(), |p, part| p.join(part));
        let written = path.parent().map_or(Ok(()), std::fs::create_dir_all).and_then(|()| octopaint_platform::durable::write(&path, data));
        if let Err(e) = written {
            eprintln!("octopaint: cannot write {}: {}", path.display(), octopaint_tree::trace::io_reason(&e));
            return ExitCode::from(1);
        }
    }
    let text = match s.trace_text() {
        Ok(t) => t,
        Err(e) => {
            eprintln!("octopaint: {e}");
            return ExitCode::from(1);
        }
    };
    match octopaint_platform::durable::write(out, text.as_bytes()) {
        Ok(()) => {
            eprintln!("{}: {} events ({} imported voxel sets beside it)", out.display(), s.event_count(), s.imports().len());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("octopaint: cannot write {}: {}", out.display(), octopaint_tree::trace::io_reason(&e));
            ExitCode::from(1)
        }
    }
}

pub fn step(a: &StepArgs, redo: bool) -> ExitCode {
    let mut s = match Session::open(&a.doc) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    say_recovered(&s);
    let kind = if redo { EventKind::Redo } else { EventKind::Undo };
    let mut n = 0;
    for _ in 0..a.steps {
        let before = (s.doc.steps().0, s.doc.steps().1);
        if let Err(e) = s.apply(&Event { line: 0, t: s.last_time(), kind: kind.clone() }) {
            return fail(e);
        }
        if (s.doc.steps().0, s.doc.steps().1) == before {
            break;
        }
        n += 1;
    }
    if let Err(e) = s.save() {
        return fail(e);
    }
    eprintln!("{}: {} {n} stroke(s)", a.doc.display(), if redo { "redid" } else { "undid" });
    ExitCode::SUCCESS
}

/// Whether `path` starts like a document (the export command takes both).
pub fn is_document(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 12];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut head)).is_ok() && &head == b"OCTOPAINTDOC"
}

/// How the desktop window casts its frames (`octopaint window`'s options).
#[derive(Default)]
pub struct Frames {
    pub fixed_resolution: bool,
    pub frame_log: Option<PathBuf>,
    /// `--play`, `--exit-after-play`, `--hold-painting`.
    pub play: Option<PathBuf>,
    pub exit_after_play: bool,
    pub hold_painting: Option<PathBuf>,
    /// `--lod`: the level of detail the window starts at (None: its
    /// adapter's default).
    pub lod: Option<f64>,
}

pub fn window(doc: &Path, size: &str, f16: bool, screenshot: Option<PathBuf>, frames: Frames) -> ExitCode {
    let parsed: Option<Vec<u32>> = size.split('x').map(|v| v.trim().parse().ok()).collect();
    let size = match parsed.as_deref() {
        Some(&[w, h]) if (64..=16384).contains(&w) && (64..=16384).contains(&h) => [w, h],
        _ => {
            eprintln!("octopaint: --size {size:?}: expected WxH, each 64 to 16384");
            return ExitCode::from(2);
        }
    };
    if let Err(e) = create_default(doc) {
        return fail(e);
    }
    let opts = octopaint_desktop::Options {
        doc: doc.to_path_buf(),
        size,
        precision: if f16 { octopaint_gpu::Precision::F16 } else { octopaint_gpu::Precision::F32 },
        screenshot: screenshot.unwrap_or_else(|| doc.with_extension("png")),
        fixed_resolution: frames.fixed_resolution,
        frame_log: frames.frame_log,
        play: frames.play,
        exit_after_play: frames.exit_after_play,
        hold_painting: frames.hold_painting,
        lod: frames.lod,
    };
    match octopaint_desktop::run(opts) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("octopaint: {e}");
            ExitCode::from(1)
        }
    }
}

/// `octopaint` with no command, what a double-click runs: the headset (or
/// the desktop window without one) on the artist's default document,
/// created on first use.
pub fn start() -> ExitCode {
    let Some(home) = octopaint_platform::folders::octopaint_home() else {
        eprintln!("octopaint: no Documents folder is known here (set OCTOPAINT_HOME, or run octopaint window DOC)");
        return ExitCode::from(1);
    };
    if let Err(e) = std::fs::create_dir_all(&home) {
        eprintln!("octopaint: cannot make {}: {}", home.display(), octopaint_tree::trace::io_reason(&e));
        return ExitCode::from(1);
    }
    let doc = home.join("painting.octo");
    if let Err(e) = create_default(&doc) {
        return fail(e);
    }
    eprintln!("octopaint: painting on {} (octopaint --help lists every command)", doc.display());
    vr(&doc, None, None, Live { script: None, play: None, hold_painting: None, frame_log: None }, false, false, false, octopaint_tree::raycast::DEFAULT_LOD)
}

/// An empty document on the desktop window's default canvas, unless `doc`
/// exists.
fn create_default(doc: &Path) -> Result<(), DocError> {
    if doc.exists() {
        return Ok(());
    }
    let canvas = Canvas { roots: [4, 4, 4], max_depth: 24, root_size: 1.0, capacity: 16_777_216 };
    let meta = titled("untitled");
    Session::create(doc, &canvas, &meta)?;
    eprintln!("octopaint: created {} (4x4x4 roots of 1 unit, depth 24)", doc.display());
    Ok(())
}

/// What drives a VR session besides the controllers (a script of
/// controller states, a trace played, a test's hold on painting), and
/// where its frame log goes.
pub struct Live {
    pub script: Option<PathBuf>,
    pub play: Option<PathBuf>,
    pub hold_painting: Option<PathBuf>,
    pub frame_log: Option<PathBuf>,
}

#[allow(clippy::too_many_arguments)]
pub fn vr(doc: &Path, frames: Option<u64>, capture: Option<PathBuf>, live: Live, f16: bool, no_fallback: bool, fixed_resolution: bool, lod: f64) -> ExitCode {
    let s = match Session::open(doc) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    say_recovered(&s);
    let precision = if f16 { octopaint_gpu::Precision::F16 } else { octopaint_gpu::Precision::F32 };
    let Live { script, play, hold_painting, frame_log } = live;
    let opts = octopaint_xr::headset::Options { frames, precision, capture: capture.clone(), script, fixed_resolution, play, hold_painting, frame_log, lod };
    // The session saves whatever happened in the headset as it ends (the
    // journal has it too).
    match octopaint_xr::headset::run(s, &opts) {
        Ok(r) if r.save_error.is_some() => {
            eprintln!("octopaint: {} (every completed stroke is in the journal)", r.save_error.unwrap_or_default());
            ExitCode::from(1)
        }
        Ok(r) => {
            eprintln!(
                "octopaint: {} frame(s) in the headset on {}: {}x{} per eye ({}), frame interval {:.1} ms mean, {:.1} ms p50, {:.1} ms p99, {:.1} ms max; both eyes cast and drawn in {:.1} ms mean; {} stroke(s) painted, saved",
                r.frames,
                r.adapter,
                r.eye_size[0],
                r.eye_size[1],
                r.format,
                r.frame_ms.0,
                r.frame_p50_p99_ms.0,
                r.frame_p50_p99_ms.1,
                r.frame_ms.1,
                r.render_ms,
                r.strokes
            );
            eprintln!(
                "octopaint: dynamic resolution: eyes cast at {:.0}% of their size on average, {:.0}% at least; {} still frame(s) at full size, {} of them drawn from the last cast",
                r.scale.0 * 100.0,
                r.scale.1 * 100.0,
                r.still_frames,
                r.reused_frames
            );
            if let Some(p) = capture {
                eprintln!("octopaint: wrote {}", p.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) if e.is_no_vr() => {
            if no_fallback {
                eprintln!("octopaint: no VR here: {e}");
                return ExitCode::from(3);
            }
            eprintln!("octopaint: no VR here: {e}; opening the desktop window instead");
            window(doc, "1280x720", f16, None, Frames { lod: Some(lod), ..Frames::default() })
        }
        Err(e) => {
            eprintln!("octopaint: VR: {e}");
            ExitCode::from(1)
        }
    }
}

pub fn dump(doc: &Path, out: &Path) -> ExitCode {
    let s = match Session::open_read(doc) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    say_recovered(&s);
    // A document of layers dumps every layer (spec 14.5).
    let bytes = if s.version == 2 { s.doc.dump_bytes() } else { octopaint_tree::dump::dump_bytes(&s.painting().tree) };
    match octopaint_platform::durable::write(out, &bytes) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("octopaint: cannot write {}: {}", out.display(), octopaint_tree::trace::io_reason(&e));
            ExitCode::from(1)
        }
    }
}

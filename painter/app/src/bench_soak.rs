//! `octopaint bench soak`: hours of painting through the engine the window
//! paints with, watching memory (docs/benchmarks.md, "The soak"). A new
//! document of layers is opened as the window opens one (an
//! `OpenDocument` on the stroke thread, the staging thread, a render
//! thread uploading and casting at the window's pace, the engine's
//! records bounded as a live session's are), and a seeded script paints `--stamps`
//! samples into it: strokes of every shape and mode inside a cube of `--region`
//! metres (the painting fills it and goes on changing below the cell budget),
//! undos and redos, layer operations, a save every `--save-every`
//! simulated seconds (a sample is 1/90 s of the script's clock, a pause
//! between strokes 0.5 to 3 s), the undo budget reached and exceeded.
//! The jobs go in as fast as the stroke thread takes them.
//!
//! At `--points` stamp counts, between strokes with the engine idle, it
//! samples the process's resident memory, the pools' cells used and
//! allocated, the undo history's bytes, the journal's size, the trace's
//! bytes in memory and the engine's records. It checks that every save
//! leaves the journal at its header alone, and at the end that the saved
//! document, opened again, and the replay of the session's trace (with
//! the same undo bound) both equal the live document, dump for dump.
//! Writes `soak.json` into `--out` (painter/bench/plot_soak.py draws it);
//! the figure to read is the slope of resident memory over the last half.

use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Instant;

use anyhow::{Context, bail, ensure};
use octopaint_doc::{Session, journal_path};
use octopaint_pipeline::settings::LIVE_RECORDS;
use octopaint_pipeline::{Canvas, Engine, Hooks, Job, OpenDocument, Pipeline, Settings};
use octopaint_tree::fuzz_harness::SplitMix64;
use octopaint_tree::layers::Model;
use octopaint_tree::trace::{Brush, Camera, Canvas as CanvasSize, EventKind, LayerOp, LayerOpKind, Meta, Mirror, Mode, Sample, Shape, parse_trace};
use octopaint_tree::view::OrbitCamera;
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    /// Samples painted (each one stamp of the brush the stroke thread runs).
    #[arg(long, default_value_t = 1_000_000)]
    stamps: u64,
    /// The undo history's bound in MiB (the session's default is 1024).
    #[arg(long, default_value_t = 1024)]
    undo_mib: usize,
    /// A save every this many seconds of the script's clock.
    #[arg(long, default_value_t = 300.0)]
    save_every: f64,
    /// Memory samples over the run.
    #[arg(long, default_value_t = 200)]
    points: u64,
    /// The cell budget of the canvas (all layers).
    #[arg(long, default_value_t = 8_000_000)]
    capacity: u32,
    /// The edge of the cube painted, metres (at most 4).
    #[arg(long, default_value_t = 0.4)]
    region: f64,
    /// The script's seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Frames a second the render thread casts (the window's pace).
    #[arg(long, default_value_t = 60.0)]
    hz: f64,
    /// Where soak.json and the document go.
    #[arg(long, default_value = "out/soak")]
    out: PathBuf,
}

/// The canvas: one root 4.096 m wide at depth 10, cells of 4 mm; the
/// script paints a cube in its middle.
const ROOT_SIZE: f64 = 4.096;
const MAX_DEPTH: u32 = 10;
const MIDDLE: f64 = ROOT_SIZE / 2.0;
/// The script's clock: a sample every 1/90 s (a controller's rate).
const SAMPLE_SECONDS: f64 = 1.0 / 90.0;

/// The script's numbers: the same script for the same seed.
struct Rng(SplitMix64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0.next()
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    /// One of `choices` by weight.
    fn pick<T: Copy>(&mut self, choices: &[(T, f64)]) -> T {
        let total: f64 = choices.iter().map(|c| c.1).sum();
        let mut x = self.unit() * total;
        for &(c, w) in choices {
            if x < w {
                return c;
            }
            x -= w;
        }
        choices[choices.len() - 1].0
    }
}

fn brush(r: &mut Rng) -> Brush {
    let shape = r.pick(&[(Shape::Sphere, 0.5), (Shape::Cylinder, 0.12), (Shape::Box, 0.12), (Shape::Cone, 0.12), (Shape::Noise, 0.14)]);
    let mode = r.pick(&[(Mode::Paint, 0.55), (Mode::Erase, 0.15), (Mode::Recolor, 0.1), (Mode::Mix, 0.1), (Mode::Pickup, 0.1)]);
    let radius = r.range(0.01, 0.04);
    let color = [r.unit(), r.unit(), r.unit()];
    let mut b = Brush::new(shape, mode, radius, color, r.range(0.3, 1.0), r.range(0.2, 1.0));
    b.mix_ratio = r.unit();
    b.pickup_rate = r.unit();
    if r.unit() < 0.3 {
        b.aspect = [r.range(0.5, 2.0), r.range(0.5, 2.0), r.range(0.5, 2.0)];
    }
    b.noise.frequency = r.range(5.0, 50.0);
    b.noise.seed = r.next() as u32;
    // Now and then mirrored across the cube's middle (spec 8.11).
    if r.unit() < 0.05 {
        b.mirror = Some(Mirror { axes: [true, false, r.unit() < 0.5], centre: [MIDDLE; 3] });
    }
    b
}

/// A stroke's samples: a wandering path inside the cube, a step of a
/// third to two thirds of the radius.
fn stroke(r: &mut Rng, b: &Brush, half: f64) -> Vec<Sample> {
    let n = 20 + r.below(181);
    let mut p = [0.0; 3].map(|_| MIDDLE + r.range(-half, half));
    let mut d = [r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)];
    let q = {
        let v = [r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)];
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-9);
        v.map(|x| x / n)
    };
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push(Sample { p, pressure: r.range(0.5, 1.0), q });
        for k in 0..3 {
            d[k] += r.range(-0.3, 0.3);
        }
        let len = d.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-9);
        let step = b.radius * r.range(0.33, 0.67);
        for k in 0..3 {
            p[k] += d[k] / len * step;
            // Back into the cube, as a mirror would send it.
            if (p[k] - MIDDLE).abs() > half {
                d[k] = -d[k];
                p[k] = MIDDLE + (p[k] - MIDDLE).clamp(-half, half);
            }
        }
    }
    out
}

/// What `f` finds in the painting, asked of the stroke thread and waited
/// for.
fn asked<T: Send + 'static>(engine: &Engine, f: impl FnOnce(&dyn Canvas) -> T + Send + 'static) -> anyhow::Result<T> {
    let (tx, rx) = mpsc::channel();
    engine
        .ask(move |c| {
            let _ = tx.send(f(c));
        })
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    rx.recv().context("the stroke thread ended")
}

/// The layers as they are (undo and redo change them too): names, locks
/// and the selection.
fn model(c: &dyn Canvas) -> Model {
    let doc = c.document();
    Model { names: doc.layers().map(|l| l.name.clone()).collect(), locked: doc.layers().map(|l| l.locked).collect(), selected: doc.selected() }
}

/// A layer operation the document takes now, chosen at random.
fn layer_op(r: &mut Rng, m: &Model, serial: &mut u32) -> Option<LayerOp> {
    let n = m.names.len();
    let any = |r: &mut Rng| Some(m.names[r.below(n)].clone());
    let mut fresh = || {
        *serial += 1;
        Some(format!("Soak {serial}"))
    };
    let blank = LayerOp { op: LayerOpKind::Select, layer: None, name: None, to: None, visible: None, opacity: None, locked: None };
    let kind = r.pick(&[
        (LayerOpKind::Add, 0.25),
        (LayerOpKind::Duplicate, 0.1),
        (LayerOpKind::Select, 0.2),
        (LayerOpKind::Set, 0.15),
        (LayerOpKind::MergeDown, 0.1),
        (LayerOpKind::Delete, 0.1),
        (LayerOpKind::Move, 0.05),
        (LayerOpKind::Rename, 0.05),
    ]);
    let op = match kind {
        LayerOpKind::Add => LayerOp { op: kind, name: fresh(), ..blank },
        LayerOpKind::Duplicate => LayerOp { op: kind, layer: any(r), name: fresh(), ..blank },
        LayerOpKind::Rename => LayerOp { op: kind, layer: any(r), name: fresh(), ..blank },
        LayerOpKind::Select | LayerOpKind::Delete => LayerOp { op: kind, layer: any(r), ..blank },
        LayerOpKind::MergeDown if n > 1 => LayerOp { op: kind, layer: Some(m.names[1 + r.below(n - 1)].clone()), ..blank },
        LayerOpKind::MergeDown => return None,
        LayerOpKind::Move => LayerOp { op: kind, layer: any(r), to: Some(r.below(n)), ..blank },
        LayerOpKind::Set => {
            let opacity = Some((r.range(0.3, 1.0) as f32 * 256.0).round() / 256.0);
            LayerOp { op: kind, layer: any(r), visible: Some(r.unit() < 0.85), opacity, ..blank }
        }
    };
    m.check(&op).is_none().then_some(op)
}

/// One memory sample, between strokes with the engine idle.
#[derive(Serialize, Clone, Copy)]
struct Point {
    stamps: u64,
    /// The script's clock, and the wall clock since the start.
    sim_s: f64,
    wall_s: f64,
    rss_mib: f64,
    cells_used: u64,
    cells_allocated: u64,
    pool_mib: f64,
    undo_mib: f64,
    forgotten: usize,
    layers: usize,
    journal_kib: f64,
    trace_kib: f64,
    records: usize,
    /// The GPU's pages: cells they hold, MiB (16 + 12 bytes a cell).
    gpu_mib: f64,
    /// The C allocator (glibc; NaN elsewhere): MiB in live allocations,
    /// and free but kept in its heaps (resident until reused or trimmed).
    heap_in_use_mib: f64,
    heap_free_mib: f64,
}

/// What the stroke thread reports of the document for a point.
struct Held {
    cells_used: u64,
    cells_allocated: u64,
    pool_bytes: usize,
    undo_bytes: usize,
    forgotten: usize,
    layers: usize,
    trace_bytes: usize,
}

fn held(c: &dyn Canvas) -> Held {
    let doc = c.document();
    let arena: Vec<_> = doc.parts().0.map(|(_, l)| l.tree()).collect();
    Held {
        cells_used: doc.used(),
        cells_allocated: arena.iter().map(|t| t.pool_capacity() as u64).sum(),
        pool_bytes: arena.iter().map(|t| t.pool_bytes_allocated()).sum(),
        undo_bytes: doc.history_bytes(),
        forgotten: c.forgotten(),
        layers: doc.len(),
        trace_bytes: c.session().map_or(0, Session::trace_bytes),
    }
}

/// A save, as the journal was before and after it.
#[derive(Serialize)]
struct Save {
    stamps: u64,
    journal_before: u64,
    journal_after: u64,
    /// Event lines the journal held beyond the document after the save.
    lines_after: usize,
    document_bytes: u64,
    ms: f64,
}

#[derive(Serialize)]
struct Results {
    stamps: u64,
    strokes: u64,
    undos: u64,
    redos: u64,
    layer_ops: u64,
    undo_budget_mib: f64,
    capacity: u32,
    region: f64,
    seconds: f64,
    /// Resident memory's slope over the last half, MiB per 10^5 stamps,
    /// and as a share of the undo budget.
    rss_slope_mib: f64,
    rss_slope_percent_of_budget: f64,
    /// The trace's bytes in memory, a stamp, over the last half.
    trace_bytes_per_stamp: f64,
    /// The stamp count when the history first reached the undo budget.
    budget_reached_at: Option<u64>,
    saves: Vec<Save>,
    points: Vec<Point>,
    /// Lines the engine said (refusals, warnings) besides the saves, the
    /// first ones.
    said: Vec<String>,
    said_count: usize,
    /// Every save, the last included, left the journal at its header.
    journal_emptied: bool,
    saved_equals_live: bool,
    replay_equals_live: bool,
}

fn mib(b: impl Into<f64>) -> f64 {
    b.into() / 1048576.0
}

fn rss_mib() -> f64 {
    octopaint_platform::memory::rss_kib().map_or(f64::NAN, |k| k as f64 / 1024.0)
}

/// The least-squares slope of `y` over `x`.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    if sxx > 0.0 { sxy / sxx } else { 0.0 }
}

/// Wait until the engine has run every job, taking what it says.
fn settle(p: &Pipeline, said: &mut Vec<String>) {
    while !p.engine().idle() {
        said.extend(p.engine().take_messages());
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    said.extend(p.engine().take_messages());
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    ensure!(a.stamps >= 100, "--stamps must be at least 100");
    ensure!(a.points >= 4, "--points must be at least 4");
    ensure!(a.save_every > 0.0 && a.save_every.is_finite(), "--save-every must be a positive number of seconds");
    ensure!((1..=1 << 20).contains(&a.undo_mib), "--undo-mib must be 1 to 1048576");
    ensure!(a.hz > 0.0 && a.hz <= 1000.0, "--hz must be in (0, 1000]");
    ensure!(a.region > 0.0 && a.region <= 4.0, "--region must be in (0, 4] metres");
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let path = a.out.join("soak.octo");
    for p in [path.clone(), journal_path(&path)] {
        match std::fs::remove_file(&p) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e).with_context(|| format!("removing {}", p.display())),
            _ => {}
        }
    }
    let canvas = CanvasSize { roots: [1, 1, 1], max_depth: MAX_DEPTH, root_size: ROOT_SIZE, capacity: a.capacity };
    let mut session = Session::create_layered(&path, &canvas, &Meta::new()).map_err(|e| anyhow::anyhow!("{e}"))?;
    let undo_bytes = a.undo_mib << 20;
    session.undo_bytes = undo_bytes;

    let orbit = OrbitCamera { target: glam::DVec3::splat(MIDDLE), distance: 3.0, yaw: 0.6, pitch: -0.4, fov_y: 0.8, covered: 0.0 };
    let camera: Camera = orbit.camera([96, 54], octopaint_tree::view::BACKGROUND);
    let mut settings = Settings::new(camera);
    settings.keep_records = Some(LIVE_RECORDS);
    settings.target_hz = Some(a.hz);
    let p = Pipeline::start_on(Box::new(OpenDocument::new(session)), settings, Hooks::default()).map_err(|e| anyhow::anyhow!("{e}"))?;

    let mut r = Rng(SplitMix64(a.seed));
    let (mut stamps, mut strokes, mut undos, mut redos, mut layer_ops, mut serial) = (0u64, 0u64, 0u64, 0u64, 0u64, 0u32);
    let (mut sim, mut next_save, mut next_point) = (0.0, a.save_every, 0u64);
    let (mut points, mut saves, mut said) = (Vec::new(), Vec::new(), Vec::new());
    let mut budget_reached_at = None;
    let t0 = Instant::now();
    let submit = |job: Job| p.submit(job).map(drop).map_err(|e| anyhow::anyhow!("{e}"));
    let journal_len = || std::fs::metadata(journal_path(&path)).map(|m| m.len()).unwrap_or(0);
    loop {
        if stamps >= next_point || stamps >= a.stamps {
            settle(&p, &mut said);
            let h = asked(p.engine(), held)?;
            let heap = octopaint_platform::memory::heap();
            if budget_reached_at.is_none() && (h.forgotten > 0 || h.undo_bytes >= undo_bytes) {
                budget_reached_at = Some(stamps);
            }
            points.push(Point {
                stamps,
                sim_s: sim,
                wall_s: t0.elapsed().as_secs_f64(),
                rss_mib: rss_mib(),
                cells_used: h.cells_used,
                cells_allocated: h.cells_allocated,
                pool_mib: mib(h.pool_bytes as f64),
                undo_mib: mib(h.undo_bytes as f64),
                forgotten: h.forgotten,
                layers: h.layers,
                journal_kib: journal_len() as f64 / 1024.0,
                trace_kib: h.trace_bytes as f64 / 1024.0,
                records: p.engine().records_held(),
                gpu_mib: mib((p.engine().gpu_cells_held() * 32) as f64),
                heap_in_use_mib: heap.map_or(f64::NAN, |h| mib(h.in_use as f64)),
                heap_free_mib: heap.map_or(f64::NAN, |h| mib(h.free as f64)),
            });
            let last = points.last().expect("pushed");
            eprintln!(
                "{:>8} stamps  {:>7.0} s  rss {:>7.1} MiB  cells {:>8}  gpu {:>6.0} MiB  undo {:>7.1} MiB  journal {:>7.1} KiB  trace {:>7.1} KiB  records {}  heap {:.0} + {:.0} free MiB",
                last.stamps,
                last.wall_s,
                last.rss_mib,
                last.cells_used,
                last.gpu_mib,
                last.undo_mib,
                last.journal_kib,
                last.trace_kib,
                last.records,
                last.heap_in_use_mib,
                last.heap_free_mib
            );
            next_point += a.stamps.div_ceil(a.points);
            if stamps >= a.stamps {
                break;
            }
        }
        // A stroke.
        let b = brush(&mut r);
        let samples = stroke(&mut r, &b, a.region / 2.0);
        submit(Job::BeginStroke(b))?;
        for s in samples {
            submit(Job::Sample(s))?;
            stamps += 1;
            sim += SAMPLE_SECONDS;
        }
        submit(Job::EndStroke)?;
        strokes += 1;
        sim += r.range(0.5, 3.0);
        // Second thoughts.
        if r.unit() < 0.1 {
            let n = 1 + r.below(3);
            for _ in 0..n {
                submit(Job::Undo)?;
            }
            undos += n as u64;
            if r.unit() < 0.5 {
                submit(Job::Redo)?;
                redos += 1;
            }
        }
        if r.unit() < 0.025 {
            settle(&p, &mut said);
            let m = asked(p.engine(), model)?;
            if let Some(op) = layer_op(&mut r, &m, &mut serial) {
                submit(Job::Event(EventKind::Layer(op)))?;
                layer_ops += 1;
            }
        }
        if sim >= next_save {
            next_save += a.save_every;
            settle(&p, &mut said);
            let before = journal_len();
            let t = Instant::now();
            submit(Job::Save)?;
            settle(&p, &mut said);
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let lines_after = octopaint_doc::journal::lines_beyond(&path).map_err(|e| anyhow::anyhow!("{e}"))?.context("no journal after a save")?;
            saves.push(Save {
                stamps,
                journal_before: before,
                journal_after: journal_len(),
                lines_after,
                document_bytes: std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0),
                ms,
            });
        }
    }
    submit(Job::Save)?;
    settle(&p, &mut said);
    let seconds = t0.elapsed().as_secs_f64();
    let report = p.finish().map_err(|e| anyhow::anyhow!("{e}"))?;
    let failures: Vec<&String> = said.iter().filter(|m| m.contains("failed")).collect();
    ensure!(failures.is_empty(), "the session failed: {failures:?}");
    let said: Vec<String> = said.into_iter().filter(|m| !m.starts_with("saved ")).collect();

    // The checks: every save left the journal at its header; the saved
    // document and the replay of the session are the live document.
    let live = report.canvas.document().dump_bytes();
    let session = report.canvas.session().context("the soak's canvas is a document")?;
    let lines_at_end = octopaint_doc::journal::lines_beyond(&path).map_err(|e| anyhow::anyhow!("{e}"))?;
    let journal_emptied = lines_at_end == Some(0) && saves.iter().all(|s| s.lines_after == 0);
    let reopened = Session::open_read(&path).map_err(|e| anyhow::anyhow!("reopening {}: {e}", path.display()))?;
    let saved_equals_live = reopened.doc.dump_bytes() == live;
    drop(reopened);
    let text = session.trace_text().map_err(|e| anyhow::anyhow!("{e}"))?;
    let trace = parse_trace(&text).map_err(|e| anyhow::anyhow!("the session's trace does not read: {e}"))?;
    let (_, replayed) = octopaint_tree::replay::replay_document_within(&trace, None, &mut (), Some(undo_bytes)).context("replaying the session")?;
    let replay_equals_live = replayed.dump_bytes() == live;

    let half: Vec<Point> = points.iter().filter(|q| q.stamps >= a.stamps / 2).copied().collect();
    let per = 1e5;
    let rss_slope_mib = slope(&half.iter().map(|q| (q.stamps as f64 / per, q.rss_mib)).collect::<Vec<_>>());
    let trace_bytes_per_stamp = slope(&half.iter().map(|q| (q.stamps as f64, q.trace_kib * 1024.0)).collect::<Vec<_>>());
    let budget = mib(undo_bytes as f64);
    let results = Results {
        stamps,
        strokes,
        undos,
        redos,
        layer_ops,
        undo_budget_mib: budget,
        capacity: a.capacity,
        region: a.region,
        seconds,
        rss_slope_mib,
        rss_slope_percent_of_budget: 100.0 * rss_slope_mib / budget,
        trace_bytes_per_stamp,
        budget_reached_at,
        saves,
        points,
        said_count: said.len(),
        said: said.into_iter().take(20).collect(),
        journal_emptied,
        saved_equals_live,
        replay_equals_live,
    };
    let json = a.out.join("soak.json");
    std::fs::write(&json, serde_json::to_string_pretty(&results)?).with_context(|| format!("writing {}", json.display()))?;
    let first = results.points.first().expect("points");
    let last = results.points.last().expect("points");
    println!(
        "{} stamps ({} strokes, {} undos, {} redos, {} layer operations, {} saves) in {:.0} s: {:.0} stamps/s",
        results.stamps,
        results.strokes,
        results.undos,
        results.redos,
        results.layer_ops,
        results.saves.len(),
        seconds,
        results.stamps as f64 / seconds
    );
    println!(
        "resident memory {:.1} MiB at the start, {:.1} MiB at half, {:.1} MiB at the end; slope over the last half {:+.2} MiB per 10^5 stamps ({:+.2} % of the {:.0} MiB undo budget; goal under 1 %)",
        first.rss_mib,
        half.first().map_or(f64::NAN, |q| q.rss_mib),
        last.rss_mib,
        results.rss_slope_mib,
        results.rss_slope_percent_of_budget,
        budget
    );
    println!(
        "undo budget reached at {} stamps; history {:.1} MiB at the end, {} steps forgotten; cells {} used, {} allocated; GPU pages {:.0} MiB; C heap {:.1} MiB in use, {:.1} MiB free; trace in memory {:.1} KiB ({:.1} bytes a stamp over the last half); engine records {}",
        results.budget_reached_at.map_or("no".to_string(), |s| format!("{s}")),
        last.undo_mib,
        last.forgotten,
        last.cells_used,
        last.cells_allocated,
        last.gpu_mib,
        last.heap_in_use_mib,
        last.heap_free_mib,
        last.trace_kib,
        results.trace_bytes_per_stamp,
        last.records
    );
    println!(
        "every save left the journal at its header alone: {} ({} saves, largest journal before a save {:.1} KiB); saved document = live: {}; replay of the session = live: {}",
        if results.journal_emptied { "yes" } else { "NO" },
        results.saves.len(),
        results.saves.iter().map(|s| s.journal_before).max().unwrap_or(0) as f64 / 1024.0,
        if results.saved_equals_live { "yes" } else { "NO" },
        if results.replay_equals_live { "yes" } else { "NO" }
    );
    println!("wrote {}", json.display());
    if let Some(s) = results.saves.iter().find(|s| s.lines_after != 0) {
        bail!("the save at {} stamps left {} event lines in the journal ({} bytes)", s.stamps, s.lines_after, s.journal_after);
    }
    ensure!(results.journal_emptied, "the last save left {lines_at_end:?} event lines in the journal");
    ensure!(results.saved_equals_live, "the saved document differs from the live one");
    ensure!(results.replay_equals_live, "the replay of the session differs from the live document");
    Ok(())
}

//! `octopaint bench realtime TRACE`: the paper's section 5 experiments on
//! the real-time pipeline (docs/benchmarks.md). The trace's strokes before
//! `--stroke` are painted first (the pre-painted scene); then that stroke
//! (or its first `--samples` samples) is submitted at its recorded pace
//! to a fresh pipeline per configuration, camera fixed, and the run is
//! measured:
//!
//! - Table 1: per block size (the whole pool, 65K .. 2M cells), the time
//!   the staging thread holds the tree's lock per copy, and the copies and
//!   cells it could stage per second at that rate;
//! - Fig. 8: frame times over the run for mask sizes (none, 4×2, 64×32) and
//!   block sizes;
//! - Fig. 9: for the staging strategies, the share of frames whose image
//!   matches neither consistent state the GPU holds (the newest fully
//!   uploaded publication, nor the newest uploaded at all), and how long
//!   such corruption lasts; the consistent images are rendered afterwards
//!   by replaying the same jobs publication by publication, and images are
//!   compared by their 64-bit digests, computed on the GPU
//!   (`octopaint_gpu::digest`), so capturing a frame costs a small pass
//!   rather than a read-back of the image;
//! - latency per job (submission to the end of the first frame showing
//!   all of it), frame times, and cells per second through the pipeline.
//!
//! Writes `results.json` into `--out` (painter/bench/plot_realtime.py draws
//! the figures from it) and prints the tables.

use std::collections::{BTreeSet, HashMap};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use octopaint_gpu::{Backend, Precision, Renderer};
use octopaint_pipeline::jobs::from_trace;
use octopaint_pipeline::{BlockSize, Hooks, Job, MaskSize, Pipeline, Replay, Report, Settings, Strategy};
use octopaint_tree::layers::Document;
use octopaint_tree::paint::Painting;
use octopaint_tree::trace::{Camera, EventKind, read_trace};
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    trace: PathBuf,
    /// Index of the stroke replayed live (0 = the first); the strokes
    /// before it are the pre-painted scene.
    #[arg(long, default_value_t = 3)]
    stroke: usize,
    /// Replay only the first N samples of that stroke live (default: all
    /// of it).
    #[arg(long)]
    samples: Option<usize>,
    /// Image size (96x54 is what lavapipe draws in about 12 ms while the
    /// stroke thread paints beside it; on a GPU, the headset's size).
    #[arg(long, default_value = "96x54")]
    size: String,
    /// Pace frames at this rate (default: as fast as the renderer goes).
    #[arg(long)]
    hz: Option<f64>,
    /// Where results.json goes.
    #[arg(long, default_value = "out/realtime")]
    out: PathBuf,
    /// Only the default configuration and the strategies (a quick look).
    #[arg(long)]
    quick: bool,
    /// Only the default configuration (the stroke thread's paint time per
    /// sample is the figure wanted).
    #[arg(long, conflicts_with = "quick")]
    default_only: bool,
    /// Paint the live stroke with this brush radius in finest cells (the
    /// canvas's lattice unit) instead of the recorded one.
    #[arg(long)]
    radius_cells: Option<f64>,
}

#[derive(Serialize)]
pub(crate) struct Percentiles {
    pub(crate) mean: f64,
    pub(crate) p50: f64,
    pub(crate) p95: f64,
    pub(crate) p99: f64,
    pub(crate) max: f64,
}

/// Mean, median, 95th and 99th percentiles (nearest rank, `(n − 1)·q`
/// rounded) and maximum of `v`; zeros when it is empty.
pub(crate) fn percentiles(v: &[f64]) -> Percentiles {
    if v.is_empty() {
        return Percentiles { mean: 0.0, p50: 0.0, p95: 0.0, p99: 0.0, max: 0.0 };
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let at = |q: f64| s[((s.len() - 1) as f64 * q).round() as usize];
    Percentiles { mean: s.iter().sum::<f64>() / s.len() as f64, p50: at(0.5), p95: at(0.95), p99: at(0.99), max: s[s.len() - 1] }
}

#[derive(Serialize)]
struct Corruption {
    frames: usize,
    corrupted: usize,
    percent: f64,
    /// Spans of consecutive corrupted frames, first start to next clean
    /// frame's start, in milliseconds.
    longest_ms: f64,
    median_ms: f64,
    spans: usize,
}

#[derive(Serialize)]
struct RunResult {
    label: String,
    group: String,
    block_cells: Option<u32>,
    mask: String,
    blocks_per_frame: usize,
    skip_invalid: bool,
    aggressive_units: Option<usize>,
    grouped: bool,
    seconds: f64,
    jobs: usize,
    frames: usize,
    /// (start offset s, frame ms) per frame.
    frame_series: Vec<(f64, f64)>,
    frame_ms: Percentiles,
    upload_ms: Percentiles,
    g3_ms: Percentiles,
    cast_ms: Percentiles,
    latency_ms: Percentiles,
    /// The stroke thread's painting time per sample job (Painting::advance
    /// with the tree's lock held, lock waits excluded).
    paint_ms: Percentiles,
    staging_copies: usize,
    staging_cells_per_copy: f64,
    staging_ms: Percentiles,
    staging_wait_ms: Percentiles,
    staged_copies_per_s: f64,
    staged_cells_per_s: f64,
    cells_written_per_s: f64,
    cells_uploaded_per_s: f64,
    corruption: Option<Corruption>,
}

struct Config {
    label: String,
    group: &'static str,
    block: BlockSize,
    mask: MaskSize,
    k: usize,
    strategy: Strategy,
    capture: bool,
}

fn mask_name(m: MaskSize) -> String {
    match m {
        MaskSize::None => "none".into(),
        MaskSize::Grid(c, r) => format!("{c}x{r}"),
    }
}

fn configs(quick: bool, default_only: bool) -> Vec<Config> {
    let base = |label: &str, group: &'static str| Config {
        label: label.into(),
        group,
        block: BlockSize::Cells(65536),
        mask: MaskSize::Grid(64, 32),
        k: 4,
        // The paper's staging (one block group a copy) for Table 1 and
        // Fig. 8; the painter's default is the grouped strategy.
        strategy: Strategy { skip_invalid: true, aggressive_units: None, grouped: false },
        capture: false,
    };
    let mut out = vec![Config { strategy: Strategy::default(), ..base("default: 65K blocks, K=4, 64x32, grouped", "default") }];
    if default_only {
        return out;
    }
    if !quick {
        out.push(Config { block: BlockSize::WholePool, k: 1, ..base("no block (whole pool)", "table1") });
        for shift in 16..=21 {
            let cells = 1u32 << shift;
            out.push(Config { block: BlockSize::Cells(cells), k: 1, ..base(&format!("{}K blocks", cells / 1024), "table1") });
        }
        for mask in [MaskSize::None, MaskSize::Grid(4, 2), MaskSize::Grid(64, 32)] {
            out.push(Config { block: BlockSize::Cells(1 << 18), k: 1, mask, ..base(&format!("mask {}", mask_name(mask)), "fig8a") });
        }
    }
    let strategies = [
        ("block dependencies ignored", Strategy { skip_invalid: false, aggressive_units: None, grouped: false }),
        ("aggressive staging", Strategy { skip_invalid: false, aggressive_units: Some(16), grouped: false }),
        ("skipping invalid parent/child", Strategy { skip_invalid: true, aggressive_units: Some(16), grouped: false }),
        ("dependencies respected (grouped)", Strategy { skip_invalid: true, aggressive_units: None, grouped: true }),
    ];
    // The paper uploads one block a frame (K = 1); at lavapipe's frame
    // rate that falls behind the brush, so the strategies also run with
    // K = 4, where the pipeline keeps up.
    for k in [1, 4] {
        if quick && k == 1 {
            continue;
        }
        for (label, strategy) in strategies {
            out.push(Config { strategy, capture: true, k, ..base(&format!("{label}, K={k}"), if k == 1 { "fig9" } else { "fig9_k4" }) });
        }
    }
    out
}

/// The image digests of the consistent states the frames need, by publication
/// number after the opening: the live jobs replayed single-threaded,
/// published exactly as the stroke thread publishes, each wanted state
/// uploaded fully and cast. One tree (version 1) only.
fn consistent_images(
    pre: &Painting,
    live: &[(f64, Job)],
    aggressive: Option<usize>,
    wanted: &BTreeSet<u64>,
    camera: &Camera,
    skip_invalid: bool,
) -> anyhow::Result<HashMap<u64, u64>> {
    let mut painting = pre.clone();
    let mut r = Renderer::new(Backend::Auto)?;
    r.sync(&mut painting.tree)?;
    let mut out = HashMap::new();
    let mut params = octopaint_tree::raycast::RayParams::new(&painting.tree.lat, camera);
    params.skip_invalid = skip_invalid;
    let cast = |r: &mut Renderer, painting: &mut Painting, n: u64, out: &mut HashMap<u64, u64>| -> anyhow::Result<()> {
        if wanted.contains(&n) {
            r.sync(&mut painting.tree)?;
            out.insert(n, r.cast_digest(&params, Precision::F32)?);
        }
        Ok(())
    };
    let mut n = 0u64;
    cast(&mut r, &mut painting, 0, &mut out)?;
    let publish = |r: &mut Renderer, painting: &mut Painting, n: &mut u64, out: &mut HashMap<u64, u64>| -> anyhow::Result<()> {
        let p = painting.tree.take_publication();
        if p.blocks.is_empty() && p.mask.count() == 0 {
            return Ok(());
        }
        *n += 1;
        r.apply(&p);
        cast(r, painting, *n, out)
    };
    for (_, job) in live {
        match job {
            Job::Sample(s) => {
                painting.begin_sample(s, 0);
                loop {
                    let done = painting.advance(aggressive);
                    publish(&mut r, &mut painting, &mut n, &mut out)?;
                    if done {
                        break;
                    }
                }
            }
            other => {
                match other {
                    Job::BeginStroke(b) => painting.begin_stroke(b),
                    Job::EndStroke => painting.end_stroke(),
                    Job::Undo => {
                        painting.undo();
                    }
                    Job::Redo => {
                        painting.redo();
                    }
                    // A version 1 trace's live stroke has no other jobs.
                    _ => {}
                }
                publish(&mut r, &mut painting, &mut n, &mut out)?;
            }
        }
    }
    Ok(out)
}

fn corruption(report: &Report, images: &HashMap<u64, u64>) -> Corruption {
    let frames = &report.frames;
    let live = |p: u64| p.saturating_sub(report.opening_pubs);
    let bad: Vec<bool> = frames
        .iter()
        .map(|f| {
            let img = f.digest.expect("captured");
            let a = images.get(&live(f.cut)) == Some(&img);
            let b = images.get(&live(f.newest_uploaded)) == Some(&img);
            !(a || b)
        })
        .collect();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < frames.len() {
        if bad[i] {
            let s = i;
            while i < frames.len() && bad[i] {
                i += 1;
            }
            let end = if i < frames.len() { frames[i].start } else { frames[i - 1].end };
            spans.push((end - frames[s].start).as_secs_f64() * 1e3);
        } else {
            i += 1;
        }
    }
    let corrupted = bad.iter().filter(|&&b| b).count();
    let p = percentiles(&spans);
    Corruption {
        frames: frames.len(),
        corrupted,
        percent: 100.0 * corrupted as f64 / frames.len().max(1) as f64,
        longest_ms: p.max,
        median_ms: p.p50,
        spans: spans.len(),
    }
}

/// Cells written so far over every layer.
fn cells_written(doc: &Document) -> u64 {
    doc.layers().map(|l| l.painting.counters.cells_written).sum()
}

fn run_one(pre: &Replay, live: &[(f64, Job)], camera: &Camera, c: &Config, hz: Option<f64>) -> anyhow::Result<(RunResult, Report)> {
    let mut settings = Settings::new(*camera);
    settings.block = c.block;
    settings.mask = c.mask;
    settings.blocks_per_frame = c.k;
    settings.strategy = c.strategy;
    settings.capture = c.capture;
    settings.target_hz = hz;
    let written_before = cells_written(&pre.doc);
    let p = Pipeline::start_on(Box::new(pre.clone()), settings, Hooks::default())?;
    let t0 = Instant::now();
    let rec0 = live.first().map_or(0.0, |x| x.0);
    for (t, job) in live {
        let due = t0 + Duration::from_secs_f64((t - rec0).max(0.0));
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        p.submit(job.clone())?;
    }
    let report = p.finish()?;
    let seconds = t0.elapsed().as_secs_f64();
    let f = &report.frames;
    let ms = |g: fn(&octopaint_pipeline::FrameRecord) -> f64| percentiles(&f.iter().map(g).collect::<Vec<_>>());
    let staging_ms: Vec<f64> = report.staging.iter().map(|s| s.seconds * 1e3).collect();
    let stage = percentiles(&staging_ms);
    let cells_per_copy = report.staging.iter().map(|s| s.cells as f64).sum::<f64>() / report.staging.len().max(1) as f64;
    let latency: Vec<f64> = report.ledger.jobs.iter().filter_map(|j| j.latency_ms()).collect();
    let paint: Vec<f64> = report.ledger.jobs.iter().filter(|j| j.kind == "sample").map(|j| j.paint_seconds * 1e3).collect();
    let uploaded: u64 = f.iter().map(|fr| fr.cells_uploaded).sum();
    let result = RunResult {
        label: c.label.clone(),
        group: c.group.into(),
        block_cells: match c.block {
            BlockSize::Cells(n) => Some(n),
            BlockSize::WholePool => None,
        },
        mask: mask_name(c.mask),
        blocks_per_frame: c.k,
        skip_invalid: c.strategy.skip_invalid,
        aggressive_units: c.strategy.aggressive_units,
        grouped: c.strategy.grouped,
        seconds,
        jobs: report.ledger.jobs.len(),
        frames: f.len(),
        frame_series: f.iter().map(|fr| ((fr.start - t0).as_secs_f64(), fr.ms())).collect(),
        frame_ms: ms(|fr| fr.ms()),
        upload_ms: ms(|fr| fr.upload_seconds * 1e3),
        g3_ms: ms(|fr| fr.g3_seconds * 1e3),
        cast_ms: ms(|fr| fr.cast_seconds * 1e3),
        latency_ms: percentiles(&latency),
        paint_ms: percentiles(&paint),
        staging_copies: report.staging.len(),
        staging_cells_per_copy: cells_per_copy,
        staged_copies_per_s: if stage.mean > 0.0 { 1e3 / stage.mean } else { 0.0 },
        staged_cells_per_s: if stage.mean > 0.0 { cells_per_copy * 1e3 / stage.mean } else { 0.0 },
        staging_ms: stage,
        staging_wait_ms: percentiles(&report.staging.iter().map(|s| s.wait_seconds * 1e3).collect::<Vec<_>>()),
        cells_written_per_s: (cells_written(report.canvas.document()) - written_before) as f64 / seconds,
        cells_uploaded_per_s: uploaded as f64 / seconds,
        corruption: None,
    };
    Ok((result, report))
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (w, h) = a
        .size
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .filter(|&(w, h)| (1..=8192).contains(&w) && (1..=8192).contains(&h))
        .with_context(|| format!("--size {:?}: expected WxH, each 1 to 8192", a.size))?;
    if let Some(r) = a.radius_cells {
        anyhow::ensure!(r.is_finite() && r > 0.0 && r <= 1e6, "--radius-cells {r}: expected a radius in (0, 1e6] finest cells");
    }
    if let Some(hz) = a.hz {
        anyhow::ensure!(hz.is_finite() && hz > 0.0, "--hz {hz}: expected a positive rate");
    }
    let trace = read_trace(&a.trace).map_err(|e| anyhow::anyhow!("{}: {e}", a.trace.display()))?;
    let mut camera = *trace.events.iter().find_map(|e| if let EventKind::Camera(c) = &e.kind { Some(c) } else { None }).context("the trace has no camera")?;
    camera.size = [w, h];
    let jobs = from_trace(&trace);
    let begins: Vec<usize> = jobs.iter().enumerate().filter(|(_, (_, j))| matches!(j, Job::BeginStroke(_))).map(|(i, _)| i).collect();
    let start = *begins.get(a.stroke).with_context(|| format!("the trace has {} strokes", begins.len()))?;
    // A version 2 trace paints a document of layers (its layer operations
    // and imports are jobs too); a version 1 trace one tree.
    let mut pre = if trace.version == 2 { Replay::of(Document::new(&trace.canvas), 2) } else { Replay::new(Painting::new(&trace.canvas)) };
    let t_pre = Instant::now();
    for (_, job) in &jobs[..start] {
        pre.apply(job);
    }
    let mut live: Vec<(f64, Job)> = Vec::new();
    // The stroke's begin, its first `--samples` samples, and its end (at
    // the last kept sample's time when the stroke is cut short).
    for (t, job) in &jobs[start..] {
        if matches!(job, Job::EndStroke) {
            live.push((*t, Job::EndStroke));
            break;
        }
        if let (Job::BeginStroke(b), Some(r)) = (job, a.radius_cells) {
            let mut b = *b;
            b.radius = r * trace.canvas.root_size * (-f64::from(trace.canvas.max_depth)).exp2();
            live.push((*t, Job::BeginStroke(b)));
            continue;
        }
        if a.samples.is_some_and(|n| live.len() > n) {
            let t = live.last().map_or(*t, |x| x.0);
            live.push((t, Job::EndStroke));
            break;
        }
        live.push((*t, job.clone()));
    }
    if !matches!(live.last(), Some((_, Job::EndStroke))) {
        let t = live.last().map_or(0.0, |x| x.0);
        live.push((t, Job::EndStroke));
    }
    println!(
        "pre-painted {} strokes in {:.1} s: {} cells in {} layer(s); live: {} jobs over {:.2} s at the recorded pace; images {w}x{h}",
        a.stroke,
        t_pre.elapsed().as_secs_f64(),
        pre.doc.used(),
        pre.doc.len(),
        live.len(),
        live.last().unwrap().0 - live[0].0
    );
    let mut results = Vec::new();
    let mut adapter = String::new();
    for c in configs(a.quick, a.default_only) {
        if c.capture && trace.version == 2 {
            // The corruption analysis replays one tree publication by
            // publication; a document of layers runs the other figures.
            continue;
        }
        let (mut result, report) = run_one(&pre, &live, &camera, &c, a.hz)?;
        adapter.clone_from(&report.adapter);
        if c.capture {
            let live_pub = |p: u64| p.saturating_sub(report.opening_pubs);
            let wanted: BTreeSet<u64> = report.frames.iter().flat_map(|f| [live_pub(f.cut), live_pub(f.newest_uploaded)]).collect();
            let images = consistent_images(pre.painting(), &live, c.strategy.aggressive_units, &wanted, &camera, c.strategy.skip_invalid)?;
            result.corruption = Some(corruption(&report, &images));
        }
        println!(
            "{:<36} {:>5} frames, frame ms p50 {:>6.1} p99 {:>6.1}; latency ms p50 {:>6.1} p99 {:>6.1} max {:>6.1}; paint ms a sample p50 {:>6.2} p99 {:>6.2}; staging {:>5} copies, {:>6.2} ms each{}",
            result.label,
            result.frames,
            result.frame_ms.p50,
            result.frame_ms.p99,
            result.latency_ms.p50,
            result.latency_ms.p99,
            result.latency_ms.max,
            result.paint_ms.p50,
            result.paint_ms.p99,
            result.staging_copies,
            result.staging_ms.mean,
            result.corruption.as_ref().map_or(String::new(), |c| format!("; corrupted {:.1}% of frames, longest {:.0} ms", c.percent, c.longest_ms))
        );
        results.push(result);
    }
    std::fs::create_dir_all(&a.out)?;
    let doc = serde_json::json!({
        "trace": a.trace.display().to_string(),
        "adapter": adapter,
        "image": [w, h],
        "prepainted_cells": pre.doc.used(),
        "layers": pre.doc.len(),
        "live_jobs": live.len(),
        "runs": results,
    });
    let path = a.out.join("results.json");
    octopaint_platform::durable::write(&path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    println!("{}", path.display());
    Ok(())
}

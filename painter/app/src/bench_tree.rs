//! `octopaint bench tree`: stamping and refinement throughput of the CPU
//! octree on a deterministic stroke set, and its memory per cell.
//!
//! The stroke set: `--strokes` strokes (default 200) of `--samples` sphere
//! samples (default 50), each a smooth random walk with samples half a
//! radius apart, brush radius `--radius` finest cells, on one root of
//! `2^11` finest cells per axis (one canvas unit per finest cell).
//! Pseudo-random values come from hashing an index (lowbias32), and
//! `--write-strokes` writes the set as text so that the OpenVDB peer
//! (painter/bench/openvdb_stamp.cpp) paints exactly the same samples; the
//! script painter/bench/tree_vs_openvdb.sh runs both and prints the ratios.
//!
//! Figures (one JSON object on stdout):
//! - cell updates/s while stamping: leaves a paint pass finds with
//!   coverage > 0 (each compared with its stroke maximum, rewritten when it
//!   rises) per second of paint pass; OpenVDB's voxel writes are counted
//!   the same way;
//! - cells created/s: cells made by refinement per second of refinement
//!   levels (rounds plus painting the new children);
//! - overall: (updates + created) per second of the whole replay;
//! - bytes per cell: the pools (16), what the vectors allocate, and the
//!   undo history.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::Context;
use octopaint_tree::noise::hash32;
use octopaint_tree::paint::Painting;
use octopaint_tree::pool::{FREE, Tree};
use octopaint_tree::trace::{Brush, Canvas, Mirror, Mode, Sample, Shape};

#[derive(clap::Args)]
pub struct Args {
    /// Brush radius in finest cells.
    #[arg(long, default_value_t = 10.0)]
    radius: f64,
    #[arg(long, default_value_t = 200)]
    strokes: u32,
    #[arg(long, default_value_t = 50)]
    samples: u32,
    /// Brush hardness: the share of the radius painted at full coverage.
    #[arg(long, default_value_t = 0.5)]
    hardness: f64,
    /// Refine settled leaves too (spec 8.7), as before the rule: shows
    /// what it saves on the same strokes.
    #[arg(long)]
    no_settling: bool,
    /// Value a unit's children one at a time instead of in vector lanes
    /// (paint/src/lanes/): the same tree, for timing the kernels.
    #[arg(long)]
    no_lanes: bool,
    /// Write the stroke set here (text: `stroke R hardness opacity r g b`,
    /// then one `x y z` line per sample).
    #[arg(long)]
    write_strokes: Option<std::path::PathBuf>,
    /// Threads of the core's parallel passes (default: every core). The
    /// result is the same tree for any count; `tree_digest` shows it.
    #[arg(long)]
    threads: Option<usize>,
    /// The smallest batch the parallel passes split across threads
    /// (default: the core's, `par::DEFAULT_GRAIN`): smaller hands off more
    /// often. Any value gives the same tree.
    #[arg(long)]
    grain: Option<usize>,
    /// Split the capsule paint pass's walk whenever the grain says it is
    /// worth it, instead of choosing by its measured cost (the default).
    /// The same tree either way.
    #[arg(long)]
    always_split: bool,
    /// The brush's shape: spheres paint a capsule a sample; the other shapes
    /// stamp every `--spacing` radii of the path (by default half a radius,
    /// as far apart as the samples: about one stamp a sample, the walk of
    /// one stamp), turned to identity. Spacing matters to spheres not at all. The OpenVDB
    /// peer paints spheres only, so only `sphere` writes `--write-strokes`.
    #[arg(long, value_enum, default_value_t = BenchShape::Sphere)]
    shape: BenchShape,
    /// Stamps' spacing along the path, in radii: below 0.5 a sample's
    /// segment holds several stamps (the walk of several).
    #[arg(long, default_value_t = 0.5)]
    spacing: f64,
    /// Mirror every stroke through the canvas's middle plane across x
    /// (spec 8.11): each segment holds the stroke's primitives and their
    /// copies'.
    #[arg(long)]
    mirror: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchShape {
    Sphere,
    Box,
    Cylinder,
    Cone,
    Noise,
}

impl BenchShape {
    fn shape(self) -> Shape {
        match self {
            BenchShape::Sphere => Shape::Sphere,
            BenchShape::Box => Shape::Box,
            BenchShape::Cylinder => Shape::Cylinder,
            BenchShape::Cone => Shape::Cone,
            BenchShape::Noise => Shape::Noise,
        }
    }
}

/// Max depth of the benchmark canvas: one root of 2^11 finest cells a side.
const DEPTH: u32 = 11;
const SIDE: f64 = (1u32 << DEPTH) as f64;

fn unit(stream: u32, i: u32) -> f64 {
    f64::from(hash32(hash32(stream) ^ i.wrapping_mul(0x9E37_79B9))) / 4294967296.0
}

struct StrokeSet {
    brushes: Vec<Brush>,
    samples: Vec<Vec<[f64; 3]>>,
}

fn stroke_set(a: &Args) -> StrokeSet {
    let r = a.radius;
    let mut brushes = Vec::new();
    let mut samples = Vec::new();
    for s in 0..a.strokes {
        let colour = [unit(1, s), unit(2, s), unit(3, s)];
        let mut brush = Brush::new(a.shape.shape(), Mode::Paint, r, colour, 0.8, a.hardness);
        brush.spacing = a.spacing;
        if a.mirror {
            brush.mirror = Some(Mirror { axes: [true, false, false], centre: [SIDE / 2.0; 3] });
        }
        brushes.push(brush);
        // A smooth random walk: the heading turns a little at every sample.
        let margin = 4.0 * r + 64.0;
        let mut p = [0, 1, 2].map(|k| margin + unit(10 + k, s) * (SIDE - 2.0 * margin));
        let mut dir = [0, 1, 2].map(|k| unit(20 + k, s) - 0.5);
        let mut pts = Vec::new();
        for i in 0..a.samples {
            pts.push(p);
            let j = s * 1000 + i;
            for (k, d) in dir.iter_mut().enumerate() {
                *d += 0.6 * (unit(30 + k as u32, j) - 0.5);
            }
            let n = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt().max(1e-9);
            for k in 0..3 {
                // Half a radius per sample; turn back from the canvas edges.
                let step = 0.5 * r * dir[k] / n;
                let next = p[k] + step;
                if next < margin || next > SIDE - margin {
                    dir[k] = -dir[k];
                    p[k] -= step;
                } else {
                    p[k] = next;
                }
            }
        }
        samples.push(pts);
    }
    StrokeSet { brushes, samples }
}

fn write_strokes(set: &StrokeSet, path: &std::path::Path) -> anyhow::Result<()> {
    let mut text = String::new();
    for (b, pts) in set.brushes.iter().zip(&set.samples) {
        let _ = writeln!(text, "stroke {} {} {} {} {} {}", b.radius, b.hardness, b.opacity, b.color[0], b.color[1], b.color[2]);
        for p in pts {
            let _ = writeln!(text, "{} {} {}", p[0], p[1], p[2]);
        }
    }
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

fn count_cells(t: &Tree) -> (u64, u64) {
    let live = t.depth().iter().filter(|&&d| d != FREE).count() as u64;
    let leaves = (0..t.n_used()).filter(|&c| t.is_live(c) && t.is_leaf(c)).count() as u64;
    (live, leaves)
}

/// FNV-1a over the pools in use and the undo steps: equal digests, equal
/// trees and histories (for comparing thread counts; not a checksum for
/// files).
fn digest(p: &Painting) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
        }
    };
    let t = &p.tree;
    let n = t.n_used() as usize;
    for c in 0..n {
        let r = t.record(c as u32);
        eat(&r.parent.to_le_bytes());
        eat(&r.first_child.to_le_bytes());
        eat(&[r.depth]);
        eat(&r.rgb);
        eat(&r.sigma.to_bits().to_le_bytes());
    }
    for step in p.history.full_steps(&p.tree) {
        for (c, b, a) in step.entries() {
            eat(&c.to_le_bytes());
            for r in [b, a] {
                eat(&r.parent.to_le_bytes());
                eat(&r.first_child.to_le_bytes());
                eat(&[r.depth]);
                eat(&r.rgb);
                eat(&r.sigma.to_bits().to_le_bytes());
            }
        }
    }
    h
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(a.radius.is_finite() && a.radius >= 0.5 && a.radius <= 256.0, "--radius must be in [0.5, 256] finest cells");
    anyhow::ensure!((0.0..=1.0).contains(&a.hardness), "--hardness must be in [0, 1]");
    anyhow::ensure!(a.spacing.is_finite() && (0.05..=4.0).contains(&a.spacing), "--spacing must be in [0.05, 4] radii");
    anyhow::ensure!(
        a.write_strokes.is_none() || (a.shape == BenchShape::Sphere && !a.mirror),
        "--write-strokes writes unmirrored sphere strokes only (what the OpenVDB peer paints)"
    );
    let set = stroke_set(a);
    if let Some(p) = &a.write_strokes {
        write_strokes(&set, p)?;
    }
    let canvas = Canvas { roots: [1, 1, 1], max_depth: DEPTH, root_size: SIDE, capacity: 0xFFFF_FFF8 };
    let mut painting = Painting::new(&canvas);
    painting.set_settling(!a.no_settling);
    octopaint_tree::lanes::set_enabled(!a.no_lanes);
    anyhow::ensure!(a.threads.is_none_or(|n| (1..=1024).contains(&n)), "--threads must be in [1, 1024]");
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads.unwrap_or(0)).build().context("cannot start the thread pool")?;
    let threads = pool.current_num_threads();
    anyhow::ensure!(a.grain.is_none_or(|g| g >= 1), "--grain must be at least 1");
    octopaint_tree::par::set_grain(a.grain.unwrap_or(octopaint_tree::par::DEFAULT_GRAIN));
    octopaint_tree::par::set_measured_split(!a.always_split);
    let t0 = Instant::now();
    pool.install(|| {
        for (b, pts) in set.brushes.iter().zip(&set.samples) {
            painting.begin_stroke(b);
            for p in pts {
                painting.add_sample(&Sample::at(*p), 0);
            }
            painting.end_stroke();
        }
    });
    let seconds = t0.elapsed().as_secs_f64();
    let c = painting.counters;
    let t = &painting.tree;
    let (live, leaves) = count_cells(t);
    let n = f64::from(t.n_used());
    let history = painting.history.bytes() as f64;
    let per_s = |count: u64, ns: u64| if ns == 0 { 0.0 } else { count as f64 / (ns as f64 * 1e-9) };
    let json = format!(
        concat!(
            "{{\"impl\": \"octopaint\", \"shape\": \"{}\", \"mirror\": {}, \"radius_cells\": {}, \"strokes\": {}, \"samples\": {}, \"seconds\": {:.4}, ",
            "\"cell_updates\": {}, \"cell_updates_per_s\": {:.0}, \"leaves_in_reach\": {}, \"paint_pass_seconds\": {:.4}, ",
            "\"hardness\": {}, \"settling\": {}, \"lanes\": {}, \"leaves_settled\": {}, \"cells_created\": {}, \"cells_created_per_s\": {:.0}, \"refine_seconds\": {:.4}, \"stroke_end_seconds\": {:.4}, ",
            "\"prefilter_seconds\": {:.4}, \"prefilter_cells\": {}, ",
            "\"overall_per_s\": {:.0}, \"cells_written\": {}, \"cells_used\": {}, \"cells_live\": {}, \"leaves\": {}, ",
            "\"deepest\": {}, \"bytes_per_cell_pools\": {}, \"bytes_per_cell_allocated\": {:.2}, \"history_bytes_per_cell\": {:.2}, \"history_bytes_per_changed_cell\": {:.2}, \"slot_map_mib\": {:.2}, ",
            "\"peak_rss_mib\": {:.1}, \"threads\": {}, \"grain\": {}, \"measured_split\": {}, \"tree_digest\": \"{:016x}\"}}"
        ),
        format!("{:?}", a.shape.shape()).to_lowercase(),
        a.mirror,
        a.radius,
        a.strokes,
        a.samples,
        seconds,
        c.leaves_hit,
        per_s(c.leaves_hit, c.paint_pass_ns),
        c.leaves_visited,
        c.paint_pass_ns as f64 * 1e-9,
        a.hardness,
        !a.no_settling,
        octopaint_tree::lanes::available(),
        c.leaves_settled,
        c.cells_created,
        per_s(c.cells_created, c.refine_ns),
        c.refine_ns as f64 * 1e-9,
        c.stroke_end_ns as f64 * 1e-9,
        c.prefilter_ns as f64 * 1e-9,
        c.prefilter_cells,
        (c.leaves_hit + c.cells_created) as f64 / seconds,
        c.cells_written,
        t.n_used(),
        live,
        leaves,
        t.depth().iter().filter(|&&d| d != FREE).max().copied().unwrap_or(0),
        Tree::BYTES_PER_CELL,
        t.pool_bytes_allocated() as f64 / n,
        history / n,
        history / painting.history.changed_cells().max(1) as f64,
        painting.slot_map_bytes() as f64 / (1024.0 * 1024.0),
        octopaint_platform::memory::peak_rss_kib().unwrap_or(0) as f64 / 1024.0,
        threads,
        octopaint_tree::par::grain(),
        octopaint_tree::par::measured_split(),
        digest(&painting),
    );
    println!("{json}");
    Ok(())
}

//! `octopaint bench gpu TRACE`: the GPU pipeline's figures on a painted
//! trace (docs/benchmarks.md): upload MB/s per block size, the g3 pass over
//! every region and over one brush sample's regions, and ray casting at
//! 1280×720 from each of the trace's cameras (f32 unlit, lit and lit with
//! shadow rays, and f16 unlit where the adapter has it). Wall-clock times around submit-and-wait, median of
//! several runs, after one warm-up.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use octopaint_gpu::pools::stage_range;
use octopaint_gpu::{Backend, Precision, Renderer};
use octopaint_tree::replay::replay;
use octopaint_tree::raycast::RayParams;
use octopaint_tree::trace::{EventKind, Light, Sample, read_trace};

#[derive(clap::Args)]
pub struct Args {
    /// A trace to paint first (its cameras are the ones cast).
    trace: PathBuf,
    /// Image size for ray casting.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Runs per figure (the median is printed).
    #[arg(long, default_value_t = 5)]
    runs: usize,
}

/// The median of some timings (benchmarks print it).
pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let trace = read_trace(&a.trace).map_err(|e| anyhow::anyhow!("{}: {e}", a.trace.display()))?;
    let cameras: Vec<_> = trace.events.iter().filter_map(|e| if let EventKind::Camera(c) = &e.kind { Some(*c) } else { None }).collect();
    anyhow::ensure!(!cameras.is_empty(), "{}: the trace has no camera", a.trace.display());
    let (_, mut painting) = replay(&trace, None, &mut ()).context("replaying the trace")?;
    let mut r = Renderer::new(Backend::Auto)?;
    println!("adapter: {}", r.gpu.describe());
    let n = u64::from(painting.tree.n_used());
    println!("tree: {n} cells, {:.1} MB in the GPU layout (16 B/cell, plus 12 B/cell of g3)", n as f64 * 16.0 / 1e6);
    let t = Instant::now();
    let first = r.sync(&mut painting.tree)?;
    println!(
        "first sync: {} blocks staged in {:.1} ms, uploads and the g3 pass over {} regions in {:.1} ms, {:.1} ms in all",
        first.blocks,
        first.stage_seconds * 1e3,
        first.regions,
        first.gpu_seconds * 1e3,
        t.elapsed().as_secs_f64() * 1e3
    );

    println!();
    println!("| block (cells) | blocks | stage (ms) | upload (ms) | MB/s staged and uploaded |");
    println!("| ---: | ---: | ---: | ---: | ---: |");
    for shift in 16..=21 {
        let block = 1usize << shift;
        let count = n.div_ceil(block as u64);
        let mut stage_s = Vec::new();
        let mut upload_s = Vec::new();
        for _ in 0..a.runs.max(1) + 1 {
            let mut st = 0.0;
            let mut up = 0.0;
            for b in 0..count {
                let t0 = Instant::now();
                let staged = stage_range(&painting.tree, b * block as u64, block);
                let t1 = Instant::now();
                r.pools.upload(&r.gpu, &staged);
                r.gpu.queue.submit([]);
                r.gpu.wait();
                st += (t1 - t0).as_secs_f64();
                up += t1.elapsed().as_secs_f64();
            }
            stage_s.push(st);
            upload_s.push(up);
        }
        stage_s.remove(0);
        upload_s.remove(0);
        let (st, up) = (median(stage_s), median(upload_s));
        let mb = (count * block as u64 * 16) as f64 / 1e6;
        println!("| {block} | {count} | {:.1} | {:.1} | {:.0} |", st * 1e3, up * 1e3, mb / (st + up));
    }

    // g3 over every region, then over what one brush sample dirties.
    let mut all = Vec::new();
    for _ in 0..a.runs.max(1) {
        painting.tree.mark_everything_dirty();
        let s = r.sync(&mut painting.tree)?;
        all.push((s.gpu_seconds, s.regions));
    }
    let regions_all = all[0].1;
    let g3_all = median(all.into_iter().map(|x| x.0).collect());
    let brush = trace.events.iter().rev().find_map(|e| if let EventKind::Brush(b) = &e.kind { Some(*b) } else { None }).context("no brush")?;
    let target = trace.events.iter().rev().find_map(|e| if let EventKind::Sample(s) = &e.kind { Some(*s) } else { None }).context("no sample")?;
    let mut sample_frames = Vec::new();
    painting.begin_stroke(&brush);
    for i in 0..a.runs.max(1) {
        let p = [target.p[0] + brush.radius * 0.3 * i as f64, target.p[1], target.p[2]];
        painting.add_sample(&Sample { p, ..target }, 0);
        let s = r.sync(&mut painting.tree)?;
        sample_frames.push((s.gpu_seconds, s.blocks, s.regions));
    }
    painting.end_stroke();
    println!();
    println!("g3 pass, every region ({regions_all}): {:.2} ms (uploads of nothing included)", g3_all * 1e3);
    let med = median(sample_frames.iter().map(|x| x.0).collect());
    println!(
        "one brush sample's frame: {} blocks, {} regions; uploads and g3 pass {:.2} ms (median)",
        sample_frames[sample_frames.len() / 2].1,
        sample_frames[sample_frames.len() / 2].2,
        med * 1e3
    );

    println!();
    // Unlit, lit, and lit with a shadow ray per pixel (spec 6.1), in f32;
    // unlit in f16 too.
    let sun = Light { dir: [0.45, 1.0, 0.35], ..Light::default() };
    let shadowed = Light { shadows: true, ..sun };
    println!("| camera | precision | light | ms per frame | rays/s |");
    println!("| --- | --- | --- | ---: | ---: |");
    for (i, cam) in cameras.iter().enumerate() {
        let mut cam = *cam;
        // Keep the field of view's aspect: widen or narrow the horizontal angles.
        cam.size = [a.width, a.height];
        let [l, rr, u, d] = cam.fov;
        let half_v = (u.tan() - d.tan()) / 2.0;
        let centre_h = (l.tan() + rr.tan()) / 2.0;
        let half_h = half_v * f64::from(a.width) / f64::from(a.height);
        cam.fov = [(centre_h - half_h).atan(), (centre_h + half_h).atan(), u, d];
        let runs: [(Precision, &str, Option<&Light>); 4] =
            [(Precision::F32, "unlit", None), (Precision::F32, "lit", Some(&sun)), (Precision::F32, "lit, shadows", Some(&shadowed)), (Precision::F16, "unlit", None)];
        for (precision, what, light) in runs {
            if !r.gpu.supports(precision) {
                continue;
            }
            let params = RayParams::new(&painting.tree.lat, &cam).with_light(light);
            let mut times = Vec::new();
            for _ in 0..a.runs.max(1) + 1 {
                let t0 = Instant::now();
                r.cast_params(&params, precision)?;
                times.push(t0.elapsed().as_secs_f64());
            }
            times.remove(0);
            let ms = median(times);
            let rays = f64::from(a.width) * f64::from(a.height);
            println!("| {i} | {precision:?} | {what} | {:.1} | {:.2} M |", ms * 1e3, rays / ms / 1e6);
        }
    }
    Ok(())
}

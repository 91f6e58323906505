//! `octopaint bench gpu TRACE`: the GPU pipeline's figures on a painted
//! trace (docs/benchmarks.md): upload MB/s per block size against the
//! device's own copy bandwidth, the g3 pass over every region and over one
//! brush sample's regions, GPU memory per cell, and ray casting from each
//! camera: mono at `--width`×`--height` (f32 unlit, lit and lit with shadow
//! rays, f16 unlit where the adapter has it) and stereo frames at headset
//! sizes (`--headsets`). `--grow` paints generated strokes after the trace
//! until the canvas holds that many cells. Wall-clock times around
//! submit-and-wait (no read-back in the timed casts), median of several
//! runs after one warm-up; `--json` writes every figure with the adapter's
//! name, driver and backend.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use octopaint_gpu::context::warm_median;
use octopaint_gpu::pools::stage_range;
use octopaint_gpu::{Backend, Precision, Renderer};
use octopaint_tree::paint::Painting;
use octopaint_tree::raycast::RayParams;
use octopaint_tree::replay::replay;
use octopaint_tree::trace::{Brush, Camera, EventKind, Light, MAX_CAPACITY, Mode, Sample, Shape, Trace, read_trace};
use serde_json::{Value, json};

#[derive(clap::Args)]
pub struct Args {
    /// A trace to paint first (its cameras are the ones cast).
    trace: PathBuf,
    /// Image size for the mono casts.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Runs per figure (the median is printed).
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// Headsets to time stereo frames for, NAME=WxH per eye (e.g.
    /// vive=1440x1600,quest3=2064x2208): each frame casts both eyes, 63 mm
    /// apart with a 100° vertical field of view, in f32 and f16, unlit.
    #[arg(long, value_delimiter = ',')]
    headsets: Vec<String>,
    /// Also give these strokes of the trace (0 = the first) a camera of
    /// their own, looking down the z axis at the whole stroke.
    #[arg(long, value_delimiter = ',')]
    frame_strokes: Vec<usize>,
    /// Only these of the trace's own cameras (0 = the first); default all.
    #[arg(long, value_delimiter = ',')]
    trace_cameras: Option<Vec<usize>>,
    /// Grow the canvas to at least this many cells before measuring:
    /// generated strokes (depth-21 spheres, a colour each) painted after the
    /// trace, the canvas's capacity raised to fit; a camera framing them is
    /// added.
    #[arg(long)]
    grow: Option<u64>,
    /// Skip the table per block size and the lit mono casts.
    #[arg(long)]
    short: bool,
    /// Write every figure as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write each camera's mono f32 image (PNG) into this folder.
    #[arg(long)]
    images: Option<PathBuf>,
    /// Levels of detail every cast is timed at (docs/spec.md 7; 0: every
    /// ray to the leaves), e.g. 0,1 for the cut against the full walk.
    #[arg(long, value_delimiter = ',', default_value = "0", value_parser = crate::lod_arg)]
    lod: Vec<f64>,
}

/// The median of some timings (benchmarks print it).
pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// The cells a ray stepped through, over the probe records of a cast:
/// (mean, 99th percentile).
fn step_figures(records: &[octopaint_gpu::raycast::ProbeRecord]) -> (f64, u32) {
    let steps: Vec<f64> = records.iter().map(|r| f64::from(r.steps)).collect();
    let p = crate::bench_realtime::percentiles(&steps);
    (p.mean, p.p99 as u32)
}

/// `v` rotated by the unit quaternion `q` (x, y, z, w).
fn rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let u = [q[0], q[1], q[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let t = cross(u, v).map(|x| 2.0 * x);
    let ut = cross(u, t);
    [v[0] + q[3] * t[0] + ut[0], v[1] + q[3] * t[1] + ut[1], v[2] + q[3] * t[2] + ut[2]]
}

/// `cam` at `w`×`h` with the same vertical field of view, the horizontal
/// one widened or narrowed to keep pixels square.
fn resized(cam: &Camera, w: u32, h: u32) -> Camera {
    let mut cam = *cam;
    cam.size = [w, h];
    let [l, rr, u, d] = cam.fov;
    let half_v = (u.tan() - d.tan()) / 2.0;
    let centre_h = (l.tan() + rr.tan()) / 2.0;
    let half_h = half_v * f64::from(w) / f64::from(h);
    cam.fov = [(centre_h - half_h).atan(), (centre_h + half_h).atan(), u, d];
    cam
}

/// The two eyes of a headset at `cam`'s pose: `w`×`h` each, a 100°
/// vertical field of view, 63 mm apart along the camera's right axis.
fn stereo(cam: &Camera, w: u32, h: u32) -> [Camera; 2] {
    let half_v = 50f64.to_radians().tan();
    let half_h = half_v * f64::from(w) / f64::from(h);
    let right = rotate(cam.q, [1.0, 0.0, 0.0]);
    [-1.0, 1.0].map(|side| {
        let mut e = *cam;
        e.size = [w, h];
        e.fov = [-half_h.atan(), half_h.atan(), half_v.atan(), -half_v.atan()];
        for k in 0..3 {
            e.eye[k] += side * 0.0315 * right[k];
        }
        e
    })
}

/// A camera looking down the z axis at `points` (each a ball of `radius`),
/// far enough for the trace's vertical field of view to hold them all.
fn framing(points: &[[f64; 3]], radius: f64, like: &Camera) -> Camera {
    let n = points.len().max(1) as f64;
    let mut c = [0.0; 3];
    for p in points {
        for k in 0..3 {
            c[k] += p[k] / n;
        }
    }
    let extent = points.iter().map(|p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt()).fold(0.0, f64::max) + radius;
    let half = like.fov[2].tan().min((-like.fov[3]).tan()).max(0.05);
    Camera { eye: [c[0], c[1], c[2] + 1.2 * extent / half + radius], q: [0.0, 0.0, 0.0, 1.0], ..*like }
}

/// Each stroke's sample positions and brush radius, in trace order.
fn strokes(trace: &Trace) -> Vec<(Vec<[f64; 3]>, f64)> {
    let mut out = Vec::new();
    let mut radius = 0.0;
    let mut open: Option<Vec<[f64; 3]>> = None;
    for e in &trace.events {
        match &e.kind {
            EventKind::Brush(b) => radius = b.radius,
            EventKind::StrokeBegin => open = Some(Vec::new()),
            EventKind::Sample(s) => {
                if let Some(v) = open.as_mut() {
                    v.push(s.p);
                }
            }
            EventKind::StrokeEnd => {
                if let Some(v) = open.take() {
                    out.push((v, radius));
                }
            }
            _ => {}
        }
    }
    out
}

/// A colour per generated stroke (a hash of its index), so that strokes
/// that overlap blend into cells no cleaning merges.
fn stroke_colour(k: u64) -> [f64; 3] {
    let mut x = k.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
    [0, 1, 2].map(|_| {
        x ^= x >> 31;
        x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x ^= x >> 29;
        0.1 + 0.85 * ((x >> 11) as f64 / (1u64 << 53) as f64)
    })
}

/// Paint generated strokes after the trace until the tree holds `target`
/// cells: rows of 4 m lines of depth-21 spheres (radius 52 mm, the scene's
/// fine brush) 70 mm apart, a colour each, in a slab beside the scene.
/// Returns (strokes, samples, the samples' positions for a camera).
fn grow(painting: &mut Painting, target: u64, like: &Brush) -> (u64, u64, Vec<[f64; 3]>) {
    let radius = 0.052;
    let step = radius * 0.5;
    let origin = [20_010.0, 20_010.0, 20_000.0];
    let per_stroke = (4.0 / step) as usize;
    let (mut k, mut samples, mut corners) = (0u64, 0u64, Vec::new());
    let mut last = u64::from(painting.tree.n_used());
    while u64::from(painting.tree.n_used()) < target {
        let brush = Brush {
            shape: Shape::Sphere,
            mode: Mode::Paint,
            radius,
            color: stroke_colour(k),
            opacity: 0.85,
            hardness: 0.55,
            spacing: 0.5,
            mirror: None,
            ..*like
        };
        let y = origin[1] + (k % 48) as f64 * 0.07;
        let z = origin[2] + (k / 48) as f64 * 0.07;
        painting.begin_stroke(&brush);
        for i in 0..per_stroke {
            let p = [origin[0] + i as f64 * step, y, z];
            painting.add_sample(&Sample::at(p), 0);
            if i == 0 || i + 1 == per_stroke {
                corners.push(p);
            }
        }
        painting.end_stroke();
        samples += per_stroke as u64;
        k += 1;
        let now = u64::from(painting.tree.n_used());
        if now == last {
            break; // the cell budget is spent: nothing more is refined
        }
        last = now;
    }
    (k, samples, corners)
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let mut trace = read_trace(&a.trace).map_err(|e| anyhow::anyhow!("{}: {e}", a.trace.display()))?;
    let mut headsets = Vec::new();
    for h in &a.headsets {
        let (name, size) = h.split_once('=').with_context(|| format!("--headsets: {h:?} is not NAME=WxH"))?;
        let (w, hh) = size.split_once('x').with_context(|| format!("--headsets: {size:?} is not WxH"))?;
        let (w, hh): (u32, u32) = (w.parse().context("--headsets: width")?, hh.parse().context("--headsets: height")?);
        anyhow::ensure!(w > 0 && hh > 0 && w <= 16384 && hh <= 16384, "--headsets: {w}x{hh} is not a size between 1 and 16384");
        headsets.push((name.to_string(), w, hh));
    }
    anyhow::ensure!(a.width > 0 && a.height > 0 && a.width <= 16384 && a.height <= 16384, "--width and --height: between 1 and 16384");
    let trace_cams: Vec<Camera> = trace.events.iter().filter_map(|e| if let EventKind::Camera(c) = &e.kind { Some(*c) } else { None }).collect();
    anyhow::ensure!(!trace_cams.is_empty(), "{}: the trace has no camera", a.trace.display());
    let like = trace_cams[0];
    let mut cameras: Vec<(String, Camera)> = Vec::new();
    for (i, c) in trace_cams.iter().enumerate() {
        if a.trace_cameras.as_ref().is_none_or(|v| v.contains(&i)) {
            cameras.push((format!("trace camera {i}"), *c));
        }
    }
    let all_strokes = strokes(&trace);
    for &k in &a.frame_strokes {
        let (points, radius) = all_strokes.get(k).with_context(|| format!("--frame-strokes: the trace has {} strokes, not {}", all_strokes.len(), k + 1))?;
        cameras.push((format!("stroke {k} (radius {radius} m)"), framing(points, *radius, &like)));
    }
    if let Some(n) = a.grow {
        let want = (n + n / 2).div_ceil(8) * 8;
        anyhow::ensure!(want <= MAX_CAPACITY as u64, "--grow {n}: more cells than a canvas may hold");
        trace.canvas.capacity = trace.canvas.capacity.max(want as u32);
    }
    let mut report = serde_json::Map::new();
    let t = Instant::now();
    let (_, mut painting) = replay(&trace, None, &mut ()).context("replaying the trace")?;
    println!("trace painted in {:.1} s: {} cells", t.elapsed().as_secs_f64(), painting.tree.n_used());
    report.insert("trace".into(), json!(a.trace.display().to_string()));
    report.insert("trace_seconds".into(), json!(t.elapsed().as_secs_f64()));
    if let Some(n) = a.grow {
        let like_brush =
            trace.events.iter().find_map(|e| if let EventKind::Brush(b) = &e.kind { Some(*b) } else { None }).context("--grow: the trace has no brush")?;
        let t = Instant::now();
        let (k, samples, corners) = grow(&mut painting, n, &like_brush);
        let secs = t.elapsed().as_secs_f64();
        let cells = painting.tree.n_used();
        println!("grown to {cells} cells in {secs:.1} s: {k} strokes, {samples} samples ({:.2} M cells/s)", f64::from(cells) / secs / 1e6);
        anyhow::ensure!(u64::from(cells) >= n, "--grow {n}: the canvas stopped at {cells} cells (capacity {})", painting.tree.capacity);
        report.insert("grow".into(), json!({"target": n, "cells": cells, "strokes": k, "samples": samples, "seconds": secs}));
        cameras.push(("grown canvas".into(), framing(&corners, 0.052, &like)));
    }
    let mut r = Renderer::new(Backend::Auto)?;
    let info = r.gpu.info.clone();
    println!("adapter: {}", r.gpu.describe());
    report.insert(
        "adapter".into(),
        json!({"name": info.name, "backend": format!("{:?}", info.backend), "device_type": format!("{:?}", info.device_type),
               "driver": info.driver, "driver_info": info.driver_info, "f16": r.gpu.f16,
               "max_storage_binding": r.gpu.limits.max_storage_buffer_binding_size, "max_buffer": r.gpu.limits.max_buffer_size}),
    );
    let n = u64::from(painting.tree.n_used());
    println!("tree: {n} cells, {:.1} MB in the GPU layout (16 B/cell, plus a 16 B/cell row of g3 and shading vector)", n as f64 * 16.0 / 1e6);
    let t = Instant::now();
    let first = r.sync(&mut painting.tree)?;
    let first_ms = t.elapsed().as_secs_f64() * 1e3;
    println!(
        "first sync: {} blocks staged in {:.1} ms, uploads and the g3 pass over {} regions in {:.1} ms, {first_ms:.1} ms in all",
        first.blocks,
        first.stage_seconds * 1e3,
        first.regions,
        first.gpu_seconds * 1e3,
    );
    let allocated = r.pools.allocated_bytes();
    println!(
        "GPU memory: {:.1} MB of pages for {n} cells ({:.1} B a cell; 32 B a cell of layout, the rest is the last page's free cells)",
        allocated as f64 / 1e6,
        allocated as f64 / n as f64
    );
    report.insert("tree".into(), json!({"cells": n, "capacity": painting.tree.capacity, "layout_bytes": n * 32, "allocated_bytes": allocated, "bytes_per_cell": allocated as f64 / n as f64}));
    report.insert(
        "first_sync".into(),
        json!({"blocks": first.blocks, "stage_ms": first.stage_seconds * 1e3, "gpu_ms": first.gpu_seconds * 1e3, "regions": first.regions, "total_ms": first_ms}),
    );

    // The device's own bandwidth, for the uploads to be judged against: a
    // buffer-to-buffer copy on the GPU, and write_buffer from the host.
    let bw = r.gpu.bandwidth((256u64 << 20).min(r.gpu.limits.max_buffer_size / 2), a.runs);
    let bytes = bw.bytes;
    let (copy_s, write_s, empty_s) = (bw.copy_seconds, bw.write_seconds, bw.empty_seconds);
    println!(
        "bandwidth: copy on the GPU {:.1} GB/s ({} MiB read and written), write_buffer from the host {:.1} GB/s; an empty submit-and-wait {:.3} ms",
        2.0 * bytes as f64 / copy_s / 1e9,
        bytes >> 20,
        bytes as f64 / write_s / 1e9,
        empty_s * 1e3
    );
    report.insert(
        "bandwidth".into(),
        json!({"bytes": bytes, "gpu_copy_gbs_read_plus_write": 2.0 * bytes as f64 / copy_s / 1e9, "host_write_gbs": bytes as f64 / write_s / 1e9, "empty_submit_ms": empty_s * 1e3}),
    );

    if !a.short {
        // The biggest block staged below runs past the used cells: the
        // pages must hold it (the last page grows with the tree).
        r.pools.ensure(&r.gpu, n.div_ceil(1 << 21) << 21)?;
        println!();
        println!("| block (cells) | blocks | stage (ms) | upload (ms) | MB/s staged and uploaded |");
        println!("| ---: | ---: | ---: | ---: | ---: |");
        let mut rows = Vec::new();
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
            rows.push(
                json!({"block": block, "blocks": count, "stage_ms": st * 1e3, "upload_ms": up * 1e3, "mb_per_s": mb / (st + up), "upload_mb_per_s": mb / up}),
            );
        }
        report.insert("blocks".into(), Value::Array(rows));
    }

    // g3 over every region, then over what one brush sample dirties.
    let mut all = Vec::new();
    for _ in 0..a.runs.max(1) {
        painting.tree.mark_everything_dirty();
        let s = r.sync(&mut painting.tree)?;
        all.push((s.gpu_seconds, s.regions, s.stage_seconds));
    }
    let regions_all = all[0].1;
    let g3_all = median(all.iter().map(|x| x.0).collect());
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
    let blocks_all = n.div_ceil(65_536);
    println!();
    println!(
        "g3 pass, every region ({regions_all}): {:.2} ms with the uploads of {blocks_all} blocks ({:.3} ms a 65,536-cell block)",
        g3_all * 1e3,
        g3_all * 1e3 / blocks_all as f64
    );
    let med = median(sample_frames.iter().map(|x| x.0).collect());
    let mid = sample_frames[sample_frames.len() / 2];
    println!("one brush sample's frame: {} blocks, {} regions; uploads and g3 pass {:.2} ms (median)", mid.1, mid.2, med * 1e3);
    report.insert(
        "g3".into(),
        json!({"all_regions": regions_all, "all_ms": g3_all * 1e3, "blocks": blocks_all, "per_block_ms": g3_all * 1e3 / blocks_all as f64,
               "sample_frame_ms": med * 1e3, "sample_blocks": mid.1, "sample_regions": mid.2,
               "sample_per_region_ms": med * 1e3 / f64::from(mid.2.max(1))}),
    );

    println!();
    let sun = Light { dir: [0.45, 1.0, 0.35], ..Light::default() };
    let shadowed = Light { shadows: true, ..sun };
    let mut casts = Vec::new();
    println!("| camera | size | precision | light | level of detail | ms per frame | rays/s | cells per ray, mean | p99 |");
    println!("| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: |");
    if let Some(dir) = &a.images {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    for (ci, (name, cam)) in cameras.iter().enumerate() {
        let mono = resized(cam, a.width, a.height);
        if let Some(dir) = &a.images {
            let img = r.cast(&painting.tree, &mono, Precision::F32)?;
            let path = dir.join(format!("camera{ci}.png"));
            octopaint_gpu::image::write_png(&path, &img, a.width, a.height).with_context(|| format!("writing {}", path.display()))?;
        }
        let mut runs: Vec<(String, [u32; 2], Vec<Camera>, Precision, &str, Option<&Light>)> = Vec::new();
        runs.push(("mono".into(), [a.width, a.height], vec![mono], Precision::F32, "unlit", None));
        if !a.short {
            runs.push(("mono".into(), [a.width, a.height], vec![mono], Precision::F32, "lit", Some(&sun)));
            runs.push(("mono".into(), [a.width, a.height], vec![mono], Precision::F32, "lit, shadows", Some(&shadowed)));
        }
        runs.push(("mono".into(), [a.width, a.height], vec![mono], Precision::F16, "unlit", None));
        for (hn, w, h) in &headsets {
            for p in [Precision::F32, Precision::F16] {
                runs.push((format!("{hn} stereo"), [*w, *h], stereo(cam, *w, *h).to_vec(), p, "unlit", None));
            }
        }
        for (what, [w, h], eyes, precision, light_name, light) in runs {
            if !r.gpu.supports(precision) {
                continue;
            }
            for &k in &a.lod {
                let params: Vec<RayParams> = eyes.iter().map(|e| RayParams::new(&painting.tree.lat, e).with_light(light).with_lod(e, k)).collect();
                let s = warm_median(a.runs, || r.cast_and_wait(&params, precision))?;
                let rays = f64::from(w) * f64::from(h) * eyes.len() as f64;
                let size = if eyes.len() == 2 { format!("2×{w}×{h}") } else { format!("{w}×{h}") };
                // Cells per ray from the probe records of a mono cast (a
                // stereo frame's records would not fit one binding here).
                let steps = if eyes.len() == 1 { Some(step_figures(&r.ray.probe(&r.gpu, &r.pools, &params[0], precision)?)) } else { None };
                let (mean, p99) = steps.map_or((String::new(), String::new()), |(m, p)| (format!("{m:.1}"), format!("{p}")));
                println!("| {name} | {what} {size} | {precision:?} | {light_name} | {k} | {:.2} | {:.1} M | {mean} | {p99} |", s * 1e3, rays / s / 1e6);
                casts.push(json!({"camera": name, "camera_index": ci, "view": what, "width": w, "height": h, "eyes": eyes.len(),
                                  "precision": format!("{precision:?}"), "light": light_name, "lod": k, "ms": s * 1e3, "rays_per_s": rays / s,
                                  "steps_mean": steps.map(|x| x.0), "steps_p99": steps.map(|x| x.1)}));
            }
        }
    }
    report.insert("cameras".into(), Value::Array(cameras.iter().map(|(n, c)| json!({"name": n, "eye": c.eye, "q": c.q})).collect()));
    report.insert("casts".into(), Value::Array(casts));
    report.insert("runs".into(), json!(a.runs));
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&Value::Object(report))? + "\n";
        octopaint_platform::durable::write(path, text.as_bytes()).with_context(|| format!("writing {}", path.display()))?;
        println!("\nwrote {}", path.display());
    }
    Ok(())
}

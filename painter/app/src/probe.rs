//! `octopaint probe`: every pixel's ray of one camera traced through a
//! dump's tree by the GPU ray caster, one record per ray (where it stopped
//! and why, where it started, the direction the shader computed), written
//! as an `.npz` for the precision study (docs/precision.md, "The GPU's
//! f16"), which compares it with the reference and mpmath ray by ray.

use std::io::Cursor;
use std::path::PathBuf;
use std::process::ExitCode;

use octopaint_gpu::{Precision, Renderer};
use octopaint_tree::dump::{NpyArray, Values, read_dump, write_npz};
use octopaint_tree::raycast::RayParams;

#[derive(clap::Args)]
pub struct Args {
    /// The tree: a dump (.npz, docs/spec.md 11.1), as `replay` writes at
    /// snapshots or `octopaint-ref` writes for any tree.
    dump: PathBuf,
    /// The camera as a trace's camera event holds it (spec 12): a JSON
    /// object with eye, q, fov, size and optionally background.
    #[arg(long)]
    camera: String,
    /// Precision of the ray caster's positions (f16 needs SHADER_F16).
    #[arg(long, value_enum, default_value_t = crate::PrecisionChoice::F16)]
    precision: crate::PrecisionChoice,
    /// The graphics API.
    #[arg(long, value_enum, default_value_t = crate::BackendChoice::Auto)]
    backend: crate::BackendChoice,
    /// The .npz to write (arrays listed in docs/precision.md).
    #[arg(long)]
    out: PathBuf,
}

fn fail(msg: String, code: u8) -> ExitCode {
    eprintln!("octopaint: {msg}");
    ExitCode::from(code)
}

pub fn run(a: &Args) -> ExitCode {
    let bytes = match std::fs::read(&a.dump) {
        Ok(b) => b,
        Err(e) => return fail(format!("cannot read {}: {}", a.dump.display(), octopaint_tree::trace::io_reason(&e)), 2),
    };
    let mut tree = match read_dump(&bytes) {
        Ok(t) => t,
        Err(e) => return fail(format!("{}: {e}", a.dump.display()), 2),
    };
    let camera = match crate::camera_arg(&a.camera) {
        Ok(c) => c,
        Err(e) => return fail(e, 2),
    };
    let precision = Precision::from(a.precision);
    let mut renderer = match Renderer::new(a.backend.into()) {
        Ok(r) => r,
        Err(e) => return fail(e.to_string(), 1),
    };
    if !renderer.gpu.supports(precision) {
        return fail(format!("{} has no SHADER_F16 for --precision f16", renderer.gpu.describe()), 1);
    }
    let t0 = std::time::Instant::now();
    let records = match renderer.probe(&mut tree, &camera, precision) {
        Ok(r) => r,
        Err(e) => return fail(e.to_string(), 1),
    };
    let seconds = t0.elapsed().as_secs_f64();
    let params = RayParams::new(&tree.lat, &camera);
    let n = records.len();
    let col = |f: &dyn Fn(&octopaint_gpu::raycast::ProbeRecord) -> u32| records.iter().map(f).collect::<Vec<u32>>();
    let col3 = |f: &dyn Fn(&octopaint_gpu::raycast::ProbeRecord) -> [u32; 3]| records.iter().flat_map(f).collect::<Vec<u32>>();
    let col3f = |f: &dyn Fn(&octopaint_gpu::raycast::ProbeRecord) -> [f32; 3]| records.iter().flat_map(f).collect::<Vec<f32>>();
    let (status, steps, cell, depth) = (col(&|r| r.status), col(&|r| r.steps), col(&|r| r.cell), col(&|r| r.depth));
    let (origin, start_origin, start_depth) = (col3(&|r| r.origin), col3(&|r| r.start_origin), col(&|r| r.start_depth));
    let (exit, dir, start) = (col3f(&|r| r.exit), col3f(&|r| r.dir), col3f(&|r| r.start));
    let eye_cell = params.eye_cell;
    let eye_rel = params.eye_rel;
    let inside = [u32::from(params.inside)];
    let adapter = renderer.gpu.describe();
    let adapter_bytes = adapter.as_bytes();
    let arrays = [
        NpyArray { name: "status", shape: vec![n], values: Values::U32(&status) },
        NpyArray { name: "steps", shape: vec![n], values: Values::U32(&steps) },
        NpyArray { name: "cell", shape: vec![n], values: Values::U32(&cell) },
        NpyArray { name: "depth", shape: vec![n], values: Values::U32(&depth) },
        NpyArray { name: "origin", shape: vec![n, 3], values: Values::U32(&origin) },
        NpyArray { name: "exit", shape: vec![n, 3], values: Values::F32(&exit) },
        NpyArray { name: "dir", shape: vec![n, 3], values: Values::F32(&dir) },
        NpyArray { name: "start_depth", shape: vec![n], values: Values::U32(&start_depth) },
        NpyArray { name: "start_origin", shape: vec![n, 3], values: Values::U32(&start_origin) },
        NpyArray { name: "start", shape: vec![n, 3], values: Values::F32(&start) },
        NpyArray { name: "eye_cell", shape: vec![3], values: Values::U32(&eye_cell) },
        NpyArray { name: "eye_rel", shape: vec![3], values: Values::F32(&eye_rel) },
        NpyArray { name: "inside", shape: vec![], values: Values::U32(&inside) },
        NpyArray { name: "adapter", shape: vec![adapter_bytes.len()], values: Values::U8(adapter_bytes) },
    ];
    let out = match write_npz(Cursor::new(Vec::new()), &arrays) {
        Ok(c) => c.into_inner(),
        Err(e) => return fail(format!("cannot encode the records: {e}"), 1),
    };
    if let Err(e) = octopaint_platform::durable::write(&a.out, &out) {
        return fail(format!("cannot write {}: {}", a.out.display(), octopaint_tree::trace::io_reason(&e)), 1);
    }
    eprintln!("octopaint: {n} rays probed in {:.1} ms on {adapter}, {precision:?}; wrote {}", seconds * 1e3, a.out.display());
    ExitCode::SUCCESS
}

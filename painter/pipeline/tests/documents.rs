//! Documents of layers through the engine, deterministically (no timing
//! assertions): every job of a version 2 trace (strokes, layer operations,
//! imports, undo and redo of both) run by the stroke thread, each layer's
//! dirty blocks uploaded into its own range of the pages and its g3
//! recomputed there; at the end every listed layer's cells and g3 on the
//! GPU equal its tree's, the image equals a fresh whole upload's, and the
//! document equals the replay's. A layer's visibility or opacity changes
//! the layer table only: no cell is uploaded for it. Needs a GPU adapter
//! (lavapipe in CI): without one the tests fail.

use std::path::Path;
use std::time::{Duration, Instant};

use octopaint_gpu::pools::stage_range;
use octopaint_gpu::raycast::LayerTableGpu;
use octopaint_gpu::{Precision, Renderer};
use octopaint_pipeline::jobs::from_trace;
use octopaint_pipeline::{Canvas, Hooks, Job, Pipeline, Replay, Report, Settings, Strategy};
use octopaint_tree::g3::g3_table;
use octopaint_tree::layers::Document;
use octopaint_tree::paint::Painting;
use octopaint_tree::raycast::RayParams;
use octopaint_tree::replay::replay_document;
use octopaint_tree::trace::{Camera, EventKind, LayerOpKind, Trace, read_trace};

fn trace(name: &str) -> Trace {
    read_trace(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"))).unwrap()
}

fn camera(t: &Trace) -> Camera {
    let mut c = t.events.iter().find_map(|e| if let EventKind::Camera(c) = &e.kind { Some(*c) } else { None }).expect("the trace has a camera");
    c.size = [64, 48];
    c
}

fn canvas_of(t: &Trace) -> Box<dyn Canvas> {
    if t.version == 2 { Box::new(Replay::of(Document::new(&t.canvas), 2)) } else { Box::new(Replay::new(Painting::new(&t.canvas))) }
}

/// Wait for `done`, failing (not skipping) after a minute: a deadlock.
fn eventually(what: &str, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !done() {
        assert!(Instant::now() < deadline, "{what}: still not done after a minute (a stall)");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Run every job of `name`; with `paced`, each job is waited for until a
/// frame shows it before the next is submitted. Checks the result against
/// the replay and a fresh upload, and returns the report.
fn run_and_check(name: &str, settings: Settings, paced: bool) -> Report {
    let t = trace(name);
    let p = Pipeline::start_on(canvas_of(&t), settings.clone(), Hooks::default()).unwrap();
    let jobs = from_trace(&t);
    for (_, job) in &jobs {
        let seq = p.submit(job.clone()).unwrap().seq;
        if paced {
            eventually("the job shown", || p.jobs_shown() as u64 >= seq);
        }
    }
    let mut report = p.finish().unwrap();
    assert!(report.ledger.jobs.iter().all(|j| j.shown.is_some()), "{name}: a job never shown");
    let (_, replayed) = replay_document(&t, None, &mut ()).unwrap();
    let doc = report.canvas.document();
    assert!(doc.dump_bytes() == replayed.dump_bytes(), "{name}: the engine's document differs from the replay's");
    // Every listed layer at its own range, cells and g3 as its tree's.
    let end = report.ranges.iter().map(|&(_, b, n)| b + n).max().unwrap();
    let r = &mut report.renderer;
    let gpu_cells = r.pools.read_cells(&r.gpu, end).unwrap();
    let gpu_g3 = r.pools.read_g3(&r.gpu, end).unwrap();
    let mut bases = Vec::new();
    let mut opacity = Vec::new();
    for (&id, layer) in doc.listed_ids().iter().zip(doc.layers()) {
        let &(_, base, cells) = report.ranges.iter().find(|r| r.0 == id).unwrap_or_else(|| panic!("{name}: layer {id} has no range"));
        let tree = layer.tree();
        let n = tree.n_used() as usize;
        assert!(n as u64 <= cells, "{name}: layer {id} outgrew its range");
        let b = base as usize;
        assert!(gpu_cells[b..b + n] == stage_range(tree, 0, n).cells[..], "{name}: layer {id}'s cells on the GPU differ from its pools");
        assert!(gpu_g3[b..b + n] == g3_table(tree)[..], "{name}: layer {id}'s g3 on the GPU differs");
        if layer.contributes() {
            bases.push(base as u32);
            opacity.push(layer.opacity);
        }
    }
    // The frames' last image equals a fresh whole upload of the layers.
    let params = RayParams::new(&doc.layer(0).tree().lat, &settings.camera);
    let image = if t.version == 2 {
        let table = LayerTableGpu::new(&bases, &opacity);
        let mut enc = r.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("test cast") });
        r.ray.encode_layers(&r.gpu, &r.pools, &mut enc, &params, Precision::F32, &table).unwrap();
        r.gpu.queue.submit([enc.finish()]);
        r.ray.read_image(&r.gpu, params.width, params.height).unwrap()
    } else {
        r.cast_params(&params, Precision::F32).unwrap()
    };
    let shown: Vec<(&octopaint_tree::Tree, f32)> = replayed.layers().filter(|l| l.contributes()).map(|l| (l.tree(), l.opacity)).collect();
    let fresh = Renderer::new(octopaint_gpu::Backend::Auto).unwrap().render_layers(&shown, &params, Precision::F32).unwrap();
    if t.version == 2 {
        assert!(image == fresh, "{name}: the frames' image differs from a whole upload's");
    }
    report
}

#[test]
fn a_document_of_layers_reaches_the_gpu_layer_by_layer() {
    for name in ["layers", "imports", "layers_budget"] {
        let t = trace(name);
        let mut s = Settings::new(camera(&t));
        s.blocks_per_frame = 2;
        eprintln!("{name}: grouped");
        run_and_check(name, s.clone(), false);
        eprintln!("{name}: block by block, newest first");
        s.strategy = Strategy { skip_invalid: true, aggressive_units: None, grouped: false };
        run_and_check(name, s, false);
    }
}

#[test]
fn a_layer_setting_uploads_no_cell() {
    let t = trace("layers");
    let report = run_and_check("layers", Settings::new(camera(&t)), true);
    // Paced: each job's changes are uploaded in frames of its own. A
    // `set` (visibility, opacity, lock) changes the table alone.
    let jobs = from_trace(&t);
    let mut sets = 0;
    for (k, (_, job)) in jobs.iter().enumerate() {
        let Job::Event(EventKind::Layer(op)) = job else { continue };
        if op.op != LayerOpKind::Set {
            continue;
        }
        sets += 1;
        let this = report.ledger.jobs[k].shown_frame.unwrap();
        let prev = if k > 0 { report.ledger.jobs[k - 1].shown_frame.unwrap() } else { 0 };
        let uploaded: u64 = report.frames.iter().filter(|f| f.index > prev && f.index <= this).map(|f| f.cells_uploaded).sum();
        assert_eq!(uploaded, 0, "a layer setting uploaded {uploaded} cells");
    }
    assert!(sets > 0, "the trace sets a layer's visibility or opacity");
}

#[test]
fn a_version_one_painting_runs_as_one_layer_at_cell_0() {
    // Mirror painting (spec 8.11) through the engine, one tree: its range
    // is the pages' first cells, drawn without a layer table.
    let t = trace("mirror");
    let report = run_and_check("mirror", Settings::new(camera(&t)), false);
    assert_eq!(report.ranges.len(), 1);
    assert_eq!(report.ranges[0].1, 0);
}

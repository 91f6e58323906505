//! The thread protocol, deterministically (no timing assertions; a hang is
//! caught by a generous deadline, never a speed): no job lost or run twice,
//! every dirty block reaches the GPU, shutting down with work in flight
//! loses nothing, the final state equals `octopaint replay`'s whatever the
//! strategy, and a stalled renderer does not stall painting nor a stalled
//! painter rendering. Needs a GPU adapter (lavapipe in CI): without one the
//! tests fail.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use octopaint_gpu::pools::stage_range;
use octopaint_pipeline::jobs::from_trace;
use octopaint_pipeline::{BlockSize, Gate, Hooks, Job, MaskSize, Pipeline, Report, Settings, Strategy, SubmitError};
use octopaint_tree::dump::dump_bytes;
use octopaint_tree::g3::g3_table;
use octopaint_tree::paint::Painting;
use octopaint_tree::replay::replay;
use octopaint_tree::trace::{Camera, EventKind, Trace, read_trace};

fn trace(name: &str) -> Trace {
    read_trace(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"))).unwrap()
}

fn camera(t: &Trace) -> Camera {
    let mut c = t.events.iter().find_map(|e| if let EventKind::Camera(c) = &e.kind { Some(*c) } else { None }).unwrap_or(Camera {
        eye: [0.5, 0.5, 2.0],
        q: [0.0, 0.0, 0.0, 1.0],
        fov: [-0.5, 0.5, 0.4, -0.4],
        size: [64, 48],
        background: [0.0; 3],
    });
    c.size = [64, 48];
    c
}

/// Wait for `done`, failing (not skipping) after a minute: a deadlock.
fn eventually(what: &str, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !done() {
        assert!(Instant::now() < deadline, "{what}: still not done after a minute (a stall)");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Run every job of `name` through a pipeline and check the result against
/// a single-threaded replay: the same dump bytes, every job once, every
/// block on the GPU, GPU g3 and image equal to a fresh render.
fn run_and_check(name: &str, tweak: impl FnOnce(&mut Settings)) -> Report {
    run_and_check_paced(name, tweak, false)
}

/// [`run_and_check`], and with `paced` each job that ends something (a
/// stroke, an undo, a redo) is waited for until a frame shows it before the
/// next job is submitted, as an artist's pauses would: every such job's
/// uploads then happen in frames of their own, however fast the threads
/// run on a loaded machine.
fn run_and_check_paced(name: &str, tweak: impl FnOnce(&mut Settings), paced: bool) -> Report {
    let t = trace(name);
    let mut settings = Settings::new(camera(&t));
    settings.blocks_per_frame = 2;
    // The paper's staging, block by block, newest first (the default,
    // grouped, is one of the variants below): copies land out of order.
    settings.strategy = Strategy { skip_invalid: true, aggressive_units: None, grouped: false };
    tweak(&mut settings);
    let p = Pipeline::start(Painting::new(&t.canvas), settings.clone(), Hooks::default()).unwrap();
    let jobs = from_trace(&t);
    let mut seqs = Vec::new();
    for (_, job) in &jobs {
        let seq = p.submit(job.clone()).unwrap().seq;
        seqs.push(seq);
        if paced && matches!(job, Job::EndStroke | Job::Undo | Job::Redo) {
            eventually("the job shown", || p.jobs_shown() as u64 >= seq);
        }
    }
    let mut report = p.finish().unwrap();
    assert_eq!(seqs, (1..=jobs.len() as u64).collect::<Vec<_>>(), "sequence numbers");
    let l = &report.ledger;
    assert_eq!(l.jobs.len(), jobs.len(), "every job recorded once");
    for (i, j) in l.jobs.iter().enumerate() {
        assert_eq!(j.seq, i as u64 + 1);
        assert_eq!(j.kind, jobs[i].1.name());
        assert!(j.finished.is_some() && j.shown.is_some(), "job {} not finished or not shown", j.seq);
        // Shown by a frame that ended after the job finished, whose cut
        // holds the job's last publication.
        assert!(j.shown.unwrap() >= j.finished.unwrap());
        let frame = &report.frames[j.shown_frame.unwrap() as usize - 1];
        assert!(j.last_pub.is_none_or(|p| p <= frame.cut), "job {} shown before its changes were up", j.seq);
        assert!(frame.shown_jobs >= j.seq);
    }
    // The same tree as the replay.
    let (_, replayed) = replay(&t, None, &mut ()).unwrap();
    assert!(dump_bytes(&report.painting().tree) == dump_bytes(&replayed.tree), "{name}: the pipeline's tree differs from the replay's");
    // Every block on the GPU as the CPU has it, g3 included.
    let tree = &mut report.canvas.document_mut().current_mut().painting.tree;
    let n = u64::from(tree.n_used());
    let r = &mut report.renderer;
    let gpu_cells = r.pools.read_cells(&r.gpu, n).unwrap();
    let cpu_cells = stage_range(tree, 0, n as usize).cells;
    assert!(gpu_cells == cpu_cells, "{name}: GPU cells differ from the CPU pools");
    assert!(r.pools.read_g3(&r.gpu, n).unwrap() == g3_table(tree), "{name}: GPU g3 differs");
    assert!(tree.take_publication().blocks.is_empty(), "nothing left unpublished");
    let last = report.frames.last().unwrap();
    assert_eq!(last.shown_jobs, jobs.len() as u64);
    report
}

#[test]
fn the_final_state_equals_the_replay() {
    let report = run_and_check("undo_redo", |_| {});
    assert!(report.frames.iter().any(|f| f.uploads > 0));
    // The pipeline really is incremental: paced as an artist paints, each
    // stroke, undo and redo that changes something is uploaded in frames
    // of its own (unpaced, a loaded machine may finish all of them before
    // the renderer's second frame).
    let paced = run_and_check_paced("undo_redo", |_| {}, true);
    let changing = 3;
    assert!(paced.frames.iter().filter(|f| f.uploads > 0).count() >= changing, "{} frames uploaded", paced.frames.iter().filter(|f| f.uploads > 0).count());
}

#[test]
fn every_strategy_paints_the_same_tree() {
    for (label, tweak) in [
        (
            "aggressive",
            Box::new(|s: &mut Settings| s.strategy = Strategy { skip_invalid: false, aggressive_units: Some(3), grouped: false }) as Box<dyn Fn(&mut Settings)>,
        ),
        ("grouped", Box::new(|s: &mut Settings| s.strategy = Strategy { grouped: true, ..Strategy::default() })),
        ("whole pool", Box::new(|s: &mut Settings| s.block = BlockSize::WholePool)),
        (
            "big blocks, coarse mask",
            Box::new(|s: &mut Settings| {
                s.block = BlockSize::Cells(1 << 19);
                s.mask = MaskSize::Grid(4, 2);
            }),
        ),
        ("no mask", Box::new(|s: &mut Settings| s.mask = MaskSize::None)),
        (
            "one block a frame, one buffer, one unit a step",
            Box::new(|s: &mut Settings| {
                s.blocks_per_frame = 1;
                s.staging_buffers = 1;
                s.strategy = Strategy { skip_invalid: true, aggressive_units: Some(1), grouped: false };
            }),
        ),
    ] {
        eprintln!("{label}");
        run_and_check("edges", |s| tweak(s));
    }
}

#[test]
fn shutting_down_with_work_in_flight_loses_nothing() {
    // Submit everything and finish at once: the queue is full of work.
    let report = run_and_check("shapes_modes", |s| {
        s.blocks_per_frame = 1;
        s.staging_buffers = 2;
    });
    assert!(report.frames.len() > 1);
}

#[test]
fn a_stalled_renderer_does_not_stall_painting() {
    let t = trace("undo_redo");
    let gate = Arc::new(Gate::default());
    let mut settings = Settings::new(camera(&t));
    settings.staging_buffers = 1; // staging soon waits for the renderer
    let p = Pipeline::start(Painting::new(&t.canvas), settings, Hooks { render: Some(gate.clone()), stroke: None }).unwrap();
    eventually("a first frame", || p.frames() >= 1);
    gate.close();
    let frames = p.frames();
    let jobs = from_trace(&t);
    for (_, job) in &jobs {
        p.submit(job.clone()).unwrap();
    }
    eventually("painting every job while the renderer is stalled", || p.jobs_finished() == jobs.len());
    assert!(p.frames() <= frames + 1, "the renderer was stalled");
    gate.open();
    let report = p.finish().unwrap();
    assert!(report.ledger.jobs.iter().all(|j| j.shown.is_some()));
}

#[test]
fn a_stalled_painter_does_not_stall_rendering() {
    let t = trace("single_stamp");
    let gate = Arc::new(Gate::default());
    gate.close();
    let p = Pipeline::start(Painting::new(&t.canvas), Settings::new(camera(&t)), Hooks { render: None, stroke: Some(gate.clone()) }).unwrap();
    for (_, job) in from_trace(&t) {
        p.submit(job).unwrap();
    }
    // The stroke thread now waits at its gate holding the tree's lock.
    let before = p.frames();
    eventually("frames while the painter is stalled", || p.frames() >= before + 5);
    assert_eq!(p.jobs_finished(), 0, "the painter was stalled");
    gate.open();
    let report = p.finish().unwrap();
    assert!(report.ledger.jobs.iter().all(|j| j.shown.is_some()));
}

#[test]
fn a_full_job_queue_gives_the_job_back() {
    let t = trace("single_stamp");
    let gate = Arc::new(Gate::default());
    gate.close();
    let mut settings = Settings::new(camera(&t));
    settings.job_queue = 2;
    let p = Pipeline::start(Painting::new(&t.canvas), settings, Hooks { render: None, stroke: Some(gate.clone()) }).unwrap();
    let brush = from_trace(&t).into_iter().find_map(|(_, j)| if let Job::BeginStroke(b) = j { Some(b) } else { None }).unwrap();
    // One job runs into the stalled stroke thread, two wait in the queue.
    p.submit(Job::BeginStroke(brush)).unwrap();
    eventually("the stroke thread takes the first job", || p.queued() == 0);
    p.try_submit(Job::EndStroke).unwrap();
    p.try_submit(Job::BeginStroke(brush)).unwrap();
    match p.try_submit(Job::EndStroke) {
        Err((SubmitError::Full(2), Job::EndStroke)) => {}
        other => panic!("expected the job back, got {:?}", other.map(|t| t.seq)),
    }
    gate.open();
    let report = p.finish().unwrap();
    assert_eq!(report.ledger.jobs.len(), 3);
}

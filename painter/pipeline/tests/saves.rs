//! Saves through the engine (docs/documents.md, "Live sessions"): a save is
//! a job the stroke thread runs between two others while more are queued
//! behind it, so the document it writes holds exactly the events before it;
//! the strokes after it are in the journal, and opening the document with
//! its journal gives the whole session. Needs no GPU (no frames are drawn).

use std::path::Path;

use octopaint_doc::Session;
use octopaint_pipeline::jobs::from_trace;
use octopaint_pipeline::{Engine, Hooks, Job, OpenDocument, Settings};
use octopaint_tree::dump::dump_bytes;
use octopaint_tree::replay::replay;
use octopaint_tree::trace::{Camera, Trace, parse_trace, read_trace};

fn trace_path(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"))
}

/// The tree `text` (a trace) replays to.
fn replayed(text: &str) -> Vec<u8> {
    let t: Trace = parse_trace(text).unwrap();
    dump_bytes(&replay(&t, None, &mut ()).unwrap().1.tree)
}

#[test]
fn a_save_between_queued_strokes_holds_the_events_before_it() {
    let path = trace_path("shapes_modes");
    let t = read_trace(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let doc = dir.path().join("doc.octo");
    let session = Session::create(&doc, &t.canvas, &t.meta).unwrap();
    let camera = Camera { eye: [0.5, 0.5, 2.0], q: [0.0, 0.0, 0.0, 1.0], fov: [-0.5, 0.5, 0.4, -0.4], size: [64, 48], background: [0.0; 3] };
    let engine = Engine::start(Box::new(OpenDocument::new(session)), &Settings::new(camera), &Hooks::default());
    // Every job queued at once, a save after the tenth stroke's end.
    let jobs = from_trace(&t);
    let tenth = jobs.iter().enumerate().filter(|(_, (_, j))| matches!(j, Job::EndStroke)).nth(9).map(|(i, _)| i).unwrap();
    for (i, (_, job)) in jobs.iter().enumerate() {
        engine.submit(job.clone()).unwrap();
        if i == tenth {
            engine.submit(Job::Save).unwrap();
        }
    }
    let finished = engine.finish().unwrap();
    assert!(finished.messages.iter().any(|m| m.starts_with("saved ")), "{:?}", finished.messages);
    assert!(!finished.messages.iter().any(|m| m.contains("refused") || m.contains("failed")), "{:?}", finished.messages);
    drop(finished);
    // The file as the save left it (its journal holds the rest): the trace
    // up to its tenth stroke's end.
    let alone = dir.path().join("alone.octo");
    std::fs::copy(&doc, &alone).unwrap();
    let saved = Session::open(&alone).unwrap();
    assert_eq!(saved.recovered, 0);
    let mut cut = Vec::new();
    let mut ends = 0;
    for line in text.lines() {
        cut.push(line);
        if line.contains("\"stroke_end\"") {
            ends += 1;
            if ends == 10 {
                break;
            }
        }
    }
    assert!(dump_bytes(&saved.painting().tree) == replayed(&(cut.join("\n") + "\n")), "the save holds other events than the ten strokes before it");
    // With its journal: the whole session.
    let whole = Session::open(&doc).unwrap();
    assert!(whole.recovered > 0, "the strokes after the save come back from the journal");
    assert!(dump_bytes(&whole.painting().tree) == replayed(&text), "the document and its journal are not the whole trace");
}

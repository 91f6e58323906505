//! What the determinism tests (threads.rs, threads_grain.rs, lanes.rs)
//! and history_tail.rs share. Each test binary uses part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use octopaint_tree::history::UndoStep;
use octopaint_tree::layers::Document;
use octopaint_tree::paint::Painting;
use octopaint_tree::read_trace;
use octopaint_tree::replay::replay_document;

/// A painting's undo and redo steps as bytes, record by record in their
/// order (a tag tells done from undone): equal bytes, equal histories.
pub fn history_bytes(p: &Painting) -> Vec<u8> {
    let mut out = Vec::new();
    let steps = p.history.full_steps(&p.tree);
    let (done, undone) = steps.split_at(p.history.done.len());
    for (tag, steps) in [(0u8, done), (1, undone)] {
        for step in steps {
            out.push(tag);
            out.extend(step_bytes(step));
        }
    }
    out
}

/// One step with all its records (not left in the pools) as bytes: its
/// used lengths, then each entry's cell and records before and after.
pub fn step_bytes(step: &UndoStep) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend(step.n_before.to_le_bytes());
    out.extend(step.n_after.to_le_bytes());
    for (c, b, a) in step.entries() {
        out.extend(c.to_le_bytes());
        for r in [b, a] {
            out.extend(r.parent.to_le_bytes());
            out.extend(r.first_child.to_le_bytes());
            out.push(r.depth);
            out.extend(r.rgb);
            out.extend(r.sigma.to_bits().to_le_bytes());
        }
    }
    out
}

/// Everything a replay leaves that the thread count (or the vector
/// kernels) must not change.
#[derive(PartialEq, Eq)]
pub struct Outcome {
    pub files: Vec<(String, Vec<u8>)>,
    pub document: Vec<u8>,
    pub history: Vec<Vec<u8>>,
    pub warnings: Vec<String>,
}

fn document_history(doc: &Document) -> Vec<Vec<u8>> {
    doc.layers().map(|l| history_bytes(&l.painting)).collect()
}

/// Replay `trace` on a pool of `threads`, dumps in a temporary folder.
pub fn replay_on(threads: usize, trace: &Path) -> Outcome {
    let t = read_trace(trace).unwrap_or_else(|e| panic!("{}: {e}", trace.display()));
    let out = tempfile::tempdir().expect("temp dir");
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
    let (stats, doc) = pool.install(|| replay_document(&t, Some(out.path()), &mut ())).expect("replay");
    let mut files: Vec<(String, Vec<u8>)> =
        stats.written.iter().map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(p).expect("dump"))).collect();
    files.sort();
    Outcome { files, document: doc.dump_bytes(), history: document_history(&doc), warnings: stats.warnings }
}

/// The checked-in traces, sorted.
pub fn traces() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces");
    let mut v: Vec<PathBuf> =
        std::fs::read_dir(&dir).expect("traces/").map(|e| e.expect("entry").path()).filter(|p| p.extension().is_some_and(|e| e == "jsonl")).collect();
    v.sort();
    v
}

/// Two replays left the same dumps, document, undo steps and warnings;
/// `what` names the second in the messages.
pub fn assert_same(one: &Outcome, other: &Outcome, what: &str) {
    let names = |o: &Outcome| o.files.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(one), names(other), "{what}: other dumps");
    for ((name, a), (_, b)) in one.files.iter().zip(&other.files) {
        assert!(a == b, "{what}: {name} differs");
    }
    assert!(one.document == other.document, "{what}: the document dump differs");
    assert!(one.history == other.history, "{what}: the undo steps differ");
    assert_eq!(one.warnings, other.warnings, "{what}: the warnings differ");
}

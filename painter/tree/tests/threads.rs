//! The painter core's parallel passes (tree/src/par.rs) give the same bytes
//! for any number of threads: every checked-in trace is replayed on pools
//! of 1, 2 and 7 threads with every batch split (grain 1), and the snapshot
//! dumps, the document's dump, every layer's undo and redo steps (record by
//! record, in order) and the warnings must be equal. (threads_grain.rs
//! checks the same at the production grain, in its own process.)

mod common;

use std::path::{Path, PathBuf};

use octopaint_tree::layers::Document;
use octopaint_tree::par;
use octopaint_tree::replay::replay_document;
use octopaint_tree::read_trace;

/// Everything a replay leaves that the thread count must not change.
#[derive(PartialEq, Eq)]
struct Outcome {
    files: Vec<(String, Vec<u8>)>,
    document: Vec<u8>,
    history: Vec<Vec<u8>>,
    warnings: Vec<String>,
}

fn document_history(doc: &Document) -> Vec<Vec<u8>> {
    doc.layers().map(|l| common::history_bytes(&l.painting)).collect()
}

fn replay_on(threads: usize, trace: &Path) -> Outcome {
    let t = read_trace(trace).unwrap_or_else(|e| panic!("{}: {e}", trace.display()));
    let out = tempfile::tempdir().expect("temp dir");
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
    let (stats, doc) = pool.install(|| replay_document(&t, Some(out.path()), &mut ())).expect("replay");
    let mut files: Vec<(String, Vec<u8>)> = stats
        .written
        .iter()
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(p).expect("dump")))
        .collect();
    files.sort();
    Outcome { files, document: doc.dump_bytes(), history: document_history(&doc), warnings: stats.warnings }
}

fn traces() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("traces/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "jsonl"))
        .collect();
    v.sort();
    v
}

#[test]
fn every_trace_gives_the_same_bytes_on_1_2_and_7_threads() {
    par::set_grain(1);
    let all = traces();
    assert!(all.len() >= 12, "expected the checked-in traces, found {}", all.len());
    for trace in &all {
        let one = replay_on(1, trace);
        assert!(!one.files.is_empty(), "{} wrote no dumps", trace.display());
        for threads in [2, 7] {
            let other = replay_on(threads, trace);
            let names = |o: &Outcome| o.files.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
            assert_eq!(names(&one), names(&other), "{}: other dumps on {threads} threads", trace.display());
            for ((name, a), (_, b)) in one.files.iter().zip(&other.files) {
                assert!(a == b, "{}: {name} differs on {threads} threads", trace.display());
            }
            assert!(one.document == other.document, "{}: document dump differs on {threads} threads", trace.display());
            assert!(one.history == other.history, "{}: undo steps differ on {threads} threads", trace.display());
            assert_eq!(one.warnings, other.warnings, "{}: warnings differ on {threads} threads", trace.display());
        }
    }
}

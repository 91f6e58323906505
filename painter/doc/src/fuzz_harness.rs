//! The bodies of the document fuzz targets (painter/fuzz: `document`,
//! `journal`), also run by `octopaint fuzz-smoke`: any bytes give a
//! document (or a session recovered from a journal) or a clear error,
//! never a panic, and what reads is whole (its trees check, its session
//! reads as a trace).

use std::path::Path;
use std::sync::OnceLock;

use octopaint_tree::check::check_tree;
use octopaint_tree::trace::{Canvas, Meta, parse_trace_with};

use crate::Session;
use crate::format::{self, Content};

/// Largest journal a fuzzed input recovers (its strokes are painted).
const MAX_JOURNAL: usize = 1 << 14;

/// Any file as a document (every format version).
pub fn document(data: &[u8]) {
    let Ok(loaded) = format::read(data) else { return };
    match &loaded.doc.content {
        Content::Tree { tree, .. } => {
            let problems = check_tree(tree);
            assert!(problems.is_empty(), "{problems:?}");
        }
        Content::Layers(doc) => {
            for layer in doc.layers() {
                let problems = check_tree(layer.tree());
                assert!(problems.is_empty(), "{problems:?}");
            }
        }
    }
    let resolve = format::resolver(&loaded.doc.imports);
    assert!(parse_trace_with(&loaded.doc.trace_text, Some(&resolve)).is_ok(), "a document read whose session does not");
}

/// The empty document every fuzzed journal extends: a small canvas
/// (`octopaint fuzz-smoke --journal-base FILE` writes it, for the seed
/// script to paint journals against).
pub fn base() -> &'static [u8] {
    static BASE: OnceLock<Vec<u8>> = OnceLock::new();
    BASE.get_or_init(|| {
        let canvas = Canvas { roots: [2, 1, 1], max_depth: 8, root_size: 1.0, capacity: 1 << 14 };
        let dir = std::env::temp_dir().join(format!("octopaint-fuzz-journal-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temporary folder");
        let path = dir.join("base.octo");
        let _ = std::fs::remove_file(&path);
        drop(Session::create(&path, &canvas, &Meta::new()).expect("an empty document"));
        let bytes = std::fs::read(&path).expect("the document just written");
        let _ = std::fs::remove_dir_all(&dir);
        bytes
    })
}

/// Any bytes as the journal of an empty document: recovered or refused,
/// never a panic; a recovered session's trees check and its session reads.
pub fn journal(data: &[u8]) {
    if data.len() > MAX_JOURNAL {
        return;
    }
    let Ok(s) = Session::from_bytes(Path::new("fuzz.octo"), base(), Some(data)) else { return };
    for layer in s.doc.layers() {
        let problems = check_tree(layer.tree());
        assert!(problems.is_empty(), "{problems:?}");
    }
    assert!(octopaint_tree::trace::parse_trace(&s.trace_text().expect("a read session's trace is in memory")).is_ok());
}

//! The vector kernels of tree/src/lanes.rs give the same bytes as the
//! per-cell path: every checked-in trace is replayed with them on and off,
//! and the snapshot dumps, the document's dump, every layer's undo and redo
//! steps and the warnings must be equal. Its own test binary, so that the
//! switch applies to no other test.

mod common;

use common::{Outcome, replay_on, traces};
use octopaint_tree::lanes;

#[test]
fn every_trace_gives_the_same_bytes_with_and_without_the_vector_kernels() {
    assert!(lanes::available() || !cfg!(target_arch = "x86_64"), "x86-64 machines here have AVX");
    let all = traces();
    assert!(all.len() >= 12, "expected the checked-in traces, found {}", all.len());
    for trace in &all {
        lanes::set_enabled(true);
        let on = replay_on(1, trace);
        lanes::set_enabled(false);
        assert!(!lanes::available());
        let off = replay_on(1, trace);
        assert!(!on.files.is_empty(), "{} wrote no dumps", trace.display());
        let names = |o: &Outcome| o.files.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
        assert_eq!(names(&on), names(&off), "{}", trace.display());
        for ((name, a), (_, b)) in on.files.iter().zip(&off.files) {
            assert!(a == b, "{}: {name} differs without the vector kernels", trace.display());
        }
        assert!(on.document == off.document, "{}: document dump differs", trace.display());
        assert!(on.history == off.history, "{}: undo steps differ", trace.display());
        assert_eq!(on.warnings, off.warnings, "{}: warnings differ", trace.display());
    }
    lanes::set_enabled(true);
}

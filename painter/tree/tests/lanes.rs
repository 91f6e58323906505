//! The vector kernels of paint/src/lanes/ give the same bytes as the
//! per-cell path: every checked-in trace is replayed with them on and off,
//! and the snapshot dumps, the document's dump, every layer's undo and redo
//! steps and the warnings must be equal. Its own test binary, so that the
//! switch applies to no other test.

mod common;

use common::{replay_on, traces};
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
        common::assert_same(&on, &off, &format!("{}, without the vector kernels", trace.display()));
    }
    lanes::set_enabled(true);
}

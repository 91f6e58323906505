//! The painter core's parallel passes (octree/src/par.rs) give the same bytes
//! for any number of threads: every checked-in trace is replayed on pools
//! of 1, 2 and 7 threads with every batch split (grain 1), and the snapshot
//! dumps, the document's dump, every layer's undo and redo steps (record by
//! record, in order) and the warnings must be equal. (threads_grain.rs
//! checks the same at the production grain, in its own process.)

mod common;

use common::{replay_on, traces};
use octopaint_tree::par;

#[test]
fn every_trace_gives_the_same_bytes_on_1_2_and_7_threads() {
    par::set_grain(1);
    // Every split the grain allows, not the measured choice.
    par::set_measured_split(false);
    let all = traces();
    assert!(all.len() >= 12, "expected the checked-in traces, found {}", all.len());
    for trace in &all {
        let one = replay_on(1, trace);
        assert!(!one.files.is_empty(), "{} wrote no dumps", trace.display());
        for threads in [2, 7] {
            common::assert_same(&one, &replay_on(threads, trace), &format!("{}, on {threads} threads", trace.display()));
        }
    }
}

//! The top-down g3 table (dumps, CPU renders) equals the shader-shaped
//! port cell by cell on the trees of every checked-in trace: at each
//! snapshot of a version 1 trace and for every layer at the end. (The
//! property tests compare the two on random trees after every level,
//! through `check_tree`.)

mod common;

use octopaint_tree::g3::{g3_table, g3_table_per_cell};
use octopaint_tree::paint::Painting;
use octopaint_tree::read_trace;
use octopaint_tree::replay::{ReplayObserver, replay_document};

/// Compares the two tables at every snapshot and dumps the per-cell one.
struct Compare {
    name: String,
    snapshots: usize,
}

impl ReplayObserver for Compare {
    fn dump_g3(&mut self, painting: &mut Painting) -> std::io::Result<Option<Vec<[u32; 3]>>> {
        let per_cell = g3_table_per_cell(&painting.tree);
        assert!(g3_table(&painting.tree) == per_cell, "{}: snapshot {}: g3 top down differs", self.name, self.snapshots);
        self.snapshots += 1;
        Ok(Some(per_cell))
    }
}

#[test]
fn top_down_g3_is_the_per_cell_g3_on_every_trace() {
    let all = common::traces();
    assert!(all.len() >= 12, "expected the checked-in traces, found {}", all.len());
    let mut compared = 0;
    for trace in &all {
        let t = read_trace(trace).unwrap_or_else(|e| panic!("{}: {e}", trace.display()));
        let out = tempfile::tempdir().expect("temp dir");
        let mut obs = Compare { name: trace.display().to_string(), snapshots: 0 };
        let (_, doc) = replay_document(&t, Some(out.path()), &mut obs).expect("replay");
        compared += obs.snapshots;
        for (k, layer) in doc.layers().enumerate() {
            let tree = layer.tree();
            assert!(g3_table(tree) == g3_table_per_cell(tree), "{}: layer {k}: g3 top down differs", trace.display());
            compared += 1;
        }
    }
    assert!(compared > all.len(), "compared only {compared} tables");
}

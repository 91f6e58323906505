//! A done step keeps only before-records; its after-records, its tail's
//! (the cells past the used length at the stroke's start) among them, stay
//! in the pools instead of being copied (history.rs). What
//! `History::full_steps` rebuilds for every step must be the records the
//! pools held when the step was committed, through later strokes that
//! repaint, refine and collapse those cells, and through undo and redo.

mod common;

use common::step_bytes;
use octopaint_tree::dump::dump_bytes;
use octopaint_tree::paint::Painting;
use octopaint_tree::trace::{Brush, Canvas, Mode, Sample, Shape};

/// Paint strokes that overlap: new cells, cells of earlier tails
/// repainted, an erase that collapses cells an earlier stroke made, and
/// paint again where the erase was (in the units it freed).
fn strokes() -> Vec<(Brush, Vec<[f64; 3]>)> {
    let paint = |r: f64, rgb: [f64; 3]| Brush::new(Shape::Sphere, Mode::Paint, r, rgb, 0.8, 0.6);
    let line = |y: f64, n: usize| (0..n).map(|i| [20.0 + 6.0 * i as f64, y, 64.0]).collect::<Vec<_>>();
    vec![
        (paint(9.0, [0.9, 0.2, 0.1]), line(60.0, 12)),
        (paint(7.0, [0.1, 0.8, 0.3]), line(66.0, 12)),
        (Brush::new(Shape::Sphere, Mode::Erase, 12.0, [0.0; 3], 1.0, 0.9), line(62.0, 8)),
        (paint(5.0, [0.2, 0.3, 0.9]), line(63.0, 14)),
        (paint(11.0, [0.5, 0.5, 0.5]), line(70.0, 6)),
        (paint(6.0, [0.7, 0.6, 0.1]), line(100.0, 10)),
    ]
}

#[test]
fn after_records_left_in_the_pools_come_back_as_they_were_committed() {
    let canvas = Canvas { roots: [1, 1, 1], max_depth: 8, root_size: 128.0, capacity: 1 << 24 };
    let mut p = Painting::new(&canvas);
    let mut committed = Vec::new();
    let mut dumps = vec![dump_bytes(&p.tree)];
    let mut new_cells = 0;
    for (brush, points) in strokes() {
        p.begin_stroke(&brush);
        for x in points {
            p.add_sample(&Sample::at(x), 0);
        }
        p.end_stroke();
        let top = p.history.done.last().expect("a step");
        assert!(top.after_in_pools(), "a committed step leaves its after-records in the pools");
        // Right after the commit the pools hold the step's after-records:
        // what the step copied out of them before this change.
        let full = p.history.full_steps(&p.tree).pop().expect("a step");
        let grew = top.n_after > top.n_before;
        assert!(top.bytes() < full.bytes(), "the after-records left in the pools take no bytes");
        new_cells += usize::from(grew);
        assert_eq!(top.len(), full.len(), "the same entries");
        committed.push(step_bytes(&full));
        dumps.push(dump_bytes(&p.tree));
    }
    assert!(p.counters.collapses > 0, "the erase collapsed no cell");
    assert!(new_cells >= 2, "only {new_cells} strokes made cells past the used length");
    let n = committed.len();
    let older = |p: &Painting| p.history.full_steps(&p.tree).iter().map(|s| step_bytes(s)).collect::<Vec<_>>();
    assert!(older(&p) == committed, "an older step's tail, rebuilt through the strokes above it, differs");

    // Undo copies each tail out of the pools before writing the
    // before-records: the undone steps hold every record.
    for k in (0..n).rev() {
        assert!(p.undo());
        let s = p.history.undone.last().expect("undone");
        assert!(!s.after_in_pools());
        assert!(step_bytes(s) == committed[k], "undone step {k} differs from its commit");
        assert!(dump_bytes(&p.tree) == dumps[k], "undo {k} did not restore the pools");
        // The steps still done are rebuilt from the pools as they are now.
        assert!(older(&p) == committed[..k].iter().chain(committed[k..].iter().rev()).cloned().collect::<Vec<_>>());
    }
    for k in 0..n {
        assert!(p.redo());
        assert!(dump_bytes(&p.tree) == dumps[k + 1], "redo {k} did not restore the pools");
    }
    assert!(older(&p) == committed, "after undo and redo the steps differ");

    // Undo two, paint a new stroke (the redo steps go), and the steps below
    // it are still rebuilt as committed.
    p.undo();
    p.undo();
    let (brush, points) = &strokes()[0];
    p.begin_stroke(brush);
    for &x in points.iter().rev() {
        p.add_sample(&Sample::at(x), 0);
    }
    p.end_stroke();
    assert!(p.history.undone.is_empty());
    let now = older(&p);
    assert_eq!(now.len(), n - 1);
    assert!(now[..n - 2] == committed[..n - 2]);
    assert!(p.undo());
    assert!(dump_bytes(&p.tree) == dumps[n - 2]);
}

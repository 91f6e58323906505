//! The parallel passes at the production grain (octree/src/par.rs): strokes
//! like `octopaint bench tree`'s, smaller, whose large batches (new cells of
//! a round, cleaning, the undo step) are split across the pool, give the
//! same dump and undo steps on 1, 2 and 7 threads. Its own test binary, so
//! that no other test's grain applies.

mod common;

use octopaint_tree::paint::Painting;
use octopaint_tree::par;
use octopaint_tree::trace::{Brush, Canvas, Mode, Sample, Shape};

/// Strokes like `octopaint bench tree`'s, smaller: batches of thousands of
/// cells, split at the production grain.
fn paint_strokes(threads: usize) -> (Vec<u8>, Vec<u8>, u64) {
    let canvas = Canvas { roots: [1, 1, 1], max_depth: 8, root_size: 256.0, capacity: 1 << 26 };
    let mut p = Painting::new(&canvas);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
    pool.install(|| {
        for s in 0..6u32 {
            let f = f64::from(s);
            let b = Brush::new(Shape::Sphere, Mode::Paint, 9.0 + f, [0.2 + 0.1 * f, 0.5, 0.9 - 0.1 * f], 0.8, 0.5);
            p.begin_stroke(&b);
            for i in 0..24u32 {
                let t = f64::from(i);
                let at = [40.0 + 7.0 * t, 60.0 + 20.0 * f + 10.0 * (t * 0.3).sin(), 128.0 + 30.0 * (t * 0.2 + f).cos()];
                p.add_sample(&Sample::at(at), 1);
            }
            p.end_stroke();
        }
        assert!(p.undo());
    });
    (octopaint_tree::dump::dump_bytes(&p.tree), common::history_bytes(&p), p.counters.cells_created)
}

#[test]
fn large_batches_split_at_the_production_grain_give_the_same_bytes() {
    assert_eq!(par::grain(), par::DEFAULT_GRAIN);
    let one = paint_strokes(1);
    assert!(one.2 > 100_000, "the strokes should create large batches, made {} cells", one.2);
    for threads in [2, 7] {
        // The paint pass's walk split as measured (the default), then
        // every time the grain allows.
        for measured in [true, false] {
            par::set_measured_split(measured);
            let other = paint_strokes(threads);
            assert!(one.0 == other.0, "dump differs on {threads} threads (measured split: {measured})");
            assert!(one.1 == other.1, "undo steps differ on {threads} threads (measured split: {measured})");
        }
    }
    par::set_measured_split(true);
}

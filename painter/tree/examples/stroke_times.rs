//! Where a trace's replay spends its time, stroke by stroke (no dumps, no
//! images): wall time from `stroke_begin` to `stroke_end`, the paint
//! counters' change over the stroke (leaves visited by paint passes, of
//! those hit, cells written, cells created, settled tests that settled),
//! the time in paint passes, refinement levels and the stroke's end, and
//! the brush. docs/history/core-speed.md (the sixteenth step) shows it on
//! the scene.
//!
//!     cd painter && RAYON_NUM_THREADS=1 cargo run --release --locked -p octopaint-tree \
//!         --example stroke_times -- ../traces/scene.jsonl

use std::time::Instant;

use octopaint_tree::paint::{PaintCounters, Painting};
use octopaint_tree::replay::{ReplayObserver, replay};
use octopaint_tree::trace::{Event, EventKind};

struct Obs {
    t0: Instant,
    last: PaintCounters,
    samples: u64,
    brush: String,
}

impl ReplayObserver for Obs {
    fn after_event(&mut self, ev: &Event, p: &Painting) {
        match &ev.kind {
            EventKind::Brush(b) => self.brush = format!("{:?} {:?} r={} op={} h={}", b.shape, b.mode, b.radius, b.opacity, b.hardness),
            EventKind::StrokeBegin => {
                self.t0 = Instant::now();
                self.last = p.counters;
                self.samples = 0;
            }
            EventKind::Sample(_) => self.samples += 1,
            EventKind::StrokeEnd => {
                let c = p.counters;
                let l = self.last;
                println!(
                    "{:>7.1} ms {:>5} samples  visited {:>9} hit {:>9} written {:>9} created {:>8} settled {:>7} | pass {:>6.1} refine {:>6.1} end {:>6.1} ms | {}",
                    self.t0.elapsed().as_secs_f64() * 1e3,
                    self.samples,
                    c.leaves_visited - l.leaves_visited,
                    c.leaves_hit - l.leaves_hit,
                    c.cells_written - l.cells_written,
                    c.cells_created - l.cells_created,
                    c.leaves_settled - l.leaves_settled,
                    (c.paint_pass_ns - l.paint_pass_ns) as f64 / 1e6,
                    (c.refine_ns - l.refine_ns) as f64 / 1e6,
                    (c.stroke_end_ns - l.stroke_end_ns) as f64 / 1e6,
                    self.brush
                );
            }
            _ => {}
        }
    }
}

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| "traces/scene.jsonl".into());
    let data = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let trace = octopaint_tree::trace::parse_trace_bytes(&data).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut obs = Obs { t0: Instant::now(), last: PaintCounters::default(), samples: 0, brush: String::new() };
    let t = Instant::now();
    let (stats, _) = replay(&trace, None, &mut obs).expect("replay");
    println!("total {:.3} s, {} cells", t.elapsed().as_secs_f64(), stats.cells);
}

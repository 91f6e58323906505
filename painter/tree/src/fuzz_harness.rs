//! The bodies of the fuzz targets (painter/fuzz), shared with the test that
//! replays their corpora on stable Rust (tests/fuzz_corpus.rs), so that a
//! crash the fuzzer once found stays fixed.
//!
//! Any byte string must give a trace or a [`TraceError`](crate::TraceError),
//! never a panic; and any trace must replay to a valid tree. The replay
//! target bounds the work of one input (events, stamps, cells) so the
//! fuzzer spends its time on variety, not on one huge painting.

use crate::check::check_tree;
use crate::replay::replay;
use crate::trace::{EventKind, Shape, parse_trace_bytes};

/// Largest cell budget a fuzzed replay gets.
pub const FUZZ_CAPACITY: u32 = 1 << 14;
const MAX_EVENTS: usize = 400;
const MAX_STAMPS: f64 = 20_000.0;

/// Parse; on success the trace's lines are in order and its events valid.
pub fn read(data: &[u8]) {
    if let Ok(t) = parse_trace_bytes(data) {
        assert!(t.events.windows(2).all(|w| w[0].line <= w[1].line && w[0].t <= w[1].t));
    }
}

/// Parse and, if the trace is small enough, replay it under a small cell
/// budget and check the tree. Returns whether it replayed.
pub fn replay_bounded(data: &[u8]) -> bool {
    let Ok(mut t) = parse_trace_bytes(data) else { return false };
    if t.events.len() > MAX_EVENTS {
        return false;
    }
    // Stamps the trace would place: skip the ones that would take minutes.
    let mut stamps = 0.0;
    let mut brush = None;
    let mut last: Option<[f64; 3]> = None;
    for ev in &t.events {
        match &ev.kind {
            EventKind::Brush(b) => brush = Some(*b),
            EventKind::StrokeBegin => last = None,
            EventKind::Sample(s) => {
                let b = brush.expect("validated");
                if b.shape != Shape::Sphere {
                    if let Some(p) = last {
                        let d = [s.p[0] - p[0], s.p[1] - p[1], s.p[2] - p[2]];
                        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                        stamps += len / (b.spacing * b.radius * 0.25) + 1.0;
                    }
                }
                last = Some(s.p);
            }
            _ => {}
        }
    }
    if !(stamps <= MAX_STAMPS) {
        return false;
    }
    t.canvas.capacity = t.canvas.capacity.min(FUZZ_CAPACITY.max(t.canvas.roots.iter().product::<u32>().div_ceil(8) * 8));
    let (_, painting) = replay(&t, None, &mut ()).expect("no files are written");
    let problems = check_tree(&painting.tree);
    assert!(problems.is_empty(), "{problems:?}");
    true
}

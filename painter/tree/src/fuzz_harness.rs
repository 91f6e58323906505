//! The bodies of the trace and voxel-set fuzz targets (painter/fuzz), and
//! the deterministic variants `octopaint fuzz-smoke` feeds every target on
//! stable Rust in CI (docs/documents.md, "Fuzzing").
//!
//! Any byte string must give a trace or a [`TraceError`](crate::TraceError),
//! never a panic; and any trace must replay to a valid tree. The readers of
//! the other crates have theirs (`octopaint_doc::fuzz_harness`,
//! `octopaint_export::fuzz_harness`); `octopaint fuzz-smoke` runs them all
//! on stable Rust, and painter/fuzz holds the cargo-fuzz targets. The replay
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
                if b.shape != Shape::Sphere
                    && let Some(p) = last
                {
                    let d = [s.p[0] - p[0], s.p[1] - p[1], s.p[2] - p[2]];
                    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    stamps += len / (b.spacing * b.radius * 0.25) + 1.0;
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

/// A voxel set (`.npz`, spec 15.1) for the canvas of traces/imports.jsonl
/// (its voxel sets are the seeds): a set or a clear
/// error, never a panic; a set that reads is inside the canvas, its
/// values valid, its voxels distinct.
pub fn voxels(data: &[u8]) {
    let canvas = crate::trace::Canvas { roots: [2, 2, 2], max_depth: 7, root_size: 0.5, capacity: FUZZ_CAPACITY };
    if let Ok(vs) = crate::voxels::parse_voxel_set(data, &canvas) {
        assert!(vs.depth <= canvas.max_depth);
        assert_eq!((vs.ijk.len(), vs.rgb.len(), vs.sigma.len()), (vs.len(), vs.len(), vs.len()));
        assert!(vs.sigma.iter().all(|s| s.is_finite() && !s.is_sign_negative()));
        // It writes back to bytes that read as the same set.
        let again = crate::voxels::parse_voxel_set(&crate::voxels::voxel_set_bytes(&vs), &canvas).expect("a set written reads back");
        assert_eq!((again.depth, &again.ijk, &again.rgb), (vs.depth, &vs.ijk, &vs.rgb));
    }
}

/// A seeded generator, SplitMix64: the same numbers on every machine (the
/// mutator below, `bench soak`'s script).
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    #[expect(clippy::should_implement_trait, reason = "an endless generator: an Iterator would hand out Options never None")]
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// The `n`-th deterministic variant of `seed` (the same on every machine:
/// splitmix64 of `n` and nothing else): one to four of bit flips, bytes set
/// to values readers treat specially, cuts, deletions, duplicated runs and
/// splices from `others`. What `octopaint fuzz-smoke` feeds the targets
/// besides their seeds; libFuzzer (painter/fuzz) mutates guided by coverage.
pub fn mutate(seed: &[u8], others: &[Vec<u8>], n: u64) -> Vec<u8> {
    let mut rng = SplitMix64(n.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ seed.len() as u64);
    let mut next = move || rng.next();
    const SPECIAL: [u8; 12] = [0, 0xff, 0x7f, 0x80, 1, b'"', b'{', b'}', b'9', b'-', b'\n', b'e'];
    let mut out = seed.to_vec();
    for _ in 0..1 + next() % 4 {
        let len = out.len() as u64;
        let at = |r: u64| if len == 0 { 0 } else { (r % len) as usize };
        match next() % 7 {
            0 if len > 0 => {
                let i = at(next());
                out[i] ^= 1 << (next() % 8);
            }
            1 if len > 0 => {
                let i = at(next());
                out[i] = SPECIAL[(next() % SPECIAL.len() as u64) as usize];
            }
            2 => out.truncate(at(next())),
            3 if len > 1 => {
                let i = at(next());
                let j = (i + 1 + (next() % 64) as usize).min(out.len());
                out.drain(i..j);
            }
            4 if len > 1 => {
                let i = at(next());
                let j = (i + 1 + (next() % 64) as usize).min(out.len());
                let run = out[i..j].to_vec();
                let k = at(next());
                out.splice(k..k, run);
            }
            5 if !others.is_empty() => {
                let other = &others[(next() % others.len() as u64) as usize];
                if !other.is_empty() {
                    let i = (next() % other.len() as u64) as usize;
                    let j = (i + 1 + (next() % 256) as usize).min(other.len());
                    let k = at(next());
                    out.splice(k..k, other[i..j].iter().copied());
                }
            }
            _ if len > 0 => {
                // A little-endian integer of a few bytes set to an edge value.
                let i = at(next());
                let edge: [u8; 4] = [[0, 0, 0, 0], [0xff, 0xff, 0xff, 0xff], [0xff, 0xff, 0xff, 0x7f], [0, 0, 0, 0x80]][(next() % 4) as usize];
                for (k, b) in edge.iter().enumerate() {
                    if let Some(v) = out.get_mut(i + k) {
                        *v = *b;
                    }
                }
            }
            _ => {}
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_are_deterministic_and_differ() {
        let seed = br#"{"format": "ddo-trace", "version": 1}"#.to_vec();
        let others = vec![b"{\"ev\": \"undo\", \"t\": 1}".to_vec()];
        let a: Vec<Vec<u8>> = (0..200).map(|n| mutate(&seed, &others, n)).collect();
        let b: Vec<Vec<u8>> = (0..200).map(|n| mutate(&seed, &others, n)).collect();
        assert_eq!(a, b);
        let distinct: std::collections::HashSet<&Vec<u8>> = a.iter().collect();
        assert!(distinct.len() > 150, "{} distinct variants of 200", distinct.len());
        assert!(a.iter().filter(|v| **v != seed).count() > 190);
        // Empty seeds are grown by splices, never a panic.
        for n in 0..50 {
            mutate(&[], &others, n);
        }
    }
}

//! Helpers for the GPU tests: every test opens a real adapter (lavapipe in
//! CI) and fails, never skips, when there is none.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use octopaint_gpu::{Backend, Renderer};
use octopaint_tree::paint::Painting;
use octopaint_tree::replay::replay;
use octopaint_tree::trace::{Camera, EventKind, Trace, read_trace};

pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

pub fn renderer(backend: Backend) -> Renderer {
    match Renderer::new(backend) {
        Ok(r) => r,
        Err(e) => panic!("this test needs a GPU adapter and found none: {e}"),
    }
}

pub fn trace(name: &str) -> Trace {
    read_trace(&repo().join("traces").join(format!("{name}.jsonl"))).unwrap()
}

/// The painting a trace leaves, and its last camera.
pub fn painted(name: &str) -> (Painting, Camera) {
    let (painting, camera) = painted_maybe_camera(name);
    (painting, camera.expect("the trace has a camera"))
}

pub fn painted_maybe_camera(name: &str) -> (Painting, Option<Camera>) {
    let t = trace(name);
    let camera = t.events.iter().rev().find_map(|e| if let EventKind::Camera(c) = &e.kind { Some(*c) } else { None });
    let (_, painting) = replay(&t, None, &mut ()).unwrap();
    (painting, camera)
}

/// Share of pixels whose channels all lie within `steps`, and the largest
/// difference.
pub fn closeness(a: &[u8], b: &[u8], steps: u8) -> (f64, u8) {
    assert_eq!(a.len(), b.len());
    let mut within = 0usize;
    let mut worst = 0u8;
    for (pa, pb) in a.chunks(3).zip(b.chunks(3)) {
        let d = pa.iter().zip(pb).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
        worst = worst.max(d);
        if d <= steps {
            within += 1;
        }
    }
    (within as f64 / (a.len() / 3) as f64, worst)
}

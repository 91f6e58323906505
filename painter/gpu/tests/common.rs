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

/// The GPU's f32 image against the CPU port's: spec 13's tolerance (within
/// a step on at least 99.9% of pixels, PSNR at least 60 dB), and on a CPU
/// adapter (lavapipe, CI) no pixel more than 2 steps off. Lavapipe computes
/// what the port computes operation by operation; compilers that fuse
/// multiply-adds (NVIDIA's: docs/precision.md, "On an NVIDIA H100") can send
/// a ray that meets a cell boundary to the other cell, and a pixel in tens
/// of thousands, on a shadow edge, comes out tens of steps off, which spec
/// 13 allows.
pub fn assert_f32_close(r: &Renderer, gpu: &[u8], cpu: &[u8], what: &str) {
    let (within, worst) = closeness(gpu, cpu, 1);
    let db = psnr(gpu, cpu);
    let exact_adapter = r.gpu.info.device_type == wgpu::DeviceType::Cpu;
    assert!(
        within >= 0.999 && db >= 60.0 && (!exact_adapter || worst <= 2),
        "{what}: {within} within a step, worst {worst}, {db:.1} dB on {}",
        r.gpu.describe()
    );
}

/// Peak signal-to-noise ratio of two 8-bit images in dB (infinite when equal).
pub fn psnr(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len());
    let se: f64 = a.iter().zip(b).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum();
    if se == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64 * 255.0 / (se / a.len() as f64)).log10() }
}

/// The lit trace's light (traces/lit.jsonl) with shadows on or off (spec 6.1).
pub fn lit_light(shadows: bool) -> octopaint_tree::trace::Light {
    octopaint_tree::trace::Light { dir: [-0.5, 1.0, 0.2], intensity: 1.2, ambient: 0.2, shadows, ..Default::default() }
}

/// The lit trace (traces/lit.jsonl) painted and synced to a Vulkan
/// renderer, with its camera and rows of g3 and shading vectors (`RayInput::of(&tree, &g3)` is
/// the CPU port's input).
pub struct LitScene {
    pub r: Renderer,
    pub painting: Painting,
    pub camera: Camera,
    pub g3: Vec<[u32; 4]>,
}

pub fn lit_scene() -> LitScene {
    let mut r = renderer(Backend::Vulkan);
    let (mut painting, camera) = painted("lit");
    r.sync(&mut painting.tree).unwrap();
    let g3 = octopaint_tree::normals::table(&painting.tree);
    LitScene { r, painting, camera, g3 }
}

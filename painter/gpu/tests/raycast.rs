//! The GPU ray caster against its CPU port (painter/tree/src/raycast.rs):
//! the same images within a step, in f32 on Vulkan and GL, in f16 within
//! the image tolerance of spec 13; cells with broken links are skipped by
//! both in the same way.

mod common;

use common::*;
use octopaint_gpu::{Backend, Precision};
use octopaint_tree::g3::g3_table;
use octopaint_tree::pool::NONE;
use octopaint_tree::raycast::{RayInput, RayParams, render};

fn cpu_image(painting: &octopaint_tree::paint::Painting, camera: &octopaint_tree::trace::Camera) -> Vec<u8> {
    let t = &painting.tree;
    let g3 = g3_table(t);
    let inp = RayInput::of(t, &g3);
    render(&inp, &RayParams::new(&t.lat, camera))
}

#[test]
fn gpu_images_match_the_cpu_port() {
    for backend in [Backend::Vulkan, Backend::Gl] {
        let mut r = renderer(backend);
        for name in ["single_stamp", "shapes_modes"] {
            let (mut painting, camera) = painted(name);
            let gpu = r.render(&mut painting.tree, &camera, Precision::F32).unwrap();
            let cpu = cpu_image(&painting, &camera);
            let (within, worst) = closeness(&gpu, &cpu, 1);
            assert!(within >= 0.999 && worst <= 2, "{name} on {backend:?}: {within} within a step, worst {worst}");
            // Not a blank image: the painting is in it.
            let bg = cpu[..3].to_vec();
            assert!(cpu.chunks(3).filter(|p| *p != bg.as_slice()).count() > 100, "{name}: nothing painted in view");
        }
    }
}

#[test]
fn the_f16_variant_stays_within_the_image_tolerance() {
    let mut r = renderer(Backend::Vulkan);
    assert!(r.gpu.f16, "lavapipe and every recent GPU have SHADER_F16");
    let (mut painting, camera) = painted("shapes_modes");
    let f16 = r.render(&mut painting.tree, &camera, Precision::F16).unwrap();
    let cpu = cpu_image(&painting, &camera);
    let (within, _) = closeness(&f16, &cpu, 2);
    assert!(within >= 0.999, "{within} within 2 steps");
}

#[test]
fn cells_with_broken_links_are_skipped_alike() {
    let mut r = renderer(Backend::Auto);
    let (mut painting, camera) = painted("single_stamp");
    let before = r.render(&mut painting.tree, &camera, Precision::F32).unwrap();
    // Break one unit's links as a half-finished upload would: its children
    // point to no parent. Both ray casters must skip it the same way.
    let t = &mut painting.tree;
    let parent = (t.lat.padded..t.n_used()).find(|&c| t.first_child[c as usize] != NONE && t.depth[c as usize] >= 3).unwrap();
    let unit = t.first_child[parent as usize];
    for c in unit..unit + 8 {
        t.parent[c as usize] = NONE;
    }
    t.mark_everything_dirty();
    let gpu = r.render(&mut painting.tree, &camera, Precision::F32).unwrap();
    let cpu = cpu_image(&painting, &camera);
    let (within, worst) = closeness(&gpu, &cpu, 1);
    assert!(within >= 0.999 && worst <= 2, "{within} within a step, worst {worst}");
    assert!(gpu != before || cpu == before, "the broken unit changed nothing on the GPU only");
}

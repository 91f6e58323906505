//! The GPU ray caster against its CPU port (painter/tree/src/raycast/):
//! the same images within a step, in f32 on Vulkan and GL, in f16 within
//! the image tolerance of spec 13; cells with broken links are skipped by
//! both in the same way.

mod common;

use common::*;
use octopaint_gpu::{Backend, Precision};
use octopaint_tree::normals::table;
use octopaint_tree::pool::NONE;
use octopaint_tree::raycast::{RayInput, RayParams, render};
use octopaint_tree::trace::Light;

fn cpu_image(painting: &octopaint_tree::paint::Painting, camera: &octopaint_tree::trace::Camera) -> Vec<u8> {
    let t = &painting.tree;
    let g3 = table(t);
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
            assert_f32_close(&r, &gpu, &cpu, &format!("{name} on {backend:?}"));
            // Not a blank image: the painting is in it.
            let bg = cpu[..3].to_vec();
            assert!(cpu.chunks(3).filter(|p| *p != bg.as_slice()).count() > 100, "{name}: nothing painted in view");
        }
    }
}

#[test]
fn lit_gpu_images_match_the_cpu_port_and_light_changes_them() {
    let LitScene { mut r, painting, camera, g3 } = lit_scene();
    let t = &painting.tree;
    let inp = RayInput::of(t, &g3);
    let plain = RayParams::new(&t.lat, &camera);
    let unlit = render(&inp, &plain);
    let mut images = Vec::new();
    for shadows in [false, true] {
        let params = plain.with_light(Some(&lit_light(shadows)));
        let cpu = render(&inp, &params);
        let gpu = r.cast_params(&params, Precision::F32).unwrap();
        assert_f32_close(&r, &gpu, &cpu, &format!("shadows {shadows}"));
        let f16 = r.cast_params(&params, Precision::F16).unwrap();
        let (within, _) = closeness(&f16, &cpu, 2);
        assert!(within >= 0.999, "f16, shadows {shadows}: {within} within 2 steps");
        images.push(cpu);
    }
    // Light changes what unlit shows; shadows only take light away.
    let changed = |a: &[u8], b: &[u8]| a.chunks(3).zip(b.chunks(3)).filter(|(x, y)| x != y).count();
    assert!(changed(&unlit, &images[0]) > 1000, "lighting changed {} pixels", changed(&unlit, &images[0]));
    let darker = images[0].chunks(3).zip(images[1].chunks(3)).filter(|(a, b)| b.iter().zip(a.iter()).all(|(x, y)| x <= y) && a != b).count();
    let brighter = images[0].chunks(3).zip(images[1].chunks(3)).filter(|(a, b)| b.iter().zip(a.iter()).any(|(x, y)| x > y)).count();
    assert!(darker > 500 && brighter == 0, "shadows darkened {darker} pixels and brightened {brighter}");
    // Off again: the unlit pixels, exactly.
    assert_eq!(render(&inp, &plain.with_light(Some(&Light::OFF))), unlit);
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
    let parent = (t.lat.padded..t.n_used()).find(|&c| t.first_child()[c as usize] != NONE && t.depth()[c as usize] >= 3).unwrap();
    let unit = t.first_child()[parent as usize];
    for c in unit..unit + 8 {
        t.break_parent_link(c, NONE);
    }
    t.mark_everything_dirty();
    let gpu = r.render(&mut painting.tree, &camera, Precision::F32).unwrap();
    let cpu = cpu_image(&painting, &camera);
    assert_f32_close(&r, &gpu, &cpu, "a broken unit");
    assert!(gpu != before || cpu == before, "the broken unit changed nothing on the GPU only");
}

/// A document's layers (spec 6.2): the GPU's march through them matches the
/// CPU port's, unlit and lit with shadows; one layer at opacity 1 is the
/// one-tree image exactly; and the renderer follows its tree again after.
#[test]
fn a_documents_layers_on_the_gpu_match_the_cpu_port() {
    use octopaint_tree::raycast::{LayerInput, render_layers};
    let t = trace("layers");
    let camera = t.events.iter().rev().find_map(|e| if let octopaint_tree::trace::EventKind::Camera(c) = &e.kind { Some(*c) } else { None }).unwrap();
    let (_, doc) = octopaint_tree::replay::replay_document(&t, None, &mut ()).unwrap();
    let layers: Vec<_> = doc.layers().filter(|l| l.contributes()).collect();
    assert!(layers.len() >= 2);
    let g3: Vec<_> = layers.iter().map(|l| table(l.tree())).collect();
    let inputs: Vec<LayerInput> = layers.iter().zip(&g3).map(|(l, g)| LayerInput { inp: RayInput::of(l.tree(), g), opacity: l.opacity }).collect();
    let trees: Vec<_> = layers.iter().map(|l| (l.tree(), l.opacity)).collect();
    let mut r = renderer(Backend::Vulkan);
    let plain = RayParams::new(&layers[0].tree().lat, &camera);
    for params in [plain, plain.with_light(Some(&lit_light(true)))] {
        let cpu = render_layers(&inputs, &params);
        let gpu = r.render_layers(&trees, &params, Precision::F32).unwrap();
        assert_f32_close(&r, &gpu, &cpu, &format!("lit {}", params.lit));
        let f16 = r.render_layers(&trees, &params, Precision::F16).unwrap();
        let (within, _) = closeness(&f16, &cpu, 2);
        assert!(within >= 0.999, "f16, lit {}: {within} within 2 steps", params.lit);
    }
    // One layer at opacity 1: the one-tree pipeline, the one-tree image.
    let single = render(&inputs[0].inp, &plain);
    let gpu_one = r.render_layers(&trees[..1].iter().map(|(t, _)| (*t, 1.0)).collect::<Vec<_>>(), &plain, Precision::F32).unwrap();
    assert_eq!(closeness(&gpu_one, &single, 1).0, 1.0);
    // The renderer's own tree is uploaded whole again after a document.
    let (mut painting, camera) = painted("single_stamp");
    let gpu = r.render(&mut painting.tree, &camera, Precision::F32).unwrap();
    let (within, _) = closeness(&gpu, &cpu_image(&painting, &camera), 1);
    assert!(within >= 0.999, "{within}");
}

/// A front end that shows several images (the headset's eyes) casts each
/// into a pixel buffer of its own: casting one leaves the others' last
/// casts as they were, to be presented again without casting.
#[test]
fn each_pixel_slot_keeps_its_last_cast() {
    let mut r = renderer(Backend::Vulkan);
    let (mut painting, camera) = painted("single_stamp");
    let [w, h] = camera.size;
    r.ray.cast_into(0);
    let first = r.render(&mut painting.tree, &camera, Precision::F32).unwrap();
    // Another view into the second slot: the background only.
    let away = octopaint_tree::trace::Camera { background: [1.0, 0.0, 0.0], q: [0.0, 1.0, 0.0, 0.0], ..camera };
    r.ray.cast_into(1);
    let second = r.cast(&painting.tree, &away, Precision::F32).unwrap();
    assert_ne!(first, second, "the two views should differ");
    r.ray.cast_into(0);
    assert_eq!(r.ray.read_image(&r.gpu, w, h).unwrap(), first, "slot 0 lost its cast");
    r.ray.cast_into(1);
    assert_eq!(r.ray.read_image(&r.gpu, w, h).unwrap(), second, "slot 1 lost its cast");
    // A new slot has nothing cast yet.
    r.ray.cast_into(2);
    assert!(r.ray.pixel_buffer().is_none());
}

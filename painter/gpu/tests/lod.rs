//! Level of detail (spec 7) on the GPU against its CPU port: the cut's
//! pipeline draws what the CPU port draws, at k = 1 and at a coarse k that
//! changes the picture, for one tree, lit, and a document's layers; a level
//! that cuts nothing draws the full walk's image exactly.

mod common;

use common::*;
use octopaint_gpu::{Backend, Precision};
use octopaint_tree::normals::table;
use octopaint_tree::raycast::{LayerInput, RayInput, RayParams, render, render_layers};
use octopaint_tree::trace::EventKind;

#[test]
fn the_cut_on_the_gpu_matches_the_cpu_port() {
    let LitScene { mut r, painting, camera, g3 } = lit_scene();
    let t = &painting.tree;
    let inp = RayInput::of(t, &g3);
    let light = lit_light(true);
    for plain in [RayParams::new(&t.lat, &camera), RayParams::new(&t.lat, &camera).with_light(Some(&light))] {
        let full = render(&inp, &plain);
        let full_gpu = r.cast_params(&plain, Precision::F32).unwrap();
        // lam > 0 but no cell small: the cut's pipeline, the full image.
        let none = plain.with_lod(&camera, 1e-9);
        assert!(none.lod > 0.0);
        assert_eq!(render(&inp, &none), full, "lit {}", plain.lit);
        assert_eq!(r.cast_params(&none, Precision::F32).unwrap(), full_gpu, "lit {}", plain.lit);
        for k in [1.0, 4.0] {
            let params = plain.with_lod(&camera, k);
            let cpu = render(&inp, &params);
            let gpu = r.cast_params(&params, Precision::F32).unwrap();
            assert_f32_close(&r, &gpu, &cpu, &format!("k {k}, lit {}", plain.lit));
            let f16 = r.cast_params(&params, Precision::F16).unwrap();
            let (within, _) = closeness(&f16, &cpu, 2);
            assert!(within >= 0.999, "f16, k {k}, lit {}: {within} within 2 steps", plain.lit);
            if k == 4.0 {
                let (same, _) = closeness(&cpu, &full, 0);
                assert!(same < 0.97, "k 4 changed only {:.2}% of the pixels", 100.0 * (1.0 - same));
            }
        }
    }
}

#[test]
fn a_documents_cut_on_the_gpu_matches_the_cpu_port() {
    let t = trace("layers");
    let camera = t.events.iter().rev().find_map(|e| if let EventKind::Camera(c) = &e.kind { Some(*c) } else { None }).unwrap();
    let (_, doc) = octopaint_tree::replay::replay_document(&t, None, &mut ()).unwrap();
    let layers: Vec<_> = doc.layers().filter(|l| l.contributes()).collect();
    let g3: Vec<_> = layers.iter().map(|l| table(l.tree())).collect();
    let inputs: Vec<LayerInput> = layers.iter().zip(&g3).map(|(l, g)| LayerInput { inp: RayInput::of(l.tree(), g), opacity: l.opacity }).collect();
    let trees: Vec<_> = layers.iter().map(|l| (l.tree(), l.opacity)).collect();
    let mut r = renderer(Backend::Vulkan);
    let full = render_layers(&inputs, &RayParams::new(&layers[0].tree().lat, &camera));
    let params = RayParams::new(&layers[0].tree().lat, &camera).with_lod(&camera, 4.0);
    let cpu = render_layers(&inputs, &params);
    let gpu = r.render_layers(&trees, &params, Precision::F32).unwrap();
    assert_f32_close(&r, &gpu, &cpu, "layers at k 4");
    assert!(closeness(&cpu, &full, 0).0 < 0.97, "k 4 left the layers' picture as it was");
}

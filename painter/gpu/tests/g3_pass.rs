//! The g3 pass on a real adapter equals the CPU port (painter/octree/src/g3.rs)
//! for every cell, after a whole trace and after every level of painting,
//! where only the dirty blocks are uploaded and only the regions the
//! neighbour mask marks are recomputed.

mod common;

use common::*;
use octopaint_gpu::Backend;
use octopaint_tree::g3::g3_table;
use octopaint_tree::paint::Painting;
use octopaint_tree::trace::{Brush, Canvas, Mode, Sample, Shape};

#[test]
fn g3_of_whole_traces_equals_the_cpu_port() {
    for name in ["shapes_modes", "edges", "undo_redo", "capacity_limit"] {
        let (mut painting, _) = painted_maybe_camera(name);
        // A renderer follows one tree: a fresh one uploads everything.
        let mut r = renderer(Backend::Auto);
        let gpu = r.read_g3(&mut painting.tree).unwrap();
        assert!(gpu == g3_table(&painting.tree), "{name}: GPU g3 differs from the CPU port");
    }
}

#[test]
fn g3_after_every_level_equals_the_cpu_port() {
    let mut r = renderer(Backend::Auto);
    let canvas = Canvas { roots: [2, 1, 2], max_depth: 8, root_size: 1.0, capacity: 1 << 20 };
    let mut painting = Painting::new(&canvas);
    let brushes = [
        Brush::new(Shape::Sphere, Mode::Paint, 0.08, [0.9, 0.2, 0.1], 0.8, 0.5),
        Brush::new(Shape::Box, Mode::Paint, 0.05, [0.1, 0.7, 0.3], 0.9, 0.6),
        Brush::new(Shape::Sphere, Mode::Erase, 0.1, [0.0; 3], 1.0, 0.7),
        Brush::new(Shape::Cone, Mode::Mix, 0.06, [0.2, 0.2, 0.9], 0.7, 0.4),
    ];
    let mut levels = 0;
    for (s, b) in brushes.iter().enumerate() {
        painting.begin_stroke(b);
        for i in 0..6 {
            let u = i as f64 / 5.0;
            let p = [0.3 + 1.2 * u, 0.5 + 0.1 * (s as f64), 0.6 + 0.7 * u];
            painting.begin_sample(&Sample::at(p), 0);
            loop {
                let done = painting.advance_level();
                let gpu = r.read_g3(&mut painting.tree).unwrap();
                levels += 1;
                assert!(gpu == g3_table(&painting.tree), "stroke {s}, sample {i}: GPU g3 differs after a level");
                if done {
                    break;
                }
            }
        }
        painting.end_stroke();
        let gpu = r.read_g3(&mut painting.tree).unwrap();
        assert!(gpu == g3_table(&painting.tree), "stroke {s}: GPU g3 differs after cleaning");
    }
    assert!(painting.undo() && painting.undo());
    assert!(r.read_g3(&mut painting.tree).unwrap() == g3_table(&painting.tree), "after undo");
    assert!(painting.redo());
    assert!(r.read_g3(&mut painting.tree).unwrap() == g3_table(&painting.tree), "after redo");
    assert!(levels > 40, "only {levels} levels were checked");
}

#[test]
fn frames_of_one_block_each_converge_to_the_tree() {
    // Five blocks, uploaded one per frame; every frame also casts an image
    // from half-uploaded pools (links broken mid-upload must not hang or
    // crash the ray caster).
    let (mut painting, camera) = painted("shapes_modes");
    let mut r = renderer(Backend::Auto);
    let mut frames = 0;
    loop {
        let stats = r.upload_frame(&mut painting.tree, Some(1)).unwrap();
        assert!(stats.blocks <= 1);
        let image = r.cast(&painting.tree, &camera, octopaint_gpu::Precision::F32).unwrap();
        assert_eq!(image.len(), (camera.size[0] * camera.size[1] * 3) as usize);
        frames += 1;
        if stats.pending == 0 {
            break;
        }
    }
    assert!(frames >= 5, "{frames} frames");
    let gpu = r.read_g3(&mut painting.tree).unwrap();
    assert!(gpu == g3_table(&painting.tree));
    let last = r.cast(&painting.tree, &camera, octopaint_gpu::Precision::F32).unwrap();
    let mut fresh = renderer(Backend::Auto);
    assert!(last == fresh.render(&mut painting.tree.clone(), &camera, octopaint_gpu::Precision::F32).unwrap());
}

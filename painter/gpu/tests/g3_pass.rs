//! The g3 pass on a real adapter equals the CPU ports (painter/octree/src/
//! g3.rs and normals.rs: g3 and the stored shading vectors) for every cell,
//! after a whole trace and after every level of painting, where only the
//! dirty blocks are uploaded and only the regions the neighbour mask marks
//! are recomputed (spec 3.4 rules 1 to 3).

mod common;

use common::*;
use octopaint_gpu::Backend;
use octopaint_tree::normals::table;
use octopaint_tree::paint::Painting;
use octopaint_tree::trace::{Brush, Canvas, Mode, Sample, Shape};

/// The GPU's rows are the CPU port's: g3 exactly; the shading vector's
/// components within one step (1/511), and all of them in all but a few
/// cells. The same f32 operations in the same order, but the device may
/// fuse `v·511 + 0.5` or round a division otherwise, which moves a
/// component sitting on a rounding boundary by a step (spec 6.1; lavapipe
/// does this in 2 of 40,000 cells of shapes_modes). A stale vector, a cell
/// the mask missed, is off by far more, or in many cells.
fn assert_rows(gpu: &[[u32; 4]], cpu: &[[u32; 4]], what: &str) {
    assert_eq!(gpu.len(), cpu.len(), "{what}");
    let g3 = gpu.iter().zip(cpu).filter(|(g, c)| g[..3] != c[..3]).count();
    assert!(g3 == 0, "{what}: GPU g3 differs from the CPU port in {g3} cells");
    let field = |w: u32, a: u32| ((w >> (10 * a)) & 1023) as i32;
    let apart = |c: usize| (0..3).map(|a| (field(gpu[c][3], a) - field(cpu[c][3], a)).abs()).max().unwrap_or(0);
    let bad: Vec<usize> = (0..gpu.len()).filter(|&c| gpu[c][3] != cpu[c][3]).collect();
    if let Some(&c) = bad.iter().max_by_key(|&&c| apart(c)) {
        assert!(apart(c) <= 1, "{what}: cell {c}'s shading vector is {} steps from the CPU port's: GPU {:#x}, CPU {:#x}", apart(c), gpu[c][3], cpu[c][3]);
    }
    assert!(bad.len() * 1000 <= gpu.len().max(1000), "{what}: the shading vectors of {} of {} cells differ by a step", bad.len(), gpu.len());
    assert!(cpu.iter().any(|r| r[3] != octopaint_tree::normals::ZERO) || cpu.len() < 64, "{what}: no cell is lit at all");
}

#[test]
fn g3_of_whole_traces_equals_the_cpu_port() {
    for name in ["shapes_modes", "edges", "undo_redo", "capacity_limit"] {
        let (mut painting, _) = painted_maybe_camera(name);
        // A renderer follows one tree: a fresh one uploads everything.
        let mut r = renderer(Backend::Auto);
        let gpu = r.read_rows(&mut painting.tree).unwrap();
        assert_rows(&gpu, &table(&painting.tree), name);
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
                let gpu = r.read_rows(&mut painting.tree).unwrap();
                levels += 1;
                assert_rows(&gpu, &table(&painting.tree), &format!("stroke {s}, sample {i}, after a level"));
                if done {
                    break;
                }
            }
        }
        painting.end_stroke();
        let gpu = r.read_rows(&mut painting.tree).unwrap();
        assert_rows(&gpu, &table(&painting.tree), &format!("stroke {s}, after cleaning"));
    }
    assert!(painting.undo() && painting.undo());
    assert_rows(&r.read_rows(&mut painting.tree).unwrap(), &table(&painting.tree), "after undo");
    assert!(painting.redo());
    assert_rows(&r.read_rows(&mut painting.tree).unwrap(), &table(&painting.tree), "after redo");
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
    let gpu = r.read_rows(&mut painting.tree).unwrap();
    assert_rows(&gpu, &table(&painting.tree), "frames of one block");
    let last = r.cast(&painting.tree, &camera, octopaint_gpu::Precision::F32).unwrap();
    let mut fresh = renderer(Backend::Auto);
    assert!(last == fresh.render(&mut painting.tree.clone(), &camera, octopaint_gpu::Precision::F32).unwrap());
}

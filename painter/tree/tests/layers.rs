//! Layers (spec 14, 6.2) in the painter core: one history for strokes and
//! layer operations restores documents byte for byte, merge down composites
//! both layers at every point, the budget refuses an operation whole, and
//! the CPU port's march through several layers gives the single-tree image
//! where it must.

use octopaint_tree::layers::Document;
use octopaint_tree::normals::table;
use octopaint_tree::raycast::{LayerInput, RayInput, RayParams, render, render_layers};
use octopaint_tree::trace::{Brush, Camera, Canvas, LayerOp, LayerOpKind, Light, Mode, Sample, Shape};

const CANVAS: Canvas = Canvas { roots: [1, 1, 1], max_depth: 5, root_size: 1.0, capacity: 65536 };

fn paint(doc: &mut Document, p: [f64; 3], radius: f64, colour: [f64; 3]) {
    assert!(doc.begin_stroke(&Brush::new(Shape::Sphere, Mode::Paint, radius, colour, 0.9, 0.5), 1));
    doc.add_sample(&Sample { p, pressure: 1.0, q: [0.0, 0.0, 0.0, 1.0] }, 1);
    doc.end_stroke();
}

fn op(kind: LayerOpKind, layer: Option<&str>, name: Option<&str>) -> LayerOp {
    LayerOp { layer: layer.map(String::from), name: name.map(String::from), ..LayerOp::new(kind) }
}

#[test]
fn undo_and_redo_of_a_merge_restore_the_document_byte_for_byte() {
    let mut doc = Document::new(&CANVAS);
    paint(&mut doc, [0.4, 0.5, 0.5], 0.2, [0.9, 0.2, 0.1]);
    assert!(doc.apply(&op(LayerOpKind::Add, None, Some("top")), 2));
    paint(&mut doc, [0.6, 0.5, 0.5], 0.1, [0.1, 0.2, 0.9]);
    let before = doc.dump_bytes();
    assert!(doc.apply(&op(LayerOpKind::MergeDown, Some("top"), None), 3));
    assert_eq!(doc.len(), 1);
    let merged = doc.dump_bytes();
    paint(&mut doc, [0.5, 0.3, 0.5], 0.05, [0.2, 0.9, 0.2]);
    assert!(doc.undo());
    assert_eq!(doc.dump_bytes(), merged);
    assert!(doc.undo());
    assert_eq!((doc.len(), doc.selected()), (2, 1));
    assert_eq!(doc.dump_bytes(), before);
    assert!(doc.redo());
    assert_eq!(doc.dump_bytes(), merged);
    // A new step drops the redo history of every layer.
    assert!(doc.apply(&op(LayerOpKind::Rename, Some("Layer 1"), Some("base")), 4));
    assert!(!doc.redo());
}

#[test]
fn merge_down_holds_both_layers_composited_at_every_point() {
    let mut doc = Document::new(&CANVAS);
    paint(&mut doc, [0.4, 0.5, 0.5], 0.25, [0.9, 0.2, 0.1]);
    doc.apply(&op(LayerOpKind::Add, None, Some("top")), 2);
    paint(&mut doc, [0.6, 0.45, 0.5], 0.12, [0.1, 0.2, 0.9]);
    doc.apply(&LayerOp { opacity: Some(0.6), ..op(LayerOpKind::Set, Some("top"), None) }, 3);
    let probes: Vec<[f64; 3]> = (0..400).map(|i| [0, 1, 2].map(|a| ((i * 37 + a * 101) % 400) as f64 / 400.0 + 0.0007)).collect();
    let want: Vec<(f32, [u8; 3])> = {
        let (a, b) = (doc.layer(0).tree(), doc.layer(1).tree());
        probes
            .iter()
            .map(|&p| {
                let (ca, cb) = (a.leaf_at(p).unwrap() as usize, b.leaf_at(p).unwrap() as usize);
                let (wa, wb) = (f64::from(a.sigma()[ca]), f64::from(0.6f32) * f64::from(b.sigma()[cb]));
                let w = wa + wb;
                let rgb = if w > 0.0 {
                    [0, 1, 2].map(|k| ((wa * f64::from(a.rgb()[ca][k]) + wb * f64::from(b.rgb()[cb][k])) / w + 0.5).floor() as u8)
                } else {
                    a.rgb()[ca]
                };
                (w as f32, rgb)
            })
            .collect()
    };
    assert!(doc.apply(&op(LayerOpKind::MergeDown, Some("top"), None), 4));
    let m = doc.layer(0).tree();
    assert_eq!(doc.layer(0).opacity, 1.0);
    for (p, (sigma, rgb)) in probes.iter().zip(&want) {
        let c = m.leaf_at(*p).unwrap() as usize;
        assert_eq!((m.sigma()[c].to_bits(), m.rgb()[c]), (sigma.to_bits(), *rgb), "{p:?}");
    }
    assert!(octopaint_tree::clean::collapsible_anywhere(m).is_empty());
    assert!(octopaint_tree::check::check_tree(m).is_empty());
}

#[test]
fn the_budget_refuses_a_layer_operation_whole() {
    let small = Canvas { capacity: 2000, ..CANVAS };
    let mut doc = Document::new(&small);
    paint(&mut doc, [0.5, 0.5, 0.5], 0.12, [0.9, 0.2, 0.1]);
    let used = doc.used();
    assert!(used * 2 > 2000, "{used} cells: the duplicate must not fit");
    let before = doc.dump_bytes();
    assert!(!doc.apply(&op(LayerOpKind::Duplicate, Some("Layer 1"), Some("copy")), 7));
    assert_eq!(doc.take_warnings(), vec!["line 7: the cell budget cannot hold this layer operation; it is skipped".to_string()]);
    assert_eq!(doc.dump_bytes(), before);
    assert!(!doc.apply(&op(LayerOpKind::Select, Some("copy"), None), 8));
    assert_eq!(doc.take_warnings(), vec!["line 8: layer: there is no layer named \"copy\"; it is skipped".to_string()]);
    assert!(!doc.undo() || doc.len() == 1, "only the stroke is a step");
}

fn params(tree: &octopaint_tree::Tree) -> RayParams {
    let cam = Camera { eye: [0.5, 0.62, 1.9], q: [-0.15, 0.0, 0.0, 0.988771], fov: [-0.3, 0.3, 0.25, -0.25], size: [24, 20], background: [0.05, 0.05, 0.08] };
    RayParams::new(&tree.lat, &cam)
}

#[test]
fn the_march_of_an_empty_layer_or_two_halves_is_the_single_image() {
    let mut doc = Document::new(&CANVAS);
    paint(&mut doc, [0.45, 0.5, 0.5], 0.25, [0.9, 0.4, 0.1]);
    paint(&mut doc, [0.6, 0.55, 0.45], 0.08, [0.1, 0.5, 0.9]);
    let empty = Document::new(&CANVAS);
    let (t, e) = (doc.layer(0).tree(), empty.layer(0).tree());
    let (g, ge) = (table(t), table(e));
    let inp = || RayInput::of(t, &g);
    let close = |a: &[u8], b: &[u8]| a.iter().zip(b).map(|(x, y)| (i32::from(*x) - i32::from(*y)).abs()).max().unwrap();
    for light in [None, Some(Light { dir: [0.3, 1.0, 0.4], shadows: true, ..Light::default() })] {
        let pr = params(t).with_light(light.as_ref());
        let single = render(&inp(), &pr);
        let with_empty = render_layers(&[LayerInput { inp: inp(), opacity: 1.0 }, LayerInput { inp: RayInput::of(e, &ge), opacity: 1.0 }], &pr);
        assert!(close(&single, &with_empty) <= 1);
        let halves = render_layers(&[LayerInput { inp: inp(), opacity: 0.5 }, LayerInput { inp: inp(), opacity: 0.5 }], &pr);
        assert!(close(&single, &halves) <= 1);
        let half = render_layers(&[LayerInput { inp: inp(), opacity: 0.5 }], &pr);
        let sum = |v: &[u8]| v.iter().map(|&x| u64::from(x)).sum::<u64>();
        assert!(sum(&single) > sum(&half));
    }
    // No layer at all: the background.
    let none = render_layers(&[], &params(t));
    assert!(none.chunks(3).all(|p| p == [13, 13, 20]), "{:?}", &none[..3]);
}

#[test]
fn the_undo_budget_counts_the_layers_only_the_history_holds() {
    let mut doc = Document::new(&CANVAS);
    paint(&mut doc, [0.5, 0.5, 0.5], 0.3, [0.9, 0.2, 0.1]);
    assert!(doc.apply(&op(LayerOpKind::Add, None, Some("top")), 2));
    paint(&mut doc, [0.3, 0.5, 0.5], 0.03, [0.1, 0.2, 0.9]);
    let (big, strokes_only) = (doc.layer(0).tree().pool_bytes_allocated(), doc.history_bytes());
    // Deleting the big layer keeps its whole tree for undo: the history
    // holds (and counts) it.
    assert!(doc.apply(&op(LayerOpKind::Delete, Some("Layer 1"), None), 3));
    assert_eq!(doc.history_bytes(), strokes_only + big);
    let held = doc.history_bytes();
    for k in 0..3 {
        paint(&mut doc, [0.3 + 0.1 * f64::from(k), 0.4, 0.5], 0.03, [0.2, 0.9, 0.2]);
    }
    let three = doc.history_bytes() - held;
    // A budget below the deleted tree forgets the steps up to and including
    // the deletion, and with it the tree; the newer strokes stay undoable.
    let within = three + big / 2;
    let forgotten = doc.trim_to(within);
    assert!(doc.history_bytes() <= within, "{} bytes over a budget of {within}", doc.history_bytes());
    assert_eq!(forgotten, 4, "the two strokes, the add and the deletion");
    let after = doc.dump_bytes();
    for _ in 0..3 {
        assert!(doc.undo());
    }
    assert!(!doc.undo(), "the deletion was forgotten");
    assert_eq!(doc.len(), 1);
    for _ in 0..3 {
        assert!(doc.redo());
    }
    assert_eq!(doc.dump_bytes(), after);
}

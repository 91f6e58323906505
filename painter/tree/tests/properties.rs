//! Property tests over random painting sessions: after every level of every
//! sample the tree is valid and its publication covers every change; after
//! every stroke the tree is at the cleaning fixpoint and every leaf holds
//! blend(before, K, a) with `a` the stroke maximum at its centre; undo and
//! redo restore the dumps byte for byte.

use glam::DVec3;
use octopaint_tree::brush::{BlendOf, blend, quantize_rgb, quantize_sigma, sigma_brush};
use octopaint_tree::check::check_tree;
use octopaint_tree::clean::collapsible_anywhere;
use octopaint_tree::dirty::{BLOCK_CELLS, region_cells};
use octopaint_tree::dump::dump_bytes;
use octopaint_tree::g3::g3_table;
use octopaint_tree::normals::{ZERO, rows};
use octopaint_tree::paint::Painting;
use octopaint_tree::pool::{FREE, NONE, Tree};
use octopaint_tree::stroke::{Geometry, Prim, StrokePath};
use octopaint_tree::trace::{Brush, Canvas, Mode, Noise, Sample, Shape};
use proptest::prelude::*;

#[derive(Clone, Debug)]
struct StrokeSpec {
    brush: Brush,
    samples: Vec<Sample>,
}

#[derive(Clone, Debug)]
enum Op {
    Stroke(StrokeSpec),
    Undo,
    Redo,
}

#[derive(Clone, Debug)]
struct Session {
    canvas: Canvas,
    ops: Vec<Op>,
}

const SHAPES: [Shape; 5] = [Shape::Sphere, Shape::Cylinder, Shape::Box, Shape::Cone, Shape::Noise];
const MODES: [Mode; 5] = [Mode::Paint, Mode::Erase, Mode::Recolor, Mode::Mix, Mode::Pickup];

fn brush(root_size: f64) -> impl Strategy<Value = Brush> {
    (
        0..5usize,
        0..5usize,
        -5.5f64..-1.0,
        prop::array::uniform3(0.0f64..=1.0),
        0.0f64..=1.0,
        0.0f64..=1.0,
        0.1f64..1.5,
        prop::array::uniform3(0.3f64..3.0),
        (0.5f64..8.0, 1u32..5, any::<u32>(), 0.0f64..=1.0),
        (0.0f64..=1.0, 0.0f64..=1.0),
    )
        .prop_map(move |(s, m, lr, color, opacity, hardness, spacing, aspect, n, (mix, pick))| Brush {
            shape: SHAPES[s],
            mode: MODES[m],
            radius: root_size * lr.exp2(),
            color,
            opacity,
            hardness,
            spacing,
            mix_ratio: mix,
            pickup_rate: pick,
            aspect,
            noise: Noise { frequency: n.0, octaves: n.1, seed: n.2, gain: n.3 },
            mirror: None,
        })
}

fn sample(extent: [f64; 3]) -> impl Strategy<Value = Sample> {
    (prop::array::uniform3(-0.1f64..1.1), 0.0f64..=1.0, prop::array::uniform4(-1.0f64..1.0)).prop_map(move |(u, pressure, q)| {
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        Sample { p: [u[0] * extent[0], u[1] * extent[1], u[2] * extent[2]], pressure, q: if n < 1e-3 { [0.0, 0.0, 0.0, 1.0] } else { q } }
    })
}

fn session() -> impl Strategy<Value = Session> {
    (prop::array::uniform3(1u32..3), 3u32..7, prop_oneof![Just(1.0), Just(0.37), Just(1000.0)], prop_oneof![Just(1u32 << 20), 600u32..5000]).prop_flat_map(
        |(roots, max_depth, root_size, capacity)| {
            let capacity = capacity.max(roots.iter().product::<u32>().div_ceil(8) * 8);
            let extent = roots.map(|r| f64::from(r) * root_size);
            let stroke = (brush(root_size), prop::collection::vec(sample(extent), 1..6)).prop_map(|(brush, samples)| Op::Stroke(StrokeSpec { brush, samples }));
            let op = prop_oneof![6 => stroke, 1 => Just(Op::Undo), 1 => Just(Op::Redo)];
            prop::collection::vec(op, 1..6).prop_map(move |ops| Session { canvas: Canvas { roots, max_depth, root_size, capacity }, ops })
        },
    )
}

/// Every cell whose g3, shading vector or record changed since `before`
/// is covered by the publication: g3 changes by the dirty cells and the
/// mask, vector changes by the mask (spec 3.4 rule 3), record changes by
/// the dirty blocks.
fn check_publication(before: &Tree, before_g3: &[[u32; 3]], after: &mut Tree) -> Result<(), TestCaseError> {
    let before_rows = rows(before, before_g3);
    let pubn = after.take_publication();
    let g3 = g3_table(after);
    let after_rows = rows(after, &g3);
    let n = before.n_used().max(after.n_used());
    let size = region_cells(after.capacity);
    for c in 0..n {
        let old = before_g3.get(c as usize).copied().unwrap_or([NONE; 3]);
        let new = g3.get(c as usize).copied().unwrap_or([NONE; 3]);
        if old != new {
            prop_assert!(pubn.dirty_cells.binary_search(&c).is_ok(), "g3 of {c} changed {old:?} -> {new:?} but it is not dirty");
            prop_assert!(pubn.mask.get((c / size) as usize), "region of {c} not in the mask");
        }
        let (was, now) = (before_rows.get(c as usize).map_or(ZERO, |r| r[3]), after_rows.get(c as usize).map_or(ZERO, |r| r[3]));
        if was != now && after.depth().get(c as usize).is_some_and(|&d| d != FREE) {
            prop_assert!(pubn.mask.get((c / size) as usize), "the shading vector of {c} changed {was:#x} -> {now:#x} but its region is not in the mask");
        }
        if !before.record(c).same_bits(&after.record(c)) {
            prop_assert!(pubn.blocks.binary_search(&(c / BLOCK_CELLS)).is_ok(), "cell {c} changed outside the dirty blocks");
        }
    }
    Ok(())
}

/// The stroke's primitives, rebuilt independently of the painting.
fn prims_of(s: &StrokeSpec) -> Vec<Prim> {
    let mut path = StrokePath::new(s.brush);
    let mut out = Vec::new();
    for smp in &s.samples {
        path.segment(smp, s.brush.color, &mut out);
    }
    out
}

/// Spec 8.8's result: every leaf = blend(before, K, max coverage at its centre).
fn check_values(pre: &Tree, post: &Tree, s: &StrokeSpec) -> Result<(), TestCaseError> {
    let b = &s.brush;
    let prims = prims_of(s);
    let perm = octopaint_tree::noise::permutation(b.noise.seed);
    let sigma_b = sigma_brush(b.opacity, b.radius);
    for c in 0..post.n_used() {
        if !post.is_live(c) || !post.is_leaf(c) {
            continue;
        }
        let x: DVec3 = post.centre(c);
        let before = pre.leaf_at(x.to_array()).expect("a leaf's centre is inside the canvas");
        let noise = if b.shape == Shape::Noise { octopaint_tree::brush::noise_factor(&perm, b, x) } else { 1.0 };
        let (mut a, mut k) = (f64::NEG_INFINITY, 0);
        for (i, p) in prims.iter().enumerate() {
            if !p.holds(x) {
                continue; // no coverage outside the box (spec 8.5)
            }
            let cov = match &p.geo {
                Geometry::Capsule(cap) => cap.coverage(x, b.hardness),
                Geometry::Stamp(st) => {
                    let v = octopaint_tree::brush::coverage_profile(st.gauge(b.shape, b.aspect, x), b.hardness) * st.f;
                    if b.shape == Shape::Noise { v * noise } else { v }
                }
            };
            if cov > a {
                a = cov;
                k = i;
            }
        }
        if !(a >= 2.2250738585072014e-308) {
            a = 0.0;
        }
        let bi = before as usize;
        let (rgb, sigma) = blend(
            &BlendOf { mode: b.mode, sigma_b, alpha: b.opacity, mix_ratio: b.mix_ratio },
            pre.rgb()[bi].map(|v| f64::from(v) / 255.0),
            f64::from(pre.sigma()[bi]),
            prims[k].colour,
            a,
        );
        prop_assert_eq!(post.rgb()[c as usize], quantize_rgb(rgb), "rgb of leaf {}", c);
        prop_assert_eq!(post.sigma()[c as usize].to_bits(), quantize_sigma(sigma).to_bits(), "sigma of leaf {}", c);
    }
    Ok(())
}

fn run(s: &Session) -> Result<(), TestCaseError> {
    let mut painting = Painting::new(&s.canvas);
    let mut done: Vec<(Vec<u8>, Vec<u8>)> = Vec::new(); // (before, after) dumps
    let mut undone: Vec<(Vec<u8>, Vec<u8>)> = Vec::new();
    painting.tree.take_publication();
    for op in &s.ops {
        match op {
            Op::Stroke(st) => {
                let pre = painting.tree.clone();
                let before_bytes = dump_bytes(&painting.tree);
                painting.begin_stroke(&st.brush);
                for smp in &st.samples {
                    painting.begin_sample(smp, 0);
                    loop {
                        let level_before = painting.tree.clone();
                        let g3_before = g3_table(&level_before);
                        let finished = painting.advance_level();
                        // Between levels the interior values are current
                        // once published (spec 4.4).
                        check_publication(&level_before, &g3_before, &mut painting.tree)?;
                        let problems = check_tree(&painting.tree);
                        prop_assert!(problems.is_empty(), "{problems:?}");
                        if finished {
                            break;
                        }
                    }
                }
                if st.brush.mode != Mode::Pickup {
                    check_values(&pre, &painting.tree, st)?;
                }
                let level_before = painting.tree.clone();
                let g3_before = g3_table(&level_before);
                painting.end_stroke();
                check_publication(&level_before, &g3_before, &mut painting.tree)?;
                prop_assert!(check_tree(&painting.tree).is_empty());
                prop_assert!(collapsible_anywhere(&painting.tree).is_empty(), "not at the cleaning fixpoint");
                done.push((before_bytes, dump_bytes(&painting.tree)));
                undone.clear();
            }
            Op::Undo | Op::Redo => {
                let (from, to) = if matches!(op, Op::Undo) { (&mut done, &mut undone) } else { (&mut undone, &mut done) };
                let Some(step) = from.pop() else { continue };
                let level_before = painting.tree.clone();
                let g3_before = g3_table(&level_before);
                let applied = if matches!(op, Op::Undo) { painting.undo() } else { painting.redo() };
                prop_assert!(applied);
                check_publication(&level_before, &g3_before, &mut painting.tree)?;
                let want = if matches!(op, Op::Undo) { &step.0 } else { &step.1 };
                prop_assert!(dump_bytes(&painting.tree) == *want, "undo/redo did not restore the dump byte for byte");
                to.push(step);
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, max_shrink_iters: 2000, ..ProptestConfig::default() })]
    #[test]
    fn random_sessions_keep_every_invariant(s in session()) {
        run(&s)?;
    }
}

/// Replay a session's strokes, each sample in steps of at most `max_units`
/// units (None: whole levels), with the settled-leaf rule on or off,
/// checking the tree after every step.
fn paint_in_steps(s: &Session, max_units: Option<usize>, settling: bool) -> Result<Painting, TestCaseError> {
    let mut painting = Painting::new(&s.canvas);
    painting.set_settling(settling);
    for op in &s.ops {
        match op {
            Op::Stroke(st) => {
                painting.begin_stroke(&st.brush);
                for smp in &st.samples {
                    painting.begin_sample(smp, 0);
                    let mut steps = 0u32;
                    while !painting.advance(max_units) {
                        // The full check is O(cells): at steps 1, 2, 4, 8...
                        // of each sample and after its last. (Every 16th
                        // step made a one-unit split of a big session
                        // quadratic: 7 s to 6 min per run, by the seed.)
                        steps += 1;
                        if steps.is_power_of_two() {
                            // As a publication between steps leaves it.
                            painting.tree.take_publication();
                            let problems = check_tree(&painting.tree);
                            prop_assert!(problems.is_empty(), "{problems:?}");
                        }
                    }
                    // Inside the stroke the interior values wait for a
                    // reader (spec 4.4): a snapshot would update them first.
                    painting.update_prefilter();
                    let problems = check_tree(&painting.tree);
                    prop_assert!(problems.is_empty(), "{problems:?}");
                }
                painting.end_stroke();
            }
            Op::Undo => {
                painting.undo();
            }
            Op::Redo => {
                painting.redo();
            }
        }
    }
    Ok(painting)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, max_shrink_iters: 200, ..ProptestConfig::default() })]
    #[test]
    fn rounds_split_into_small_steps_paint_the_same_tree(s in session(), k in prop_oneof![Just(1usize), 2usize..40]) {
        let whole = dump_bytes(&paint_in_steps(&s, None, true)?.tree);
        let split = dump_bytes(&paint_in_steps(&s, Some(k), true)?.tree);
        prop_assert!(whole == split, "painting in steps of {k} units changed the tree");
    }
}

/// Every leaf of `a` holds the value `b` stores at its centre.
fn same_values_at_centres(a: &Tree, b: &Tree) -> Result<(), TestCaseError> {
    for c in 0..a.n_used() {
        if !a.is_live(c) || !a.is_leaf(c) {
            continue;
        }
        let x = a.centre(c).to_array();
        let other = b.leaf_at(x).expect("a leaf's centre is inside the canvas") as usize;
        prop_assert_eq!(a.rgb()[c as usize], b.rgb()[other], "rgb at the centre of leaf {} ({:?})", c, x);
        prop_assert_eq!(a.sigma()[c as usize].to_bits(), b.sigma()[other].to_bits(), "sigma at the centre of leaf {} ({:?})", c, x);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, max_shrink_iters: 500, ..ProptestConfig::default() })]
    /// Spec 8.7: a settled leaf stores what refining it would have stored at
    /// every centre inside it, so the rule changes topology, never a value.
    #[test]
    fn settled_leaves_hold_what_refinement_would(s in session()) {
        let (with, without) = (paint_in_steps(&s, None, true)?, paint_in_steps(&s, None, false)?);
        // The two use different numbers of cells: a budget may refuse
        // refinement in one and not the other.
        if with.counters.refusals + without.counters.refusals > 0 {
            return Ok(());
        }
        prop_assert!(with.counters.cells_created <= without.counters.cells_created);
        same_values_at_centres(&with.tree, &without.tree)?;
        same_values_at_centres(&without.tree, &with.tree)?;
    }
}

/// A hard sphere brush over a region painted with one colour: the rule
/// settles the cores and the repainted region, creates fewer cells, and
/// stores the same values.
#[test]
fn settling_saves_cells_on_hard_brushes() {
    let canvas = Canvas { roots: [1, 1, 1], max_depth: 7, root_size: 128.0, capacity: 1 << 24 };
    let mut brush = Brush::new(Shape::Sphere, Mode::Paint, 20.0, [0.9, 0.4, 0.1], 0.7, 0.9);
    brush.spacing = 0.3;
    let run = |settling: bool| {
        let mut p = Painting::new(&canvas);
        p.set_settling(settling);
        for stroke in 0..2 {
            p.begin_stroke(&brush);
            for i in 0..12 {
                let t = f64::from(i) * 4.0;
                p.add_sample(&Sample::at([30.0 + t, 64.0 + f64::from(stroke), 64.0]), 0);
            }
            p.end_stroke();
        }
        p
    };
    let (with, without) = (run(true), run(false));
    assert!(with.counters.leaves_settled > 0, "no leaf settled");
    assert_eq!(without.counters.leaves_settled, 0);
    assert!(
        with.counters.cells_created * 10 < without.counters.cells_created * 9,
        "settling saved under 10%: {} cells against {}",
        with.counters.cells_created,
        without.counters.cells_created
    );
    same_values_at_centres(&with.tree, &without.tree).unwrap();
    same_values_at_centres(&without.tree, &with.tree).unwrap();
    assert!(check_tree(&with.tree).is_empty());
}

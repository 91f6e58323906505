//! The exporters against the tree they export: voxel values looked up
//! through the VDB-shaped grid against brute-force sums over the tree's
//! leaves, crops and the z-up turn against the plain grid, meshes checked
//! for being closed, consistently oriented 2-manifolds enclosing a positive
//! volume, and the glTF binary and OBJ read back. (OpenVDB itself reads the
//! .vdb files in conformance/tests/test_export.py.)

use std::collections::HashMap;
use std::path::PathBuf;

use glam::DVec3;
use octopaint_export::values::{ColourSpace, srgb_to_linear};
use octopaint_export::voxels::{self, VoxelGrid};
use octopaint_export::{Crop, ExportError, Mesh, Placement, SurfaceOptions, default_iso, mesh, surface};
use octopaint_tree::paint::Painting;
use octopaint_tree::replay::{ReplayObserver, replay};
use octopaint_tree::{NONE, Tree};

struct Silent;
impl ReplayObserver for Silent {}

fn painted(name: &str) -> Painting {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"));
    let trace = octopaint_tree::read_trace(&path).expect("a checked-in trace");
    replay(&trace, None, &mut Silent).expect("replays").1
}

const TRACES: [&str; 4] = ["single_stamp", "shapes_modes", "edges", "undo_redo"];
const BIG: u64 = 1 << 40;

/// A small deterministic generator (no dependency on the exporter's order).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        self.0 >> 33
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
}

/// Sums over the leaves finer than export depth `e`, by the voxel they lie
/// in: sigma·volume, rgb·sigma·volume, rgb·volume, volume (in voxels).
type Sums = std::collections::HashMap<[u32; 3], (f64, [f64; 3], [f64; 3], f64)>;

fn sums_by_voxel(tree: &Tree, origins: &[[u32; 3]], e: u32) -> Sums {
    let dmax = tree.lat.max_depth;
    let mut sums = Sums::new();
    for l in 0..tree.n_used() as usize {
        if tree.depth()[l] == octopaint_tree::FREE || tree.first_child()[l] != NONE || u32::from(tree.depth()[l]) <= e {
            continue;
        }
        let v = origins[l].map(|o| o >> (dmax - e));
        let w = (2.0f64).powi(-3 * (i32::from(tree.depth()[l]) - e as i32));
        let sl = f64::from(tree.sigma()[l]);
        let s = sums.entry(v).or_default();
        s.0 += sl * w;
        s.3 += w;
        for a in 0..3 {
            let c = f64::from(tree.rgb()[l][a]) / 255.0;
            s.1[a] += c * sl * w;
            s.2[a] += c * w;
        }
    }
    sums
}

/// What voxel `p` at depth `e` must hold, from the leaves alone: the leaf
/// around it, or the sums over the leaves inside it (the colour weighted
/// by sigma·volume).
fn expected(tree: &Tree, sums: &Sums, e: u32, p: [i32; 3]) -> Option<(f32, [f32; 3])> {
    let dmax = tree.lat.max_depth;
    let q = p.map(|v| (v as u32) << (dmax - e));
    let c = tree.cell_at(q, dmax);
    let d = u32::from(tree.depth()[c as usize]);
    let (sigma, rgb) = if d <= e {
        let s = f64::from(tree.sigma()[c as usize]);
        (s, tree.rgb()[c as usize].map(|v| f64::from(v) / 255.0))
    } else {
        let &(s, w_rgb, all, vol) = sums.get(&p.map(|v| v as u32)).expect("leaves under a voxel");
        assert!((vol - 1.0).abs() < 1e-12, "the leaves under a voxel tile it: volume {vol}");
        let rgb = if s > 0.0 { w_rgb.map(|v| (v / s).clamp(0.0, 1.0)) } else { all };
        (s, rgb)
    };
    (sigma as f32 > 0.0).then(|| (sigma as f32, rgb.map(|v| srgb_to_linear(v) as f32)))
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 4.0 * f32::EPSILON * a.abs().max(b.abs()).max(1e-30)
}

#[test]
fn voxels_hold_the_leaves_values_at_every_depth() {
    for name in TRACES {
        let p = painted(name);
        let tree = &p.tree;
        let origins = octopaint_tree::dump::origins(tree);
        let dmax = tree.lat.max_depth;
        for e in [dmax.saturating_sub(4), dmax - 1, dmax] {
            let g = VoxelGrid::build(tree, &voxels::plan(tree, Some(e), None, BIG).unwrap(), ColourSpace::Linear, Placement::default(), &mut |_| {});
            assert_eq!(g.depth, e);
            assert_eq!(g.voxel_size, tree.lat.root_size / f64::from(1u32 << e));
            let sums = sums_by_voxel(tree, &origins, e);
            let mut rng = Lcg(e as u64 * 7919 + name.len() as u64);
            let n = tree.lat.roots.map(|r| (u64::from(r) << e) as i64);
            let (mut active, mut checked) = (0u64, 0u64);
            for _ in 0..3000 {
                let v = [0, 1, 2].map(|a| rng.below(n[a] as u64) as i32);
                let want = expected(tree, &sums, e, v);
                let got = g.get(v);
                match (want, got) {
                    (None, None) => {}
                    (Some((s, c)), Some(x)) => {
                        active += 1;
                        assert!(close(s, x.density), "{name} depth {e} voxel {v:?}: density {} != {s}", x.density);
                        for a in 0..3 {
                            assert!((c[a] - x.colour[a]).abs() <= 1e-6, "{name} {e} {v:?}: colour {:?} != {c:?}", x.colour);
                        }
                    }
                    _ => panic!("{name} depth {e} voxel {v:?}: expected {want:?}, grid has {got:?}"),
                }
                checked += 1;
            }
            // Also probe next to every painted leaf, where the values are.
            for l in 0..tree.n_used() as usize {
                if tree.depth()[l] == octopaint_tree::FREE || tree.first_child()[l] != NONE || tree.sigma()[l] == 0.0 {
                    continue;
                }
                let v = origins[l].map(|o| (o >> (dmax - e)) as i32);
                let want = expected(tree, &sums, e, v).expect("a painted leaf's voxel is active");
                let x = g.get(v).expect("active in the grid");
                assert!(close(want.0, x.density), "{name} {e} {v:?}");
                active += 1;
            }
            assert!(active > 0, "{name} {e}: no active voxel probed");
            // The active voxel count is the painted volume in voxels.
            let mut vol = 0u128;
            let mut stack: Vec<u32> = (0..tree.lat.n_roots).collect();
            while let Some(c) = stack.pop() {
                let d = u32::from(tree.depth()[c as usize]);
                let fc = tree.first_child()[c as usize];
                if fc != NONE && d < e {
                    stack.extend(fc..fc + 8);
                } else if octopaint_export::values::cell_value(tree, c).sigma as f32 > 0.0 {
                    vol += 1u128 << (3 * (e - d));
                }
            }
            assert_eq!(g.active_voxels, vol, "{name} {e}");
            let _ = checked;
        }
    }
}

#[test]
fn a_crop_is_the_whole_grid_cut_to_its_box() {
    let p = painted("shapes_modes");
    let tree = &p.tree;
    let e = tree.lat.max_depth - 1;
    let full = VoxelGrid::build(tree, &voxels::plan(tree, Some(e), None, BIG).unwrap(), ColourSpace::Srgb, Placement::default(), &mut |_| {});
    let crop = Crop { lo: [0.3, 0.55, 0.1], hi: [1.7, 1.2, 0.77] };
    let cut = VoxelGrid::build(tree, &voxels::plan(tree, Some(e), Some(crop), BIG).unwrap(), ColourSpace::Srgb, Placement::default(), &mut |_| {});
    let h = full.voxel_size;
    let lo = crop.lo.map(|v| (v / h).floor() as i32);
    let hi = crop.hi.map(|v| (v / h).ceil() as i32);
    let mut inside = 0u64;
    let (lo_b, hi_b) = full.bbox.unwrap();
    for x in lo_b[0]..=hi_b[0] {
        for y in (lo_b[1]..=hi_b[1]).step_by(3) {
            for z in (lo_b[2]..=hi_b[2]).step_by(2) {
                let v = [x, y, z];
                let within = (0..3).all(|a| v[a] >= lo[a] && v[a] < hi[a]);
                if within {
                    assert_eq!(cut.get(v), full.get(v), "{v:?}");
                    inside += u64::from(full.get(v).is_some());
                } else {
                    assert_eq!(cut.get(v), None, "{v:?} is outside the crop");
                }
            }
        }
    }
    assert!(inside > 100, "the crop holds painted voxels: {inside}");
    assert!(cut.active_voxels < full.active_voxels);
}

#[test]
fn z_up_turns_the_grid_and_scale_keeps_optical_depth() {
    let p = painted("edges");
    let tree = &p.tree;
    let e = tree.lat.max_depth - 2;
    let plain = VoxelGrid::build(tree, &voxels::plan(tree, Some(e), None, BIG).unwrap(), ColourSpace::Linear, Placement::default(), &mut |_| {});
    let turned = VoxelGrid::build(
        tree,
        &voxels::plan(tree, Some(e), None, BIG).unwrap(),
        ColourSpace::Linear,
        Placement { scale: 2.0, z_up: true, origin: [0.0; 3] },
        &mut |_| {},
    );
    assert_eq!(turned.voxel_size, 2.0 * plain.voxel_size);
    assert_eq!(turned.active_voxels, plain.active_voxels);
    let (lo, hi) = plain.bbox.unwrap();
    let mut seen = 0;
    for x in (lo[0]..=hi[0]).step_by(2) {
        for y in (lo[1]..=hi[1]).step_by(2) {
            for z in lo[2]..=hi[2] {
                let a = plain.get([x, y, z]);
                let b = turned.get([x, -1 - z, y]);
                assert_eq!(a.is_some(), b.is_some(), "{x} {y} {z}");
                if let (Some(a), Some(b)) = (a, b) {
                    assert_eq!(b.density, a.density / 2.0);
                    assert_eq!(b.colour, a.colour);
                    seen += 1;
                }
            }
        }
    }
    assert!(seen > 100);
}

#[test]
fn an_origin_far_out_moves_the_indices_by_whole_nodes() {
    // The scene's detail lies near (20000, 20000, 20000) on a 40 km canvas.
    let p = painted("scene");
    let tree = &p.tree;
    let crop = Some(Crop { lo: [20000.0, 20000.0, 19999.8], hi: [20000.3, 20000.2, 20000.0] });
    let e = 20;
    let origin = [20000.1, 20000.05, 19999.9];
    let plain = VoxelGrid::build(tree, &voxels::plan(tree, Some(e), crop, BIG).unwrap(), ColourSpace::Linear, Placement::default(), &mut |_| {});
    for z_up in [false, true] {
        let moved =
            VoxelGrid::build(tree, &voxels::plan(tree, Some(e), crop, BIG).unwrap(), ColourSpace::Linear, Placement { scale: 1.0, z_up, origin }, &mut |_| {});
        assert_eq!(moved.active_voxels, plain.active_voxels);
        let h = plain.voxel_size;
        // Indices moved by whole 4096-voxel nodes; the rest is translation,
        // under a node's width.
        let shift = origin.map(|o| ((o / h / 4096.0).floor() as i64) * 4096);
        assert!(shift.iter().all(|&s| s > 0));
        let (lo, hi) = plain.bbox.unwrap();
        let mut seen = 0;
        for x in lo[0]..=hi[0] {
            for y in (lo[1]..=hi[1]).step_by(3) {
                for z in (lo[2]..=hi[2]).step_by(3) {
                    let Some(a) = plain.get([x, y, z]) else { continue };
                    let c = [x, y, z].map(i64::from);
                    let s = [c[0] - shift[0], c[1] - shift[1], c[2] - shift[2]];
                    let q = if z_up { [s[0], -1 - s[2], s[1]] } else { s };
                    let b = moved.get(q.map(|v| v as i32)).expect("the same voxel, moved");
                    assert_eq!(a, b);
                    // Its centre lands where the canvas point minus the origin goes.
                    let file = [0, 1, 2].map(|k| (q[k] as f64 + 0.5) * h + moved.translation[k]);
                    let canvas = [0, 1, 2].map(|k| (c[k] as f64 + 0.5) * h - origin[k]);
                    let want = if z_up { [canvas[0], -canvas[2], canvas[1]] } else { canvas };
                    for k in 0..3 {
                        assert!((file[k] - want[k]).abs() < 1e-9, "{file:?} vs {want:?}");
                    }
                    seen += 1;
                }
            }
        }
        assert!(seen > 100, "{seen}");
        assert!(moved.translation.iter().all(|t| t.abs() <= 4096.0 * h));
    }
}

#[test]
fn depth_and_size_refusals_say_what_fits() {
    let p = painted("shapes_modes");
    let tree = &p.tree;
    let dmax = tree.lat.max_depth;
    match voxels::plan(tree, Some(dmax + 1), None, BIG) {
        Err(ExportError::DepthOutOfRange { depth, deepest }) => assert_eq!((depth, deepest), (dmax + 1, dmax)),
        other => panic!("expected DepthOutOfRange, got {:?}", other.err()),
    }
    let at_max = voxels::estimate(tree, dmax, None, BIG).bytes();
    let cap = at_max - 1;
    match voxels::plan(tree, Some(dmax), None, cap) {
        Err(ExportError::TooLarge { depth, bytes, cap_bytes, fits }) => {
            assert_eq!((depth, cap_bytes), (dmax, cap));
            assert!(bytes > cap);
            let f = fits.expect("a coarser depth fits");
            assert!(f < dmax && voxels::estimate(tree, f, None, BIG).bytes() <= cap);
            assert!(((f + 1)..dmax).all(|d| voxels::estimate(tree, d, None, BIG).bytes() > cap));
            let msg = ExportError::TooLarge { depth, bytes, cap_bytes, fits }.to_string();
            assert!(msg.contains(&format!("--depth {f}")), "{msg}");
        }
        other => panic!("expected TooLarge, got {:?}", other.err()),
    }
    assert_eq!(voxels::choose_depth(tree, None, BIG).unwrap(), voxels::deepest_painted(tree, None));
    let chosen = voxels::choose_depth(tree, None, cap).unwrap();
    assert!(chosen < dmax);
    assert!(matches!(voxels::choose_depth(tree, None, 1), Err(ExportError::NothingFits { .. })));
    // The estimate is the grid's real size: count the built grid's nodes.
    let g = VoxelGrid::build(tree, &voxels::plan(tree, Some(chosen), None, cap).unwrap(), ColourSpace::Linear, Placement::default(), &mut |_| {});
    let est = voxels::estimate(tree, chosen, None, BIG);
    assert_eq!(est.nodes5, g.nodes.len() as u64);
    assert_eq!(est.nodes4, g.nodes.values().map(|n| n.children.len() as u64).sum::<u64>());
    assert_eq!(est.leaves, g.nodes.values().flat_map(|n| n.children.values()).map(|n| n.leaves.len() as u64).sum::<u64>());
    assert_eq!(est.root_tiles, g.root_tiles.len() as u64);
}

/// Closed, consistently oriented 2-manifold: every directed edge once and
/// its reverse once; no degenerate triangle; positive enclosed volume.
fn check_closed(m: &Mesh, what: &str) -> f64 {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &m.triangles {
        assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2], "{what}: degenerate {t:?}");
        for i in 0..3 {
            *directed.entry((t[i], t[(i + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "{what}: edge {a}->{b} used {n} times (orientation or non-manifold)");
        assert_eq!(directed.get(&(b, a)), Some(&1), "{what}: edge {a}->{b} has no twin: a hole");
    }
    let mut vol = 0.0;
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        vol += a.dot(b.cross(c)) / 6.0;
    }
    vol
}

#[test]
fn surfaces_are_closed_oriented_manifolds() {
    for name in TRACES {
        let p = painted(name);
        let tree = &p.tree;
        let iso0 = default_iso(tree).expect("painted");
        let dmax = tree.lat.max_depth;
        let canvas = tree.lat.roots.map(|r| f64::from(r) * tree.lat.root_size);
        let crop = Crop { lo: canvas.map(|c| 0.2 * c), hi: canvas.map(|c| 0.7 * c) };
        for (iso, cap, crop) in [(iso0, dmax, None), (iso0 * 0.1, dmax, None), (iso0 * 4.0, dmax, None), (iso0, dmax - 2, None), (iso0, dmax, Some(crop))] {
            let what = format!("{name} iso {iso} cap {cap} crop {}", crop.is_some());
            let m = surface(tree, SurfaceOptions { iso, depth_cap: cap, max_triangles: usize::MAX, crop }, &mut |_| {}).unwrap();
            assert_eq!(m.positions.len(), m.colours.len());
            if m.triangles.is_empty() {
                continue;
            }
            let vol = check_closed(&m, &what);
            assert!(vol > 0.0, "{what}: volume {vol} (inward normals?)");
            // The surface lies on the canvas (or in the crop, give or take
            // the leaf centres it interpolates between) and vertices are used.
            let mut used = vec![false; m.positions.len()];
            for t in &m.triangles {
                for &i in t {
                    used[i as usize] = true;
                }
            }
            assert!(used.iter().all(|&u| u), "{what}: unused vertices");
            for p in &m.positions {
                for a in 0..3 {
                    assert!(p[a] >= 0.0 && p[a] <= canvas[a], "{what}: {p} off the canvas");
                }
            }
            // The enclosed volume is that of the leaves at or above iso,
            // give or take a layer of half a leaf around them.
            let inside: f64 = (0..tree.n_used() as usize)
                .filter(|&c| {
                    tree.depth()[c] != octopaint_tree::FREE
                        && tree.first_child()[c] == NONE
                        && u32::from(tree.depth()[c]) <= cap
                        && f64::from(tree.sigma()[c]) >= iso
                        && crop.is_none_or(|k| k.contains(tree.centre(c as u32)))
                })
                .map(|c| tree.lat.size_canvas[tree.depth()[c] as usize].powi(3))
                .sum();
            if cap == dmax && inside > 0.0 {
                // Measured on these traces: 0.95 to 1.16.
                assert!(vol > 0.8 * inside && vol < 1.25 * inside, "{what}: volume {vol} vs painted leaves {inside}");
            }
        }
        // A triangle cap refuses.
        let n = surface(tree, SurfaceOptions { iso: iso0, depth_cap: dmax, max_triangles: usize::MAX, crop: None }, &mut |_| {}).unwrap().triangles.len();
        if n > 1 {
            assert!(surface(tree, SurfaceOptions { iso: iso0, depth_cap: dmax, max_triangles: n - 1, crop: None }, &mut |_| {}).is_none());
        }
    }
}

#[test]
fn a_surface_on_the_canvas_border_is_closed_there() {
    // edges.jsonl paints across every face of the canvas.
    let p = painted("edges");
    let tree = &p.tree;
    let iso = default_iso(tree).unwrap() * 0.01;
    let m = surface(tree, SurfaceOptions { iso, depth_cap: tree.lat.max_depth, max_triangles: usize::MAX, crop: None }, &mut |_| {}).unwrap();
    let vol = check_closed(&m, "edges");
    assert!(vol > 0.0);
    let canvas = tree.lat.roots.map(|r| f64::from(r) * tree.lat.root_size);
    let near_border =
        m.positions.iter().filter(|p| (0..3).any(|a| p[a] < 1e-9 || p[a] > canvas[a] - tree.lat.size_canvas[tree.lat.max_depth as usize])).count();
    assert!(near_border > 0, "the paint reaches the border, so must the surface");
}

fn sample_mesh() -> (Mesh, Painting) {
    let p = painted("shapes_modes");
    let iso = default_iso(&p.tree).unwrap();
    let m = surface(&p.tree, SurfaceOptions { iso, depth_cap: p.tree.lat.max_depth, max_triangles: usize::MAX, crop: None }, &mut |_| {}).unwrap();
    assert!(m.triangles.len() > 1000);
    (m, p)
}

#[test]
fn glb_reads_back_with_the_gltf_crate() {
    let (m, _) = sample_mesh();
    let origin = [0.5, 0.25, 0.75];
    let placement = Placement { scale: 3.0, z_up: true, origin }; // glTF ignores z_up
    let bytes = mesh::glb_bytes(&m, placement, "test").unwrap();
    assert_eq!(bytes.len() % 4, 0);
    let g = gltf::Gltf::from_slice(&bytes).expect("a valid glTF binary");
    let blob = g.blob.as_deref().expect("a BIN chunk");
    let node = g.nodes().next().unwrap();
    let t = DVec3::from_array(node.transform().decomposed().0.map(f64::from));
    let prim = g.meshes().next().unwrap().primitives().next().unwrap();
    assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
    let r = prim.reader(|_| Some(blob));
    let pos: Vec<[f32; 3]> = r.read_positions().unwrap().collect();
    let nrm: Vec<[f32; 3]> = r.read_normals().unwrap().collect();
    let col: Vec<[f32; 3]> = r.read_colors(0).unwrap().into_rgb_f32().collect();
    let idx: Vec<u32> = r.read_indices().unwrap().into_u32().collect();
    assert_eq!(pos.len(), m.positions.len());
    assert_eq!(idx.len(), 3 * m.triangles.len());
    assert!(idx.chunks(3).zip(&m.triangles).all(|(a, b)| a == b));
    let extent = m.positions.iter().fold(0.0f64, |e, p| e.max(p.abs().max_element())) * 3.0;
    for (i, p) in pos.iter().enumerate() {
        let world = t + DVec3::from_array(p.map(f64::from));
        let want = (m.positions[i] - DVec3::from_array(origin)) * 3.0;
        assert!((world - want).length() <= 4.0 * f64::from(f32::EPSILON) * extent, "{world} vs {want}");
        let c = ColourSpace::Linear.encode(m.colours[i]);
        assert_eq!(col[i], c);
        let n = DVec3::from_array(nrm[i].map(f64::from));
        assert!((n.length() - 1.0).abs() < 1e-5);
    }
    // Normals point out: along the outward face normals on average.
    let normals = mesh::vertex_normals(&m);
    let mut agree = 0;
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        let f = (b - a).cross(c - a);
        if f.dot(normals[t[0] as usize]) > 0.0 {
            agree += 1;
        }
    }
    assert!(agree * 10 > m.triangles.len() * 9, "{agree} of {}", m.triangles.len());
    // Bounds in the accessor match the data (glTF requires them).
    let acc = prim.get(&gltf::Semantic::Positions).unwrap();
    let max = acc.max().unwrap();
    let max: Vec<f32> = max.as_array().unwrap().iter().map(|v| v.as_f64().unwrap() as f32).collect();
    for a in 0..3 {
        assert_eq!(max[a], pos.iter().map(|p| p[a]).fold(f32::NEG_INFINITY, f32::max));
    }
}

#[test]
fn obj_reads_back() {
    let (m, _) = sample_mesh();
    let mut out = Vec::new();
    mesh::write_obj(&mut out, &m, Placement { scale: 1.0, z_up: true, origin: [0.0, 0.5, 0.0] }, ColourSpace::Srgb, "test").unwrap();
    let text = String::from_utf8(out).unwrap();
    let (mut v, mut vn, mut f) = (Vec::new(), 0, Vec::new());
    for line in text.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.first() {
            Some(&"v") => v.push(w[1..].iter().map(|x| x.parse::<f64>().unwrap()).collect::<Vec<_>>()),
            Some(&"vn") => vn += 1,
            Some(&"f") => f.push(w[1..].iter().map(|x| x.split("//").next().unwrap().parse::<u32>().unwrap() - 1).collect::<Vec<_>>()),
            _ => {}
        }
    }
    assert_eq!((v.len(), vn, f.len()), (m.positions.len(), m.positions.len(), m.triangles.len()));
    for (i, row) in v.iter().enumerate() {
        let p = m.positions[i];
        // z up: (x, y, z) -> (x, -z, y), printed exactly (shortest round trip).
        assert_eq!(&row[..3], &[p.x, -p.z, p.y - 0.5]);
        assert_eq!(row[3] as f32, m.colours[i][0] as f32);
    }
    assert!(f.iter().zip(&m.triangles).all(|(a, b)| a[..] == b[..]));
}

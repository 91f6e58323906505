//! Imports (spec 15, docs/documents.md "Imports"): a painting exported to
//! OpenVDB and imported back holds every value within one colour step and
//! the rounding of sigma, whatever the placement; a closed mesh becomes
//! exactly the voxels whose centres it encloses, with its colours; meshes
//! with holes are refused.

use std::io::Cursor;
use std::path::PathBuf;

use glam::DVec3;
use octopaint_export::import::{estimate_voxels, voxels_from_mesh, voxels_from_vdb};
use octopaint_export::mesh_read::{MeshLimits, read_mesh};
use octopaint_export::vdb_read::{ReadLimits, read_vdb};
use octopaint_export::voxels::{self, VoxelGrid};
use octopaint_export::{ColourSpace, Placement, vdb};
use octopaint_tree::paint::Painting;
use octopaint_tree::replay::{ReplayObserver, replay};
use octopaint_tree::trace::Canvas;
use octopaint_tree::{FREE, NONE, Tree};

struct Silent;
impl ReplayObserver for Silent {}

fn painted(name: &str) -> (Canvas, Painting) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"));
    let trace = octopaint_tree::read_trace(&path).expect("a checked-in trace");
    (trace.canvas, replay(&trace, None, &mut Silent).expect("replays").1)
}

fn leaves(tree: &Tree) -> impl Iterator<Item = u32> + '_ {
    (0..tree.n_used()).filter(|&c| tree.depth()[c as usize] != FREE && tree.first_child()[c as usize] == NONE)
}

/// Export `tree` at its deepest leaf depth (every voxel then holds one
/// leaf's value, nothing averaged), write and read the VDB, import it into
/// an empty painting, and compare at every original leaf's centre.
fn round_trip(name: &str, placement: Placement, colour: ColourSpace) {
    let (canvas, p) = painted(name);
    let tree = &p.tree;
    let e = leaves(tree).map(|c| u32::from(tree.depth()[c as usize])).max().unwrap();
    let grid = VoxelGrid::build(tree, &voxels::plan(tree, Some(e), None, 1 << 40).unwrap(), colour, placement, &mut |_| {});
    let mut file = Cursor::new(Vec::new());
    vdb::write_vdb(&mut file, &grid, "test").unwrap();
    let (grids, _) = read_vdb(file.get_ref(), &ReadLimits { max_voxels: 1 << 26, tile_cover: true }).unwrap();
    let density = grids.iter().find(|g| g.name == "density").unwrap();
    let color = grids.iter().find(|g| g.name == "color");
    let (vs, report) = voxels_from_vdb(density, color, &canvas, None, &placement, colour, [1.0; 3]).unwrap();
    assert_eq!(report.depth, e, "{name}: the default depth is the VDB's voxel size");
    assert_eq!(report.outside, 0);
    let mut back = Painting::new(&canvas);
    back.import_voxels(&vs, 1);
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    let t2 = &back.tree;
    let mut painted = 0;
    for c in leaves(tree) {
        let x = tree.centre(c);
        let got = t2.leaf_at(x.to_array()).unwrap() as usize;
        let (s0, s1) = (tree.sigma()[c as usize], t2.sigma()[got]);
        if s0 == 0.0 {
            assert_eq!(s1, 0.0, "{name}: an empty leaf at {x} came back painted");
            continue;
        }
        painted += 1;
        if placement.scale == 1.0 {
            assert_eq!(s0.to_bits(), s1.to_bits(), "{name}: sigma at {x}");
        } else {
            // sigma / scale and back: two roundings to f32.
            assert!(((s1 - s0) / s0).abs() <= 2.0 * f32::EPSILON, "{name}: sigma {s0} came back {s1} at {x}");
        }
        for a in 0..3 {
            let (c0, c1) = (i32::from(tree.rgb()[c as usize][a]), i32::from(t2.rgb()[got][a]));
            let step = if colour == ColourSpace::Srgb { 0 } else { 1 };
            assert!((c0 - c1).abs() <= step, "{name}: colour {:?} came back {:?} at {x}", tree.rgb()[c as usize], t2.rgb()[got]);
        }
    }
    assert!(painted > 50, "{name}: only {painted} painted leaves compared");
}

#[test]
fn an_exported_volume_imports_back_within_a_colour_step() {
    for name in ["single_stamp", "shapes_modes"] {
        round_trip(name, Placement::default(), ColourSpace::Linear);
        round_trip(name, Placement::default(), ColourSpace::Srgb);
    }
}

#[test]
fn placement_scale_origin_and_up_axis_are_undone() {
    let placement = Placement { scale: 2.5, z_up: true, origin: [0.25, 0.5, 0.125] };
    round_trip("single_stamp", placement, ColourSpace::Linear);
    round_trip("shapes_modes", Placement { scale: 0.01, z_up: false, origin: [0.5, 0.5, 0.5] }, ColourSpace::Linear);
}

/// A cube as OBJ text with vertex colours (sRGB), outward faces.
fn cube_obj(lo: f64, hi: f64, drop_face: bool) -> String {
    let mut s = String::new();
    for k in 0..8 {
        let p = [k & 1, (k >> 1) & 1, (k >> 2) & 1].map(|b| if b == 1 { hi } else { lo });
        s += &format!("v {} {} {} 0.8 0.4 0.2\n", p[0], p[1], p[2]);
    }
    // Faces as quads (1-based), counter-clockwise seen from outside.
    let faces = [[1, 3, 4, 2], [5, 6, 8, 7], [1, 2, 6, 5], [3, 7, 8, 4], [1, 5, 7, 3], [2, 4, 8, 6]];
    for (i, f) in faces.iter().enumerate() {
        if drop_face && i == 0 {
            continue;
        }
        s += &format!("f {} {} {}\nf {} {} {}\n", f[0], f[1], f[2], f[0], f[2], f[3]);
    }
    s
}

#[test]
fn a_closed_mesh_becomes_the_voxels_whose_centres_it_encloses() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.obj");
    std::fs::write(&path, cube_obj(0.25, 0.75, false)).unwrap();
    let mesh = read_mesh(&path, &MeshLimits { max_triangles: 1000 }).unwrap();
    let canvas = Canvas { roots: [1, 1, 1], max_depth: 6, root_size: 1.0, capacity: 1 << 20 };
    // Depth 4: edge 1/16, centres (i + 0.5)/16 inside (0.25, 0.75) for i = 4..11.
    let (vs, report) = voxels_from_mesh(&mesh, &canvas, 4, &Placement::default(), true, 30.0).unwrap();
    assert_eq!(report.voxels, 512);
    assert!(vs.ijk.iter().all(|q| q.iter().all(|&v| (4..12).contains(&v))));
    // OBJ colours are sRGB: 0.8 is byte 204 (floor(0.8*255 + 0.5)), give or take the linear round trip.
    assert!(vs.rgb.iter().all(|c| (i32::from(c[0]) - 204).abs() <= 1 && (i32::from(c[2]) - 51).abs() <= 1), "{:?}", vs.rgb[0]);
    let mut p = Painting::new(&canvas);
    p.import_voxels(&vs, 1);
    let t = &p.tree;
    for (x, inside) in [(DVec3::splat(0.5), true), (DVec3::splat(0.27), true), (DVec3::splat(0.2), false), (DVec3::new(0.5, 0.5, 0.8), false)] {
        let c = t.leaf_at(x.to_array()).unwrap() as usize;
        assert_eq!(t.sigma()[c] > 0.0, inside, "at {x}");
    }
    // Shifted and scaled: the file's unit cube at --origin 0.25,0.25,0.25 and --scale 2.
    std::fs::write(&path, cube_obj(0.0, 1.0, false)).unwrap();
    let mesh = read_mesh(&path, &MeshLimits { max_triangles: 1000 }).unwrap();
    let (vs, _) = voxels_from_mesh(&mesh, &canvas, 4, &Placement { scale: 2.0, z_up: false, origin: [0.25; 3] }, true, 30.0).unwrap();
    assert_eq!(vs.len(), 512);
}

#[test]
fn a_mesh_with_a_hole_is_refused_saying_so() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("open.obj");
    std::fs::write(&path, cube_obj(0.25, 0.75, true)).unwrap();
    let mesh = read_mesh(&path, &MeshLimits { max_triangles: 1000 }).unwrap();
    let canvas = Canvas { roots: [1, 1, 1], max_depth: 6, root_size: 1.0, capacity: 1 << 20 };
    let err = voxels_from_mesh(&mesh, &canvas, 4, &Placement::default(), true, 30.0).unwrap_err();
    assert!(err.contains("boundary"), "{err}");
}

#[test]
fn a_depth_too_fine_is_refused_at_once_naming_one_that_fits() {
    let (canvas, p) = painted("single_stamp");
    let tree = &p.tree;
    let grid = VoxelGrid::build(tree, &voxels::plan(tree, Some(6), None, 1 << 40).unwrap(), ColourSpace::Linear, Placement::default(), &mut |_| {});
    let mut file = Cursor::new(Vec::new());
    vdb::write_vdb(&mut file, &grid, "test").unwrap();
    let (grids, _) = read_vdb(file.get_ref(), &ReadLimits { max_voxels: 1 << 26, tile_cover: false }).unwrap();
    let density = grids.iter().find(|g| g.name == "density").unwrap();
    // The same canvas, deeper: depth 20 would make each VDB voxel 8^14 voxels.
    let deep = Canvas { max_depth: 20, ..canvas };
    let t0 = std::time::Instant::now();
    let err = voxels_from_vdb(density, None, &deep, Some(20), &Placement::default(), ColourSpace::Linear, [1.0; 3]).unwrap_err();
    assert!(t0.elapsed().as_secs() < 10, "refused only after {:?}", t0.elapsed());
    let fits: u32 = err.split("--depth ").nth(1).and_then(|r| r.split(' ').next()).and_then(|d| d.parse().ok()).unwrap_or_else(|| panic!("{err}"));
    // The finest depth whose count fits, counted as the import counts
    // (an import at `fits` itself would make some 10^7 voxels).
    let max = octopaint_tree::voxels::MAX_VOXELS as f64;
    assert!(estimate_voxels(density, &deep, fits, &Placement::default()) <= max);
    assert!(estimate_voxels(density, &deep, fits + 1, &Placement::default()) > max);
    // And a depth that fits imports exactly the VDB's voxels' cells (depth 6 here).
    let (vs, _) = voxels_from_vdb(density, None, &deep, Some(6), &Placement::default(), ColourSpace::Linear, [1.0; 3]).unwrap();
    assert_eq!(vs.len() as f64, estimate_voxels(density, &deep, 6, &Placement::default()));
}

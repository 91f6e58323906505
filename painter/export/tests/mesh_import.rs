//! The mesh reader and the solid voxeliser behind `octopaint import-mesh`:
//! exact voxel counts for boxes and an octahedron whose faces, edges and
//! vertices lie on the voxel-centre lattice (the tie rule), volumes of a
//! sphere and a torus, closedness refusals, colours and node transforms
//! from glTF and OBJ files written here, the crate's own glTF export read
//! back, limits and malformed files.

use std::path::{Path, PathBuf};

use gltf::json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use octopaint_export::mesh_read::{MeshError, MeshLimits, TriMesh, read_mesh};
use octopaint_export::values::srgb_to_linear;
use octopaint_export::voxelise::{SolidGrid, check_closed, voxelise};

const NO_LIMIT: MeshLimits = MeshLimits { max_triangles: u64::MAX };
const BIG: u64 = 1 << 40;

// ------------------------------------------------------------ geometry

/// The box [lo, hi] as 8 vertices and 12 triangles, counter-clockwise
/// seen from outside.
fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let p = (0..8).map(|i| [0, 1, 2].map(|a| if i >> a & 1 == 1 { hi[a] } else { lo[a] })).collect();
    // Corner i has bit a set when coordinate a is at hi.
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let t = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    (p, t)
}

fn tri_mesh(positions: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> TriMesh {
    let colours = vec![[1.0; 3]; positions.len()];
    TriMesh { positions, colours, triangles }
}

fn signed_volume(m: &TriMesh) -> f64 {
    m.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            (a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0
        })
        .sum()
}

/// A unit icosphere: the icosahedron subdivided `levels` times.
fn icosphere(levels: u32) -> TriMesh {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let mut p: Vec<[f64; 3]> = vec![
        [-1.0, g, 0.0],
        [1.0, g, 0.0],
        [-1.0, -g, 0.0],
        [1.0, -g, 0.0],
        [0.0, -1.0, g],
        [0.0, 1.0, g],
        [0.0, -1.0, -g],
        [0.0, 1.0, -g],
        [g, 0.0, -1.0],
        [g, 0.0, 1.0],
        [-g, 0.0, -1.0],
        [-g, 0.0, 1.0],
    ];
    let mut t: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let norm = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| c / l)
    };
    for v in &mut p {
        *v = norm(*v);
    }
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        for tri in &t {
            let m = [0, 1, 2].map(|e| {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let (pa, pb) = (p[a as usize], p[b as usize]);
                    p.push(norm([0, 1, 2].map(|k| pa[k] + pb[k])));
                    (p.len() - 1) as u32
                })
            });
            next.extend([[tri[0], m[0], m[2]], [tri[1], m[1], m[0]], [tri[2], m[2], m[1]], [m[0], m[1], m[2]]]);
        }
        t = next;
    }
    tri_mesh(p, t)
}

/// A UV sphere of radius `r` with `n` bands and 2n segments: 4n² − 4n
/// triangles (poles as fans).
fn uv_sphere(n: u32, r: f64) -> TriMesh {
    let seg = 2 * n;
    let mut p = vec![[0.0, 0.0, r], [0.0, 0.0, -r]];
    for i in 1..n {
        let th = std::f64::consts::PI * f64::from(i) / f64::from(n);
        for j in 0..seg {
            let ph = 2.0 * std::f64::consts::PI * f64::from(j) / f64::from(seg);
            p.push([r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), r * th.cos()]);
        }
    }
    let ring = |i: u32, j: u32| 2 + (i - 1) * seg + j % seg;
    let mut t = Vec::new();
    for j in 0..seg {
        t.push([0, ring(1, j), ring(1, j + 1)]);
        t.push([1, ring(n - 1, j + 1), ring(n - 1, j)]);
        for i in 1..n - 1 {
            t.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
            t.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
        }
    }
    tri_mesh(p, t)
}

/// A torus around the z axis: tube radius `r` at distance `big_r`.
fn torus(big_r: f64, r: f64, nu: u32, nv: u32) -> TriMesh {
    let mut p = Vec::new();
    for i in 0..nu {
        let u = 2.0 * std::f64::consts::PI * f64::from(i) / f64::from(nu);
        for j in 0..nv {
            let v = 2.0 * std::f64::consts::PI * f64::from(j) / f64::from(nv);
            let w = big_r + r * v.cos();
            p.push([w * u.cos(), w * u.sin(), r * v.sin()]);
        }
    }
    let id = |i: u32, j: u32| (i % nu) * nv + j % nv;
    let mut t = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    tri_mesh(p, t)
}

/// A grid covering [lo, hi] with spacing h, starting at `lo` shifted by
/// `shift`·h.
fn grid_over(lo: f64, hi: f64, h: f64, shift: f64) -> SolidGrid {
    let origin = lo - h + shift * h;
    let n = ((hi - origin) / h).ceil() as u32 + 2;
    SolidGrid { origin: [origin; 3], h, dims: [n; 3] }
}

/// How many of `grid`'s centres on `axis` lie in [lo, hi).
fn centres_in(grid: &SolidGrid, axis: usize, lo: f64, hi: f64) -> u64 {
    (0..grid.dims[axis]).filter(|&i| (lo..hi).contains(&grid.centre(axis, i))).count() as u64
}

fn assert_row_order(v: &[([u32; 3], [f32; 3])]) {
    for w in v.windows(2) {
        let key = |x: &([u32; 3], [f32; 3])| (x.0[2], x.0[1], x.0[0]);
        assert!(key(&w[0]) < key(&w[1]), "not in (z, y, x) order: {:?} then {:?}", w[0].0, w[1].0);
    }
}

// ------------------------------------------------------------- writers

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("a temporary directory")
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write a test file");
    p
}

/// OBJ text: `v` lines (with colours when given), then faces.
fn obj_text(positions: &[[f64; 3]], colours: Option<&[[f64; 3]]>, triangles: &[[u32; 3]]) -> String {
    let mut s = String::new();
    for (i, p) in positions.iter().enumerate() {
        match colours {
            Some(c) => s += &format!("v {} {} {} {} {} {}\n", p[0], p[1], p[2], c[i][0], c[i][1], c[i][2]),
            None => s += &format!("v {} {} {}\n", p[0], p[1], p[2]),
        }
    }
    for t in triangles {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

enum Colours {
    None,
    F32(Vec<[f32; 3]>),
    U8Rgba(Vec<[u8; 4]>),
    U16Rgba(Vec<[u16; 4]>),
}

struct Prim {
    positions: Vec<[f32; 3]>,
    colours: Colours,
    indices: Option<Vec<u32>>,
    mode: json::mesh::Mode,
    factor: [f32; 4],
}

impl Prim {
    fn triangles(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Prim {
        Prim {
            positions: positions.iter().map(|p| p.map(|v| v as f32)).collect(),
            colours: Colours::None,
            indices: Some(triangles.iter().flatten().copied().collect()),
            mode: json::mesh::Mode::Triangles,
            factor: [1.0; 4],
        }
    }
}

#[derive(Default)]
struct NodeSpec {
    mesh: Option<Vec<Prim>>,
    translation: Option<[f32; 3]>,
    scale: Option<[f32; 3]>,
    rotation: Option<[f32; 4]>,
    children: Vec<u32>,
}

/// A glTF document over one buffer holding every accessor, and that
/// buffer; scene 0 has `roots`.
fn gltf_doc(nodes: Vec<NodeSpec>, roots: &[u32]) -> (json::Root, Vec<u8>) {
    let mut root = json::Root::default();
    let mut bin: Vec<u8> = Vec::new();
    let buffer = json::Index::new(0);
    let add = |root: &mut json::Root,
               bin: &mut Vec<u8>,
               bytes: &[u8],
               count: usize,
               ct: json::accessor::ComponentType,
               ty: json::accessor::Type,
               normalized: bool,
               min_max: Option<(Vec<f32>, Vec<f32>)>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let view = root.push(json::buffer::View {
            buffer,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(bin.len())),
            byte_stride: None,
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            target: None,
        });
        bin.extend_from_slice(bytes);
        root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(ct)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(ty),
            min: min_max.as_ref().map(|m| json::Value::from(m.0.clone())),
            max: min_max.as_ref().map(|m| json::Value::from(m.1.clone())),
            name: None,
            normalized,
            sparse: None,
        })
    };
    use json::accessor::{ComponentType as C, Type as T};
    let mut node_ix = Vec::new();
    for spec in &nodes {
        let mesh = spec.mesh.as_ref().map(|prims| {
            let primitives = prims
                .iter()
                .map(|pr| {
                    let bytes: Vec<u8> = pr.positions.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
                    let lo = (0..3).map(|a| pr.positions.iter().map(|p| p[a]).fold(f32::INFINITY, f32::min)).collect();
                    let hi = (0..3).map(|a| pr.positions.iter().map(|p| p[a]).fold(f32::NEG_INFINITY, f32::max)).collect();
                    let pos = add(&mut root, &mut bin, &bytes, pr.positions.len(), C::F32, T::Vec3, false, Some((lo, hi)));
                    let mut attributes = std::collections::BTreeMap::from([(Valid(json::mesh::Semantic::Positions), pos)]);
                    let col = match &pr.colours {
                        Colours::None => None,
                        Colours::F32(c) => {
                            let b: Vec<u8> = c.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
                            Some(add(&mut root, &mut bin, &b, c.len(), C::F32, T::Vec3, false, None))
                        }
                        Colours::U8Rgba(c) => Some(add(&mut root, &mut bin, &c.concat(), c.len(), C::U8, T::Vec4, true, None)),
                        Colours::U16Rgba(c) => {
                            let b: Vec<u8> = c.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
                            Some(add(&mut root, &mut bin, &b, c.len(), C::U16, T::Vec4, true, None))
                        }
                    };
                    if let Some(col) = col {
                        attributes.insert(Valid(json::mesh::Semantic::Colors(0)), col);
                    }
                    let indices = pr.indices.as_ref().map(|ix| {
                        let b: Vec<u8> = ix.iter().flat_map(|v| v.to_le_bytes()).collect();
                        add(&mut root, &mut bin, &b, ix.len(), C::U32, T::Scalar, false, None)
                    });
                    let material = root.push(json::Material {
                        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                            base_color_factor: json::material::PbrBaseColorFactor(pr.factor),
                            ..Default::default()
                        },
                        ..Default::default()
                    });
                    json::mesh::Primitive {
                        attributes,
                        extensions: Default::default(),
                        extras: Default::default(),
                        indices,
                        material: Some(material),
                        mode: Valid(pr.mode),
                        targets: None,
                    }
                })
                .collect();
            root.push(json::Mesh { extensions: Default::default(), extras: Default::default(), name: None, primitives, weights: None })
        });
        node_ix.push(mesh);
    }
    for (spec, mesh) in nodes.iter().zip(node_ix) {
        root.push(json::Node {
            mesh,
            translation: spec.translation,
            scale: spec.scale,
            rotation: spec.rotation.map(json::scene::UnitQuaternion),
            children: (!spec.children.is_empty()).then(|| spec.children.iter().map(|&c| json::Index::new(c)).collect()),
            ..Default::default()
        });
    }
    let scene = root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: roots.iter().map(|&r| json::Index::new(r)).collect(),
    });
    root.scene = Some(scene);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root.push(json::Buffer { byte_length: USize64::from(bin.len()), extensions: Default::default(), extras: Default::default(), name: None, uri: None });
    (root, bin)
}

fn glb(root: &json::Root, bin: Vec<u8>) -> Vec<u8> {
    let mut j = json::serialize::to_vec(root).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let length = (12 + 8 + j.len() + 8 + bin.len()) as u32;
    gltf::binary::Glb {
        header: gltf::binary::Header { magic: *b"glTF", version: 2, length },
        bin: Some(std::borrow::Cow::Owned(bin)),
        json: std::borrow::Cow::Owned(j),
    }
    .to_vec()
    .unwrap()
}

/// The same document as a .gltf whose buffer has `uri`.
fn gltf_text(root: &json::Root, uri: String) -> Vec<u8> {
    let mut r = root.clone();
    r.buffers[0].uri = Some(uri);
    json::serialize::to_vec(&r).unwrap()
}

fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16) | (u32::from(*c.get(1).unwrap_or(&0)) << 8) | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

// ------------------------------------------------------------ the tie rule

#[test]
fn a_cube_fills_the_centres_in_its_half_open_box_for_every_alignment() {
    let dir = tmp();
    let (p, t) = cuboid([0.0; 3], [1.0; 3]);
    let path = write(dir.path(), "cube.obj", obj_text(&p, None, &t).as_bytes());
    let m = read_mesh(&path, &NO_LIMIT).unwrap();
    assert_eq!((m.positions.len(), m.triangles.len()), (8, 12));
    let report = check_closed(&m).unwrap();
    assert_eq!((report.vertices, report.triangles, report.degenerate_dropped), (8, 12, 0));
    let mut flipped = m.clone();
    for tri in &mut flipped.triangles {
        tri.swap(0, 1);
    }
    let grids = [
        // Faces, edges and vertices exactly on voxel centres.
        SolidGrid { origin: [-0.125; 3], h: 0.25, dims: [8; 3] },
        SolidGrid { origin: [-0.625, -0.125, -0.375], h: 0.25, dims: [9, 7, 8] },
        // Faces half-way between centres.
        SolidGrid { origin: [0.0; 3], h: 0.25, dims: [4; 3] },
        // Unaligned and non-dyadic spacings.
        SolidGrid { origin: [-0.3, -0.05, -0.27], h: 0.1, dims: [16, 14, 15] },
        SolidGrid { origin: [0.05, -0.35, 0.15], h: 0.3, dims: [4, 6, 3] },
        // Clipped by the grid: part of the cube is outside.
        SolidGrid { origin: [0.375, -0.125, 0.5], h: 0.25, dims: [3, 8, 8] },
    ];
    for g in grids {
        let want: u64 = (0..3).map(|a| centres_in(&g, a, 0.0, 1.0)).product();
        let v = voxelise(&m, &g, BIG).unwrap();
        assert_eq!(v.len() as u64, want, "{g:?}");
        assert!(want > 0);
        assert_row_order(&v);
        for (ijk, c) in &v {
            for a in 0..3 {
                assert!((0.0..1.0).contains(&g.centre(a, ijk[a])), "{ijk:?} outside the cube in {g:?}");
            }
            assert_eq!(*c, [1.0; 3]);
        }
        // Inward normals change nothing.
        assert_eq!(voxelise(&flipped, &g, BIG).unwrap(), v, "flipped {g:?}");
    }
}

#[test]
fn an_octahedron_through_lattice_vertices_follows_the_tie_rule_exactly() {
    // |x| + |y| + |z| ≤ 1 on a grid of centres at multiples of 1/4: rays
    // run through its six vertices, along its edges and through faces at
    // lattice points. A centre on the surface is inside exactly when the
    // centre moved by (δ, ε, ε²) is: when x < 0 (the δ term decides).
    let p = vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
    let mut t = Vec::new();
    for (x, sx) in [(0u32, 1.0), (1, -1.0)] {
        for (y, sy) in [(2u32, 1.0), (3, -1.0)] {
            for (z, sz) in [(4u32, 1.0), (5, -1.0)] {
                // Counter-clockwise from outside when sx·sy·sz > 0.
                t.push(if sx * sy * sz > 0.0 { [x, y, z] } else { [x, z, y] });
            }
        }
    }
    let m = tri_mesh(p.clone(), t.clone());
    check_closed(&m).unwrap();
    assert!(signed_volume(&m) > 0.0);
    for (shift, scale) in [(0.0, 1.0), (0.0, 3.0), (0.25, 1.0)] {
        // Also moved and scaled by exact amounts, so every centre stays
        // on the lattice relative to the shape.
        let m = tri_mesh(p.iter().map(|v| v.map(|c| c * scale + shift)).collect(), t.clone());
        let h = 0.25 * scale;
        let g = SolidGrid { origin: [shift - 1.5 * scale - 0.5 * h; 3], h, dims: [13; 3] };
        let v = voxelise(&m, &g, BIG).unwrap();
        let mut want = Vec::new();
        for k in 0..13 {
            for j in 0..13 {
                for i in 0..13 {
                    let c = [i, j, k].map(|n| (g.centre(0, n) - shift) / scale);
                    let f = c[0].abs() + c[1].abs() + c[2].abs();
                    if f < 1.0 || (f == 1.0 && c[0] < 0.0) {
                        want.push([i, j, k]);
                    }
                }
            }
        }
        let got: Vec<[u32; 3]> = v.iter().map(|x| x.0).collect();
        assert_eq!(got, want, "shift {shift} scale {scale}");
        // 63 lattice points with |x|+|y|+|z| < 1, 25 of the 66 on the
        // surface with x < 0.
        assert_eq!(want.len(), 88, "the count the rule gives");
    }
    // Inward normals: the same voxels.
    for tri in &mut t {
        tri.swap(1, 2);
    }
    let g = SolidGrid { origin: [-1.625; 3], h: 0.25, dims: [13; 3] };
    assert_eq!(voxelise(&tri_mesh(p, t), &g, BIG).unwrap().len(), 88);
}

/// Parity of the crossings of the ray from `o` along `d` (Möller–Trumbore,
/// plain f64): right for a generic direction away from the surface.
fn ray_parity(m: &TriMesh, o: [f64; 3], d: [f64; 3]) -> bool {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut odd = false;
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        let (e1, e2) = (sub(b, a), sub(c, a));
        let pv = cross(d, e2);
        let det = dot(e1, pv);
        if det.abs() < 1e-300 {
            continue;
        }
        let tv = sub(o, a);
        let u = dot(tv, pv) / det;
        let qv = cross(tv, e1);
        let v = dot(d, qv) / det;
        let t = dot(e2, qv) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 {
            odd = !odd;
        }
    }
    odd
}

#[test]
fn a_lumpy_mesh_on_the_integer_lattice_has_no_leaking_rows() {
    // An icosphere scaled and rounded to integer vertices, with centres on
    // the integers: rays run through many vertices and along slanted
    // edges. Wherever a point is clearly off the surface (six generic rays
    // agree), the voxeliser must agree with them; a crossing counted twice
    // or missed would flip the rest of its row.
    let s = icosphere(2);
    for scale in [6.0, 7.5] {
        let m = tri_mesh(s.positions.iter().map(|p| p.map(|v| (v * scale).round())).collect(), s.triangles.clone());
        let g = SolidGrid { origin: [-9.5; 3], h: 1.0, dims: [19; 3] };
        let v = voxelise(&m, &g, BIG).unwrap();
        let inside: std::collections::HashSet<[u32; 3]> = v.iter().map(|x| x.0).collect();
        let (r2, r3, r5, r7) = (2f64.sqrt() * 1e-3, 3f64.sqrt() * 1e-3, 5f64.sqrt() * 1e-3, 7f64.sqrt() * 1e-3);
        let dirs = [[1.0, r2, r3], [-1.0, r5, -r7], [r3, 1.0, r5], [-r7, -1.0, r2], [r5, -r2, 1.0], [r2, r7, -1.0]];
        let (mut judged, mut on_surface, mut hits_vertex_row) = (0, 0, 0);
        for k in 0..19 {
            for j in 0..19 {
                let (y, z) = (g.centre(1, j), g.centre(2, k));
                if m.positions.iter().any(|p| p[1] == y && p[2] == z) {
                    hits_vertex_row += 1;
                }
                for i in 0..19 {
                    let o = [g.centre(0, i), y, z];
                    let votes: Vec<bool> = dirs.iter().map(|&d| ray_parity(&m, o, d)).collect();
                    if votes.iter().all(|&x| x == votes[0]) {
                        judged += 1;
                        assert_eq!(inside.contains(&[i, j, k]), votes[0], "scale {scale}: centre {o:?}");
                    } else {
                        on_surface += 1;
                    }
                }
            }
        }
        assert!(judged > 5000 && on_surface > 50 && hits_vertex_row > 20, "{judged} {on_surface} {hits_vertex_row}");
    }
}

// ------------------------------------------------------------ volumes

#[test]
fn a_sphere_fills_its_volume() {
    let dir = tmp();
    let s = icosphere(4);
    assert_eq!(s.triangles.len(), 5120);
    // Through an OBJ file, to read what we voxelise.
    let path = write(dir.path(), "sphere.obj", obj_text(&s.positions, None, &s.triangles).as_bytes());
    let m = read_mesh(&path, &NO_LIMIT).unwrap();
    check_closed(&m).unwrap();
    let poly = signed_volume(&m);
    let ball = 4.0 / 3.0 * std::f64::consts::PI;
    assert!(poly < ball && poly > 0.99 * ball);
    for (h, shift) in [(0.05, 0.0), (0.04, 0.37), (0.1, 0.5)] {
        let g = grid_over(-1.0, 1.0, h, shift);
        let v = voxelise(&m, &g, BIG).unwrap();
        let vol = v.len() as f64 * h * h * h;
        let tol = if h > 0.06 { 0.02 } else { 0.005 };
        assert!((vol / poly - 1.0).abs() < tol, "h {h}: {vol} vs {poly}");
        for (ijk, _) in &v {
            let r2: f64 = (0..3).map(|a| g.centre(a, ijk[a]).powi(2)).sum();
            assert!(r2 <= 1.0 + 1e-12, "{ijk:?} outside the ball");
        }
    }
}

#[test]
fn a_torus_keeps_its_hole_empty() {
    let (big_r, r) = (1.0, 0.35);
    let m = torus(big_r, r, 96, 48);
    let rep = check_closed(&m).unwrap();
    assert_eq!(rep.triangles, 96 * 48 * 2);
    let h = 0.04;
    let g = grid_over(-1.4, 1.4, h, 0.21);
    let v = voxelise(&m, &g, BIG).unwrap();
    let vol = v.len() as f64 * h * h * h;
    let poly = signed_volume(&m).abs();
    assert!((vol / poly - 1.0).abs() < 0.01, "{vol} vs {poly}");
    let exact = 2.0 * std::f64::consts::PI.powi(2) * big_r * r * r;
    assert!((vol / exact - 1.0).abs() < 0.02, "{vol} vs {exact}");
    let mut in_hole = 0;
    for (ijk, _) in &v {
        let c = [0, 1, 2].map(|a| g.centre(a, ijk[a]));
        let d = (c[0] * c[0] + c[1] * c[1]).sqrt();
        // The facets cut a little into the hole (chords of the inner ring).
        assert!(((d - big_r).powi(2) + c[2] * c[2]).sqrt() <= r + 0.002, "{c:?} outside the tube");
        if d < big_r - r - 0.002 {
            in_hole += 1;
        }
    }
    assert_eq!(in_hole, 0);
    // The hole's own rows are crossed four times: a voxel at the centre of
    // the hole is out, one in the tube at the same row is in.
    let at = |x: f64| {
        v.iter().any(|(ijk, _)| (g.centre(0, ijk[0]) - x).abs() < h / 2.0 && g.centre(1, ijk[1]).abs() < h / 2.0 && g.centre(2, ijk[2]).abs() < h / 2.0)
    };
    assert!(!at(0.0) && at(big_r) && at(-big_r));
}

// ------------------------------------------------------------ closedness

#[test]
fn open_flipped_and_non_manifold_meshes_are_refused_with_counts() {
    let (p, t) = cuboid([0.0; 3], [1.0; 3]);
    // Missing a face: its four edges are holes.
    let open = tri_mesh(p.clone(), t[2..].to_vec());
    let mut no_x0 = t.clone();
    no_x0.drain(8..10);
    let open_in_x = tri_mesh(p.clone(), no_x0);
    let defects = |m: &TriMesh| match check_closed(m) {
        Err(MeshError::NotClosed(d)) => *d,
        other => panic!("{other:?}"),
    };
    let d = defects(&open);
    assert_eq!((d.boundary, d.non_manifold, d.inconsistent), (4, 0, 0));
    // The example edge is on the missing face (z = 0).
    let e = d.boundary_at.unwrap();
    assert!(e.iter().all(|q| q[2] == 0.0), "{e:?}");
    assert!(d.non_manifold_at.is_none() && d.inconsistent_at.is_none());
    let msg = check_closed(&open).unwrap_err().to_string();
    assert!(msg.contains("4 boundary edge") && msg.contains("e.g. from ("), "{msg}");
    // The voxeliser refuses to fill rows through a hole facing its rays
    // (one parallel to them is never crossed: the rows still pair up).
    let g = SolidGrid { origin: [-0.1; 3], h: 0.25, dims: [6; 3] };
    assert!(matches!(voxelise(&open_in_x, &g, BIG), Err(MeshError::OddCrossings { .. })));
    assert_eq!(voxelise(&open, &g, BIG).unwrap().len(), 64);

    // One flipped triangle: its three edges run the same way as their twins.
    let mut flipped = t.clone();
    flipped[5].swap(0, 1);
    let d = defects(&tri_mesh(p.clone(), flipped));
    assert_eq!((d.boundary, d.non_manifold, d.inconsistent), (0, 0, 3));
    assert!(d.inconsistent_at.is_some());
    assert!(
        check_closed(&tri_mesh(p.clone(), {
            let mut f = t.clone();
            f[0].swap(1, 2);
            f
        }))
        .unwrap_err()
        .to_string()
        .contains("3 inconsistently oriented")
    );

    // A fin on an edge: three triangles there, and the fin's own edges open.
    let mut pf = p.clone();
    pf.push([0.5, -1.0, -1.0]);
    let mut tf = t.clone();
    tf.push([0, 1, 8]);
    let d = defects(&tri_mesh(pf, tf));
    assert_eq!((d.boundary, d.non_manifold, d.inconsistent), (2, 1, 0));
    assert_eq!(d.non_manifold_at, Some([[0.0; 3], [1.0, 0.0, 0.0]]));
    let msg = MeshError::NotClosed(Box::new(d)).to_string();
    assert!(msg.contains("1 non-manifold edge(s)") && msg.contains("e.g. from (0, 0, 0) to (1, 0, 0)"), "{msg}");

    // Welding and degenerate triangles: the cube with every triangle's
    // own copy of its corners, plus a zero-area sliver and a collapsed one,
    // is still closed.
    let mut sp = Vec::new();
    let mut st = Vec::new();
    for tri in &t {
        let base = sp.len() as u32;
        sp.extend(tri.map(|i| p[i as usize]));
        st.push([base, base + 1, base + 2]);
    }
    sp.push([0.5, 0.0, 0.0]);
    let mid = (sp.len() - 1) as u32;
    // A real extra triangle opens the mesh...
    st.push([0, 1, mid]);
    assert!(check_closed(&tri_mesh(sp.clone(), st.clone())).is_err());
    st.pop();
    // (0,0,0), (1,0,0) are cube corners; (0.5,0,0) lies between them.
    let i0 = sp.iter().position(|q| *q == [0.0, 0.0, 0.0]).unwrap() as u32;
    let i1 = sp.iter().position(|q| *q == [1.0, 0.0, 0.0]).unwrap() as u32;
    st.push([i0, mid, i1]); // zero area
    st.push([i0, i0, i1]); // two equal corners
    sp.push([-0.0, 0.0, 0.0]); // −0 welds with +0
    let neg = (sp.len() - 1) as u32;
    st.push([neg, i0, i1]);
    let r = check_closed(&tri_mesh(sp.clone(), st)).unwrap();
    assert_eq!((r.vertices, r.triangles, r.degenerate_dropped), (9, 12, 3));
    assert_eq!(r.vertices_welded, sp.len() as u64 - 9);
}

// ------------------------------------------------------------ glTF

fn cube_prim(lo: [f64; 3], hi: [f64; 3]) -> Prim {
    let (p, t) = cuboid(lo, hi);
    Prim::triangles(&p, &t)
}

#[test]
fn gltf_colours_factors_and_node_transforms() {
    // Node 0: a unit cube with u8 RGBA vertex colours, factor (0.5, 1,
    // 0.25), translated to x = 10 and scaled by 2: [10, 12] × [0, 2]².
    let mut a = cube_prim([0.0; 3], [1.0; 3]);
    a.colours = Colours::U8Rgba(vec![[255, 51, 102, 7]; 8]);
    a.factor = [0.5, 1.0, 0.25, 0.3];
    // Node 2 (child of node 1, which moves it by y + 5): mirrored in z and
    // moved by z + 3 → [0, 1] × [5, 6] × [2, 3]; no COLOR_0, factor only.
    let mut b = cube_prim([0.0; 3], [1.0; 3]);
    b.factor = [0.2, 0.4, 0.6, 1.0];
    // Node 3: a float-coloured cube turned 90° about z, at x = −4:
    // [−5, −4] × [0, 1] × [0, 1], colour (0.1, 0.2, 0.3).
    let mut c = cube_prim([0.0; 3], [1.0; 3]);
    c.colours = Colours::F32(vec![[0.1, 0.2, 0.3]; 8]);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let nodes = vec![
        NodeSpec { mesh: Some(vec![a]), translation: Some([10.0, 0.0, 0.0]), scale: Some([2.0; 3]), ..Default::default() },
        NodeSpec { translation: Some([0.0, 5.0, 0.0]), children: vec![2], ..Default::default() },
        NodeSpec { mesh: Some(vec![b]), translation: Some([0.0, 0.0, 3.0]), scale: Some([1.0, 1.0, -1.0]), ..Default::default() },
        NodeSpec { mesh: Some(vec![c]), translation: Some([-4.0, 0.0, 0.0]), rotation: Some([0.0, 0.0, s, s]), ..Default::default() },
    ];
    let (root, bin) = gltf_doc(nodes, &[0, 1, 3]);
    let dir = tmp();
    let path = write(dir.path(), "three.glb", &glb(&root, bin.clone()));
    let m = read_mesh(&path, &NO_LIMIT).unwrap();
    assert_eq!((m.positions.len(), m.triangles.len()), (24, 36));
    check_closed(&m).unwrap();

    // Each cube outward: the mirrored one had its winding reversed.
    for part in 0..3 {
        let sub = TriMesh { positions: m.positions.clone(), colours: m.colours.clone(), triangles: m.triangles[12 * part..12 * part + 12].to_vec() };
        assert!(signed_volume(&sub) > 0.0, "cube {part} inside out");
    }

    let ca = [1.0f32 * 0.5, 0.2 * 1.0, 0.4 * 0.25];
    let cb = [0.2f32, 0.4, 0.6];
    let cc = [0.1f32, 0.2, 0.3];
    let g = SolidGrid { origin: [-6.0, -1.0, -1.0], h: 0.5, dims: [40, 16, 10] };
    let v = voxelise(&m, &g, BIG).unwrap();
    assert_row_order(&v);
    let (mut na, mut nb, mut nc) = (0, 0, 0);
    for (ijk, col) in &v {
        let p = [0, 1, 2].map(|a| g.centre(a, ijk[a]));
        let close = |want: [f32; 3]| (0..3).all(|k| (col[k] - want[k]).abs() < 1e-6);
        if p[0] > 9.0 {
            assert!((10.0..12.0).contains(&p[0]) && (0.0..2.0).contains(&p[1]) && (0.0..2.0).contains(&p[2]), "{p:?}");
            assert!(close(ca), "{col:?} vs {ca:?}");
            na += 1;
        } else if p[1] > 4.0 {
            assert!((0.0..1.0).contains(&p[0]) && (5.0..6.0).contains(&p[1]) && (2.0..3.0).contains(&p[2]), "{p:?}");
            assert!(close(cb), "{col:?}");
            nb += 1;
        } else {
            assert!((-5.0..-4.0).contains(&p[0]) && (0.0..1.0).contains(&p[1]) && (0.0..1.0).contains(&p[2]), "{p:?}");
            assert!(close(cc), "{col:?}");
            nc += 1;
        }
    }
    assert_eq!((na, nb, nc), (64, 8, 8));

    // The same document as .gltf, buffer embedded and beside it (with a
    // space in its name): the same mesh.
    let embedded = write(dir.path(), "e.gltf", &gltf_text(&root, format!("data:application/octet-stream;base64,{}", base64(&bin))));
    assert_eq!(read_mesh(&embedded, &NO_LIMIT).unwrap(), m);
    write(dir.path(), "the data.bin", &bin);
    let external = write(dir.path(), "x.GLTF", &gltf_text(&root, "the%20data.bin".into()));
    assert_eq!(read_mesh(&external, &NO_LIMIT).unwrap(), m);
    // A missing .bin names itself.
    let missing = write(dir.path(), "m.gltf", &gltf_text(&root, "gone.bin".into()));
    let e = read_mesh(&missing, &NO_LIMIT).unwrap_err().to_string();
    assert!(e.contains("gone.bin"), "{e}");
}

#[test]
fn gltf_strips_fans_u16_colours_and_refused_modes() {
    // A box [0,1]³ whose four sides are one triangle strip, bottom a fan,
    // top plain triangles without indices: closed only if the strip's and
    // fan's windings are converted as glTF says.
    let (p, _) = cuboid([0.0; 3], [1.0; 3]);
    let pf = |i: usize| p[i].map(|v| v as f32);
    // Around the sides: bottom (z = 0) corners 0, 1, 3, 2 and top 4, 5, 7, 6.
    let ring = [0usize, 1, 3, 2];
    let mut strip = Vec::new();
    for k in 0..=4 {
        strip.push(ring[k % 4] as u32 + 4);
        strip.push(ring[k % 4] as u32);
    }
    let sides = Prim {
        positions: p.iter().map(|q| q.map(|v| v as f32)).collect(),
        colours: Colours::U16Rgba(vec![[65535, 0, 32768, 0]; 8]),
        indices: Some(strip),
        mode: json::mesh::Mode::TriangleStrip,
        factor: [1.0; 4],
    };
    // Bottom seen from below (outside): 0, 2, 3, 1 is counter-clockwise.
    let bottom = Prim {
        positions: p.iter().map(|q| q.map(|v| v as f32)).collect(),
        colours: Colours::None,
        indices: Some(vec![0, 2, 3, 1]),
        mode: json::mesh::Mode::TriangleFan,
        factor: [1.0; 4],
    };
    let top = Prim {
        positions: vec![pf(4), pf(5), pf(7), pf(4), pf(7), pf(6)],
        colours: Colours::None,
        indices: None,
        mode: json::mesh::Mode::Triangles,
        factor: [1.0; 4],
    };
    let (root, bin) = gltf_doc(vec![NodeSpec { mesh: Some(vec![sides, bottom, top]), ..Default::default() }], &[0]);
    let dir = tmp();
    let path = write(dir.path(), "strip.glb", &glb(&root, bin));
    let m = read_mesh(&path, &NO_LIMIT).unwrap();
    assert_eq!(m.triangles.len(), 8 + 2 + 2);
    let r = check_closed(&m).unwrap();
    assert_eq!(r.vertices, 8);
    assert!(signed_volume(&m).abs() > 0.999);
    // The strip's colour: u16 normalized, alpha dropped.
    assert_eq!(m.colours[0], [1.0, 0.0, (32768.0 / 65535.0) as f32]);
    let g = SolidGrid { origin: [-0.125; 3], h: 0.25, dims: [8; 3] };
    assert_eq!(voxelise(&m, &g, BIG).unwrap().len(), 64);

    // Lines and points are refused by name.
    for mode in [json::mesh::Mode::Lines, json::mesh::Mode::Points, json::mesh::Mode::LineStrip] {
        let mut pr = cube_prim([0.0; 3], [1.0; 3]);
        pr.mode = mode;
        let (root, bin) = gltf_doc(vec![NodeSpec { mesh: Some(vec![pr]), ..Default::default() }], &[0]);
        let path = write(dir.path(), "lines.glb", &glb(&root, bin));
        let e = read_mesh(&path, &NO_LIMIT).unwrap_err();
        assert!(matches!(e, MeshError::Unsupported(_)), "{e:?}");
        assert!(e.to_string().contains("triangle meshes only"), "{e}");
    }
}

// ------------------------------------------------------------ OBJ

#[test]
fn obj_vertex_colours_are_srgb_and_the_nearer_crossing_colours_a_voxel() {
    // Black at x = 0, white at x = 1, sRGB 0.5 grey between: faces at x = 0
    // and x = 1 are uniform, so a voxel takes the colour of the nearer one.
    let (p, t) = cuboid([0.0; 3], [1.0; 3]);
    let c: Vec<[f64; 3]> = p.iter().map(|q| if q[0] == 0.0 { [0.0; 3] } else { [1.0, 0.5, 0.25] }).collect();
    let dir = tmp();
    let path = write(dir.path(), "c.obj", obj_text(&p, Some(&c), &t).as_bytes());
    let m = read_mesh(&path, &NO_LIMIT).unwrap();
    let lin = [1.0, srgb_to_linear(0.5) as f32, srgb_to_linear(0.25) as f32];
    for (q, col) in m.positions.iter().zip(&m.colours) {
        assert_eq!(*col, if q[0] == 0.0 { [0.0; 3] } else { lin });
    }
    let g = SolidGrid { origin: [0.0; 3], h: 0.25, dims: [4; 3] };
    let v = voxelise(&m, &g, BIG).unwrap();
    assert_eq!(v.len(), 64);
    for (ijk, col) in &v {
        let want = if ijk[0] < 2 { [0.0; 3] } else { lin };
        assert_eq!(*col, want, "{ijk:?}");
    }
}

#[test]
fn obj_material_kd_colours_its_faces() {
    let dir = tmp();
    write(dir.path(), "m.mtl", b"newmtl red\nKd 1 0 0\nnewmtl grey\nKd 0.5 0.5 0.5\n");
    let (p, t) = cuboid([0.0; 3], [1.0; 3]);
    let (p2, _) = cuboid([2.0, 0.0, 0.0], [3.0, 1.0, 1.0]);
    let mut s = String::from("# two cubes\nmtllib m.mtl\no a\nusemtl red\n");
    for q in p.iter().chain(&p2) {
        s += &format!("v {} {} {}\n", q[0], q[1], q[2]);
    }
    // Quads for the first cube (triangulated on reading), triangles for the
    // second, with texture/normal slots and negative indices.
    s += "vt 0 0\nvn 0 0 1\n";
    for q in [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]] {
        s += &format!("f {}/1/1 {}/1/1 {}/1/1 {}/1/1\n", q[0] + 1, q[1] + 1, q[2] + 1, q[3] + 1);
    }
    s += "o b\nusemtl grey\n";
    for tri in &t {
        s += &format!("f {} {}//1 {}\n", tri[0] as i64 - 8, tri[1] as i64 - 8, tri[2] as i64 - 8);
    }
    let path = write(dir.path(), "two.obj", s.as_bytes());
    let m = read_mesh(&path, &NO_LIMIT).unwrap();
    assert_eq!(m.triangles.len(), 24);
    check_closed(&m).unwrap();
    let grey = srgb_to_linear(0.5) as f32;
    for (q, c) in m.positions.iter().zip(&m.colours) {
        assert_eq!(*c, if q[0] < 1.5 { [1.0, 0.0, 0.0] } else { [grey; 3] }, "{q:?}");
    }
    let g = SolidGrid { origin: [0.0; 3], h: 0.5, dims: [6, 2, 2] };
    let v = voxelise(&m, &g, BIG).unwrap();
    assert_eq!(v.len(), 16);
    assert!(v.iter().all(|(ijk, c)| *c == if ijk[0] < 2 { [1.0, 0.0, 0.0] } else { [grey; 3] }));

    // A missing library and a malformed one are refusals that name it.
    let missing = write(dir.path(), "nomtl.obj", s.replace("m.mtl", "gone.mtl").as_bytes());
    let e = read_mesh(&missing, &NO_LIMIT).unwrap_err().to_string();
    assert!(e.contains("gone.mtl"), "{e}");
    write(dir.path(), "bad.mtl", b"newmtl red\nKd 1\n");
    let bad = write(dir.path(), "badmtl.obj", s.replace("m.mtl", "bad.mtl").as_bytes());
    let e = read_mesh(&bad, &NO_LIMIT).unwrap_err().to_string();
    assert!(e.contains("bad.mtl") && e.contains("three numbers"), "{e}");
}

// ------------------------------------------------------------ our own export

fn painted(name: &str) -> octopaint_tree::paint::Painting {
    struct Silent;
    impl octopaint_tree::replay::ReplayObserver for Silent {}
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"));
    let trace = octopaint_tree::read_trace(&path).expect("a checked-in trace");
    octopaint_tree::replay::replay(&trace, None, &mut Silent).expect("replays").1
}

#[test]
fn our_own_glb_export_reads_back_closed() {
    use octopaint_export::{Placement, SurfaceOptions, default_iso, mesh, surface};
    let p = painted("shapes_modes");
    let iso = default_iso(&p.tree).unwrap();
    let m = surface(&p.tree, SurfaceOptions { iso, depth_cap: p.tree.lat.max_depth, max_triangles: usize::MAX, crop: None }, &mut |_| {}).unwrap();
    assert!(m.triangles.len() > 1000);
    let bytes = mesh::glb_bytes(&m, Placement::default(), "test").unwrap();
    let dir = tmp();
    let path = write(dir.path(), "painting.glb", &bytes);
    let r = read_mesh(&path, &NO_LIMIT).unwrap();

    // What the file holds, read with the gltf crate: node translation plus
    // f32 positions, summed in f64.
    let g = gltf::Gltf::from_slice(&bytes).unwrap();
    let t = g.nodes().next().unwrap().transform().decomposed().0.map(f64::from);
    let prim = g.meshes().next().unwrap().primitives().next().unwrap();
    let rd = prim.reader(|_| g.blob.as_deref());
    let pos: Vec<[f32; 3]> = rd.read_positions().unwrap().collect();
    let col: Vec<[f32; 3]> = rd.read_colors(0).unwrap().into_rgb_f32().collect();
    assert_eq!(r.positions.len(), pos.len());
    assert_eq!(r.triangles, m.triangles);
    for i in 0..pos.len() {
        let want = [0, 1, 2].map(|a| f64::from(pos[i][a]) + t[a]);
        assert_eq!(r.positions[i], want, "vertex {i}");
        assert_eq!(r.colours[i], col[i]);
        let d = (0..3).map(|a| (r.positions[i][a] - m.positions[i][a]).abs()).fold(0.0, f64::max);
        assert!(d < 1e-5, "vertex {i} moved by {d}");
    }

    // Dual marching tetrahedra on a painting inside the canvas is closed;
    // rounding to f32 must not have broken it.
    let rep = check_closed(&r).unwrap();
    assert_eq!(rep.triangles as usize + rep.degenerate_dropped as usize, m.triangles.len());
    // And it voxelises to about its volume.
    let vol = signed_volume(&r);
    assert!(vol > 0.0);
    let lo = (0..3).map(|a| r.positions.iter().map(|q| q[a]).fold(f64::INFINITY, f64::min)).fold(f64::INFINITY, f64::min);
    let hi = (0..3).map(|a| r.positions.iter().map(|q| q[a]).fold(f64::NEG_INFINITY, f64::max)).fold(f64::NEG_INFINITY, f64::max);
    let h = (vol / 200_000.0).cbrt();
    let grid = grid_over(lo, hi, h, 0.3);
    let v = voxelise(&r, &grid, BIG).unwrap();
    let got = v.len() as f64 * h * h * h;
    assert!((got / vol - 1.0).abs() < 0.05, "{got} vs {vol}");
}

// ------------------------------------------------------------ limits, malformed

#[test]
fn triangle_and_voxel_limits_refuse() {
    let dir = tmp();
    let (p, t) = cuboid([0.0; 3], [1.0; 3]);
    let obj = write(dir.path(), "c.obj", obj_text(&p, None, &t).as_bytes());
    let (root, bin) = gltf_doc(vec![NodeSpec { mesh: Some(vec![cube_prim([0.0; 3], [1.0; 3])]), ..Default::default() }], &[0]);
    let glb_path = write(dir.path(), "c.glb", &glb(&root, bin));
    for path in [&obj, &glb_path] {
        assert_eq!(read_mesh(path, &MeshLimits { max_triangles: 12 }).unwrap().triangles.len(), 12);
        match read_mesh(path, &MeshLimits { max_triangles: 11 }) {
            Err(e @ MeshError::TooManyTriangles { max: 11, .. }) => assert!(e.to_string().contains("more than 11 triangles"), "{e}"),
            other => panic!("{path:?}: {other:?}"),
        }
    }
    // A declared count far past the data is refused before it is read.
    let mut big = root.clone();
    big.accessors[1].count = USize64(1 << 40);
    let path = write(dir.path(), "huge.glb", &glb(&big, vec![0; 400]));
    assert!(matches!(read_mesh(&path, &MeshLimits { max_triangles: 1 << 20 }), Err(MeshError::TooManyTriangles { .. })));
    assert!(matches!(read_mesh(&path, &NO_LIMIT), Err(MeshError::Malformed(_))));

    let m = tri_mesh(p, t);
    let g = SolidGrid { origin: [-0.125; 3], h: 0.25, dims: [8; 3] };
    assert_eq!(voxelise(&m, &g, 64).unwrap().len(), 64);
    match voxelise(&m, &g, 63) {
        Err(e @ MeshError::TooManyVoxels { max: 63 }) => assert!(e.to_string().contains("more than 63 voxels")),
        other => panic!("{other:?}"),
    }
    // A bad grid is an error, not a panic.
    for bad in [SolidGrid { h: 0.0, ..g }, SolidGrid { h: f64::NAN, ..g }, SolidGrid { origin: [f64::INFINITY, 0.0, 0.0], ..g }] {
        assert!(matches!(voxelise(&m, &bad, BIG), Err(MeshError::BadGrid(_))));
    }
}

/// Deterministic pseudo-random bytes.
fn noise(seed: u64, n: usize) -> Vec<u8> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 33) as u8
        })
        .collect()
}

#[test]
fn malformed_files_are_errors_not_panics() {
    let dir = tmp();
    let (root, bin) = gltf_doc(vec![NodeSpec { mesh: Some(vec![cube_prim([0.0; 3], [1.0; 3])]), ..Default::default() }], &[0]);
    let good = glb(&root, bin.clone());
    let mut cases: Vec<(&str, Vec<u8>)> = vec![
        ("noise.glb", noise(1, 4096)),
        ("noise.gltf", noise(2, 4096)),
        ("noise.obj", noise(3, 4096)),
        ("empty.glb", Vec::new()),
        ("empty.obj", Vec::new()),
        ("truncated.glb", good[..good.len() / 2].to_vec()),
        ("text.gltf", b"{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 99}}]}]}".to_vec()),
        ("obj_range.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n".to_vec()),
        ("obj_zero.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n".to_vec()),
        // tobj 4.0 panics (overflow) on a texture index like this one.
        ("obj_vt.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/-5 2/1 3/1\n".to_vec()),
        ("obj_line.obj", b"v 0 0 0\nv 1 0 0\nl 1 2\n".to_vec()),
        ("obj_mixed.obj", b"v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec()),
        ("obj_nan.obj", b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec()),
        ("obj_inf.obj", b"v 0 0 0\nv 1e400 0 0\nv 0 1 0\nf 1 2 3\n".to_vec()),
        ("mesh.stl", b"solid x\nendsolid x\n".to_vec()),
    ];
    // Random corruptions of a good file: every byte of the JSON chunk in
    // turn where it parses, and bits anywhere.
    for i in 0..200 {
        let mut b = good.clone();
        let at = (i * 7919) % b.len();
        b[at] ^= 1 << (i % 8);
        cases.push(("flip.glb", b));
    }
    // A NaN position in an otherwise valid file.
    let mut nan_bin = bin.clone();
    nan_bin[..4].copy_from_slice(&f32::NAN.to_le_bytes());
    cases.push(("nan.glb", glb(&root, nan_bin)));
    // Offsets past the buffer, a stride too short.
    let mut off = root.clone();
    off.buffer_views[0].byte_offset = Some(USize64(1 << 20));
    cases.push(("offset.glb", glb(&off, bin.clone())));
    let mut stride = root.clone();
    stride.buffer_views[0].byte_stride = Some(json::buffer::Stride(4));
    cases.push(("stride.glb", glb(&stride, bin.clone())));

    let mut errors = 0;
    for (name, bytes) in &cases {
        let path = write(dir.path(), name, bytes);
        let r = std::panic::catch_unwind(|| read_mesh(&path, &NO_LIMIT));
        match r {
            Ok(Ok(_)) => {
                // A bit flip may land in padding or a value: fine if the
                // result is still a mesh; the named cases must fail.
                assert!(name.starts_with("flip"), "{name} was accepted");
            }
            Ok(Err(e)) => {
                errors += 1;
                assert!(!e.to_string().is_empty());
            }
            Err(_) => panic!("{name} panicked"),
        }
    }
    assert!(errors >= 18, "{errors}");
    let e = read_mesh(&write(dir.path(), "n.obj", b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), &NO_LIMIT).unwrap_err();
    assert!(matches!(e, MeshError::NonFinite { .. }), "{e:?}");
    let e = read_mesh(&write(dir.path(), "nan.glb", &cases.iter().find(|c| c.0 == "nan.glb").unwrap().1), &NO_LIMIT).unwrap_err();
    assert!(matches!(e, MeshError::NonFinite { .. }), "{e:?}");
}

// ------------------------------------------------------------ a big mesh

/// A sphere of 100,488 triangles into 256³ fills the mesh's volume within
/// 0.5 %. It prints how long the closedness check and the voxelising took
/// (the figures docs/documents.md quotes; `-- --nocapture` shows them); no
/// time is asserted.
#[test]
fn a_100k_triangle_sphere_fills_its_volume_in_256_cubed() {
    let m = uv_sphere(159, 1.0);
    assert!(m.triangles.len() > 100_000, "{}", m.triangles.len());
    let t0 = std::time::Instant::now();
    check_closed(&m).unwrap();
    let t1 = std::time::Instant::now();
    let h = 2.0 / 256.0;
    let g = SolidGrid { origin: [-1.0; 3], h, dims: [256; 3] };
    let v = voxelise(&m, &g, BIG).unwrap();
    let t2 = std::time::Instant::now();
    let vol = signed_volume(&m).abs();
    let got = v.len() as f64 * h * h * h;
    println!(
        "{} triangles: check_closed {:.0} ms, voxelise into 256^3 {:.0} ms, {} voxels ({:.4} of the mesh volume)",
        m.triangles.len(),
        (t1 - t0).as_secs_f64() * 1e3,
        (t2 - t1).as_secs_f64() * 1e3,
        v.len(),
        got / vol
    );
    assert!((got / vol - 1.0).abs() < 0.005);
}

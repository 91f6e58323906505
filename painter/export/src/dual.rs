//! An iso-surface of the extinction on the adaptive tree itself, crack-free
//! across depth changes, by marching tetrahedra on the tree's *dual grid*
//! (docs/export.md, "Meshes").
//!
//! The dual grid has a vertex at the centre of every leaf and a (possibly
//! degenerate) hexahedron around every point where leaves meet: its eight
//! corners are the leaves around that point, the same leaf repeated where a
//! coarse leaf covers several octants. The recursive procedures below
//! (cell, face, edge and vertex procedures over the octree, as in Ju et
//! al.'s dual contouring and Schaefer and Warren's dual marching cubes)
//! enumerate each of those hexahedra once, in O(leaves). Two hexahedra that
//! share a face share its four corners, so splitting every hexahedron into
//! the same six tetrahedra around its 0–7 diagonal (the Kuhn split, which
//! cuts every face along the diagonal from its lowest to its highest
//! corner) gives a conforming tetrahedral mesh, and marching tetrahedra on
//! it a closed surface: a vertex is keyed by the two leaves whose centres
//! its edge joins, so neighbours agree on it exactly. No case table is
//! ambiguous on a tetrahedron.
//!
//! The canvas is wrapped in one layer of empty root-sized leaves, so a
//! surface that reaches the canvas's edge is closed there too; the roots
//! hang under virtual nodes (a power-of-two cube of roots) so the same
//! procedures walk across root boundaries.

use std::collections::HashMap;

use glam::DVec3;
use octopaint_tree::pool::{NONE, Tree};

use crate::Crop;
use crate::values::{Value, cell_value, leaf_value};

/// A node of the walk: a tree cell, a virtual node above the roots, a
/// root-sized empty leaf just outside the canvas, or a virtual node that
/// holds nothing but empty space (itself a leaf).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Node {
    Cell(u32),
    /// `level` ≥ 1: a cube of 2^level roots at `at` (in units of its edge)
    /// in padded root coordinates (the canvas's roots are 1..=R).
    Virtual {
        level: u8,
        at: [i32; 3],
    },
    Outside {
        at: [i32; 3],
    },
    Void {
        level: u8,
        at: [i32; 3],
    },
}

/// Per-leaf data the surface needs.
#[derive(Clone, Copy)]
struct Corner {
    key: u64,
    centre: DVec3,
    value: Value,
}

/// A triangle mesh with per-vertex colour, positions in canvas units.
#[derive(Default)]
pub struct Mesh {
    pub positions: Vec<DVec3>,
    /// sRGB-encoded, [0, 1].
    pub colours: Vec<[f64; 3]>,
    /// Counter-clockwise seen from outside (from lower extinction).
    pub triangles: Vec<[u32; 3]>,
}

/// Options of the surface.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceOptions {
    /// Extinction at the surface: leaves at or above it are inside.
    pub iso: f64,
    /// Cells at this depth are treated as leaves (their aggregate value).
    pub depth_cap: u32,
    /// Refuse (return None) past this many triangles.
    pub max_triangles: usize,
    /// Leaves whose centre is outside it count as empty.
    pub crop: Option<Crop>,
}

struct Walk<'a> {
    tree: &'a Tree,
    opts: SurfaceOptions,
    origins: Vec<[u32; 3]>,
    roots: [i32; 3],
    aggregated: HashMap<u32, Value>,
    vertex_of: HashMap<(u64, u64), u32>,
    mesh: Mesh,
    overflow: bool,
    progress_every: usize,
    progress: &'a mut dyn FnMut(usize),
}

/// Kuhn's six tetrahedra of a hexahedron with corners 0..7 (bit a = axis
/// a): 0 → one axis → two axes → 7, for every order of the axes, with the
/// sign of that order (the tetrahedron's orientation in a true cube).
const TETS: [([usize; 4], bool); 6] = [
    ([0, 1, 3, 7], true),  // x, y, z
    ([0, 1, 5, 7], false), // x, z, y
    ([0, 2, 3, 7], false), // y, x, z
    ([0, 2, 6, 7], true),  // y, z, x
    ([0, 4, 5, 7], true),  // z, x, y
    ([0, 4, 6, 7], false), // z, y, x
];

/// Reorderings that put one vertex first and keep the orientation (even
/// permutations).
const LONE_FIRST: [[usize; 4]; 4] = [[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]];

/// Even permutations (i, j, k, l) for each pair {i, j} of inside vertices.
const PAIR_FIRST: [([usize; 2], [usize; 4]); 6] =
    [([0, 1], [0, 1, 2, 3]), ([0, 2], [0, 2, 3, 1]), ([0, 3], [0, 3, 1, 2]), ([1, 2], [1, 2, 0, 3]), ([1, 3], [1, 3, 2, 0]), ([2, 3], [2, 3, 0, 1])];

fn other_axes(a: usize) -> (usize, usize) {
    match a {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

impl<'a> Walk<'a> {
    fn is_leaf(&self, n: Node) -> bool {
        match n {
            Node::Cell(c) => self.tree.first_child()[c as usize] == NONE || u32::from(self.tree.depth()[c as usize]) >= self.opts.depth_cap,
            Node::Virtual { .. } => false,
            Node::Outside { .. } | Node::Void { .. } => true,
        }
    }

    /// Child octant `k` of a node that is not a leaf.
    fn child(&self, n: Node, k: usize) -> Node {
        match n {
            Node::Cell(c) => Node::Cell(self.tree.first_child()[c as usize] + k as u32),
            Node::Virtual { level, at } => {
                let p = [0, 1, 2].map(|a| 2 * at[a] + ((k >> a) & 1) as i32);
                let l = level - 1;
                // Padded roots covered: [p·2^l, (p+1)·2^l).
                let lo = p.map(|v| v << l);
                let hi = p.map(|v| ((v + 1) << l) - 1);
                let touches_shell = (0..3).all(|a| hi[a] >= 0 && lo[a] <= self.roots[a] + 1);
                if !touches_shell {
                    return Node::Void { level: l, at: p };
                }
                if l > 0 {
                    return Node::Virtual { level: l, at: p };
                }
                let inside = (0..3).all(|a| p[a] >= 1 && p[a] <= self.roots[a]);
                if inside {
                    let r = [p[0] - 1, p[1] - 1, p[2] - 1].map(|v| v as u32);
                    Node::Cell(self.tree.lat.root_index(r))
                } else {
                    Node::Outside { at: p }
                }
            }
            Node::Outside { .. } | Node::Void { .. } => n,
        }
    }

    fn sub(&self, n: Node, k: usize) -> Node {
        if self.is_leaf(n) { n } else { self.child(n, k) }
    }

    fn corner(&mut self, n: Node) -> Corner {
        let rs = self.tree.lat.root_size;
        match n {
            Node::Cell(c) => {
                let d = u32::from(self.tree.depth()[c as usize]);
                let value = if self.tree.first_child()[c as usize] == NONE {
                    leaf_value(self.tree, c)
                } else {
                    let tree = self.tree;
                    *self.aggregated.entry(c).or_insert_with(|| cell_value(tree, c))
                };
                let centre = self.tree.lat.centre(self.origins[c as usize], d);
                let value = match self.opts.crop {
                    Some(crop) if !crop.contains(centre) => Value::EMPTY,
                    _ => value,
                };
                Corner { key: u64::from(c), centre, value }
            }
            // Empty space around the canvas stands at its nearest point
            // on the canvas's border, so a surface that reaches the border
            // is closed on it rather than half a root outside.
            Node::Outside { at } | Node::Void { level: 0, at } => {
                Corner { key: (1 << 63) | pack(0, at), centre: self.on_canvas(at.map(|v| (f64::from(v) - 0.5) * rs)), value: Value::EMPTY }
            }
            Node::Void { level, at } => {
                let size = f64::from(1u32 << level);
                Corner {
                    key: (1 << 63) | pack(level, at),
                    centre: self.on_canvas(at.map(|v| (f64::from(v) * size + 0.5 * size - 1.0) * rs)),
                    value: Value::EMPTY,
                }
            }
            Node::Virtual { .. } => unreachable!("a virtual node is never a leaf"),
        }
    }

    /// The point of the canvas nearest to `p` (canvas units).
    fn on_canvas(&self, p: [f64; 3]) -> DVec3 {
        let size = self.tree.lat.roots.map(|r| f64::from(r) * self.tree.lat.root_size);
        DVec3::from_array([0, 1, 2].map(|a| p[a].clamp(0.0, size[a])))
    }

    fn cell_proc(&mut self, n: Node) {
        if self.overflow || self.is_leaf(n) {
            return;
        }
        let ch: [Node; 8] = std::array::from_fn(|k| self.child(n, k));
        for &c in &ch {
            self.cell_proc(c);
        }
        for a in 0..3 {
            for k in 0..8 {
                if k & (1 << a) == 0 {
                    self.face_proc(ch[k], ch[k | (1 << a)], a);
                }
            }
        }
        for a in 0..3 {
            let (u, v) = other_axes(a);
            for s in 0..2 {
                let b = s << a;
                self.edge_proc([ch[b], ch[b | (1 << u)], ch[b | (1 << v)], ch[b | (1 << u) | (1 << v)]], a);
            }
        }
        self.vert_proc(ch);
    }

    /// Two nodes sharing a face normal to axis `a`, n0 on the low side.
    fn face_proc(&mut self, n0: Node, n1: Node, a: usize) {
        if self.overflow || (self.is_leaf(n0) && self.is_leaf(n1)) {
            return;
        }
        let (u, v) = other_axes(a);
        for i in 0..2 {
            for j in 0..2 {
                let q = (i << u) | (j << v);
                self.face_proc(self.sub(n0, q | (1 << a)), self.sub(n1, q), a);
            }
        }
        // The four edges inside the face: two along u, two along v.
        for (d, w) in [(u, v), (v, u)] {
            // Edge along d at the split of w; its nodes are ordered by the
            // other two axes of d (a and w) ascending.
            let (p, q) = other_axes(d);
            for i in 0..2 {
                let nodes: [Node; 4] = std::array::from_fn(|m| {
                    let bits = [(m & 1), (m >> 1) & 1];
                    let bit_of = |axis: usize| if axis == p { bits[0] } else { bits[1] };
                    let (sa, sw) = (bit_of(a), bit_of(w));
                    let oct = (i << d) | (sw << w);
                    if sa == 0 { self.sub(n0, oct | (1 << a)) } else { self.sub(n1, oct) }
                });
                let _ = q;
                self.edge_proc(nodes, d);
            }
        }
        let nodes: [Node; 8] = std::array::from_fn(|k| if k & (1 << a) == 0 { self.sub(n0, k | (1 << a)) } else { self.sub(n1, k & !(1 << a)) });
        self.vert_proc(nodes);
    }

    /// Four nodes around an edge along axis `d`, indexed by their sides on
    /// the other two axes (p, q ascending): index pb + 2·qb.
    fn edge_proc(&mut self, nodes: [Node; 4], d: usize) {
        if self.overflow || nodes.iter().all(|&n| self.is_leaf(n)) {
            return;
        }
        let (p, q) = other_axes(d);
        let toward = |m: usize| ((1 - (m & 1)) << p) | ((1 - ((m >> 1) & 1)) << q);
        for i in 0..2 {
            let sub: [Node; 4] = std::array::from_fn(|m| self.sub(nodes[m], (i << d) | toward(m)));
            self.edge_proc(sub, d);
        }
        let around: [Node; 8] = std::array::from_fn(|k| {
            let m = ((k >> p) & 1) | (((k >> q) & 1) << 1);
            let db = (k >> d) & 1;
            self.sub(nodes[m], (db << d) | toward(m))
        });
        self.vert_proc(around);
    }

    /// Eight nodes around a point, node k on side k of it.
    fn vert_proc(&mut self, nodes: [Node; 8]) {
        if self.overflow {
            return;
        }
        if nodes.iter().all(|&n| self.is_leaf(n)) {
            self.dual_cell(nodes);
            return;
        }
        let sub: [Node; 8] = std::array::from_fn(|k| self.sub(nodes[k], 7 - k));
        self.vert_proc(sub);
    }

    fn vertex(&mut self, a: &Corner, b: &Corner) -> u32 {
        let key = if a.key < b.key { (a.key, b.key) } else { (b.key, a.key) };
        if let Some(&v) = self.vertex_of.get(&key) {
            return v;
        }
        // Interpolate from the lower key so both sides compute the same bits.
        let (a, b) = if a.key < b.key { (a, b) } else { (b, a) };
        let t = ((self.opts.iso - a.value.sigma) / (b.value.sigma - a.value.sigma)).clamp(0.0, 1.0);
        let p = a.centre + (b.centre - a.centre) * t;
        let c = [0, 1, 2].map(|i| a.value.rgb[i] + (b.value.rgb[i] - a.value.rgb[i]) * t);
        let v = self.mesh.positions.len() as u32;
        self.mesh.positions.push(p);
        self.mesh.colours.push(c);
        self.vertex_of.insert(key, v);
        v
    }

    fn triangle(&mut self, t: [u32; 3]) {
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            return; // a tetrahedron with a repeated corner: nothing there
        }
        self.mesh.triangles.push(t);
        if self.mesh.triangles.len() > self.opts.max_triangles {
            self.overflow = true;
        }
        if self.mesh.triangles.len().is_multiple_of(self.progress_every) {
            (self.progress)(self.mesh.triangles.len());
        }
    }

    fn dual_cell(&mut self, nodes: [Node; 8]) {
        let corners: [Corner; 8] = std::array::from_fn(|k| self.corner(nodes[k]));
        let iso = self.opts.iso;
        let inside: [bool; 8] = corners.map(|c| c.value.sigma >= iso);
        if inside.iter().all(|&b| b) || inside.iter().all(|&b| !b) {
            return;
        }
        for (tet, positive) in TETS {
            let ins: Vec<usize> = (0..4).filter(|&i| inside[tet[i]]).collect();
            match ins.len() {
                1 | 3 => {
                    let lone = if ins.len() == 1 { ins[0] } else { (0..4).find(|i| !ins.contains(i)).expect("one outside") };
                    let o = LONE_FIRST[lone].map(|i| tet[i]);
                    let e = [1, 2, 3].map(|j| self.vertex(&corners[o[0]], &corners[o[j]]));
                    // Facing away from the lone corner in a positive tet.
                    let away_is_out = ins.len() == 1;
                    if positive == away_is_out { self.triangle(e) } else { self.triangle([e[0], e[2], e[1]]) }
                }
                2 => {
                    let (_, ord) = PAIR_FIRST.iter().find(|(pair, _)| pair[0] == ins[0] && pair[1] == ins[1]).expect("a pair");
                    let o = ord.map(|i| tet[i]);
                    let (i, j, k, l) = (&corners[o[0]], &corners[o[1]], &corners[o[2]], &corners[o[3]]);
                    let q = [self.vertex(i, k), self.vertex(i, l), self.vertex(j, l), self.vertex(j, k)];
                    if positive {
                        self.triangle([q[0], q[1], q[2]]);
                        self.triangle([q[0], q[2], q[3]]);
                    } else {
                        self.triangle([q[0], q[2], q[1]]);
                        self.triangle([q[0], q[3], q[2]]);
                    }
                }
                _ => {}
            }
        }
    }
}

fn pack(level: u8, at: [i32; 3]) -> u64 {
    // Padded root coordinates are in [-1, 2^17]: 20 bits each with an
    // offset; level below 32.
    let f = |v: i32| (v + 2) as u64 & 0xF_FFFF;
    (u64::from(level) << 60) | (f(at[0]) << 40) | (f(at[1]) << 20) | f(at[2])
}

/// The iso-surface `sigma = opts.iso` of `tree`, or None when it would
/// have more than `opts.max_triangles` triangles.
pub fn surface(tree: &Tree, opts: SurfaceOptions, progress: &mut dyn FnMut(usize)) -> Option<Mesh> {
    let roots = tree.lat.roots.map(|r| r as i32);
    let need = roots.iter().map(|&r| r + 2).max().expect("three axes");
    let mut level = 1u8;
    while (1i32 << level) < need {
        level += 1;
    }
    let mut w = Walk {
        tree,
        opts,
        origins: octopaint_tree::dump::origins(tree),
        roots,
        aggregated: HashMap::new(),
        vertex_of: HashMap::new(),
        mesh: Mesh::default(),
        overflow: false,
        progress_every: 1 << 16,
        progress,
    };
    w.cell_proc(Node::Virtual { level, at: [0; 3] });
    if w.overflow {
        return None;
    }
    let n = w.mesh.triangles.len();
    (w.progress)(n);
    Some(w.mesh)
}

/// The default iso value: half the median extinction of the non-empty
/// leaves, so that the surface wraps the strokes a painting is made of
/// rather than faint haze (a median over leaves counts fine strokes, which
/// have many leaves, more than large thin volumes).
pub fn default_iso(tree: &Tree) -> Option<f64> {
    let mut s: Vec<f32> = (0..tree.n_used() as usize)
        .filter(|&c| tree.depth()[c] != octopaint_tree::pool::FREE && tree.first_child()[c] == NONE && tree.sigma()[c] > 0.0)
        .map(|c| tree.sigma()[c])
        .collect();
    if s.is_empty() {
        return None;
    }
    let mid = s.len() / 2;
    let (_, m, _) = s.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    Some(0.5 * f64::from(*m))
}

//! A closed triangle mesh ([`TriMesh`], from [`crate::mesh_read`]) as
//! solid voxels: the closedness check and the inside test that `octopaint
//! import-mesh` paints from.
//!
//! Inside/outside is decided by ray parity along +x, one ray per row of
//! voxel centres: a centre is inside when an odd number of surface
//! crossings lie at or before it on its row. Triangles are swept in z and
//! binned by the rows their y/z bounding box spans, so the work is about
//! Σ(rows a triangle spans) + (voxels written), never voxels × triangles.
//!
//! Exactness. A ray through a vertex or along an edge must still count
//! every crossing of the surface exactly once, or a whole row leaks. Each
//! centre is treated as if moved by (δ, ε, ε²) in (x, y, z), infinitely
//! little with δ ≫ ε ≫ ε² > 0 (Simulation of Simplicity, Edelsbrunner and
//! Mücke 1990): the moved ray passes through no vertex and along no edge,
//! so whether a triangle's y/z projection contains it is a sign question
//! with no ties, decided by an exact 2D orientation predicate (Shewchuk's
//! filter with an exact expansion fallback) and, where that is zero, by
//! the signs of the perturbation terms (exact comparisons). Triangles
//! with a zero-area projection (parallel to x) never count. The x shift δ
//! makes "crossing at the centre" count as "before it": a face lying on a
//! plane of voxel centres keeps the centres on its low side of x, and the
//! ε terms do the same in y and z, so a box `[lo, hi]` fills exactly the
//! centres in `[lo, hi)` on every axis. For a closed mesh every row then
//! has an even number of crossings; an odd count (an open mesh) is
//! refused rather than filled to the grid's end.
//!
//! The x of a crossing is computed in f64 (exactly for axis-aligned faces
//! and for small dyadic coordinates); rounding there can move only voxels
//! whose centre is within rounding of the surface, never a whole row.
//!
//! The predicates are exact for coordinates up to ±1e150 in magnitude
//! (larger ones are refused); products that underflow (coordinates below
//! about 1e-150 in magnitude, other than zero) may lose exactness.

use std::collections::HashMap;

use crate::mesh_read::TriMesh;
pub use crate::mesh_read::{EdgeDefects, MeshError};

/// An inside voxel: its (i, j, k) and its linear RGB colour.
pub type InsideVoxel = ([u32; 3], [f32; 3]);

/// Coordinates beyond this (in magnitude) are refused: the exact
/// predicates need their products to stay finite.
const MAX_ABS: f64 = 1e150;

/// A box of voxels: voxel (i, j, k) covers `origin + [i, i + 1)·h` on x
/// (j on y, k on z), its centre is `origin + (i + 0.5)·h`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolidGrid {
    pub origin: [f64; 3],
    pub h: f64,
    pub dims: [u32; 3],
}

impl SolidGrid {
    /// The centre of voxel `i` on `axis`, computed the one way every test
    /// here uses.
    pub fn centre(&self, axis: usize, i: u32) -> f64 {
        self.origin[axis] + (f64::from(i) + 0.5) * self.h
    }

    /// How many voxel centres on `axis` lie strictly below `v` (the first
    /// index whose centre is ≥ v), in [0, dims].
    fn centres_below(&self, axis: usize, v: f64) -> u32 {
        let n = self.dims[axis];
        // An estimate (saturating cast; NaN gives 0), then exact steps.
        let mut i = ((v - self.origin[axis]) / self.h - 0.5).ceil().clamp(0.0, f64::from(n)) as u32;
        while i > 0 && self.centre(axis, i - 1) >= v {
            i -= 1;
        }
        while i < n && self.centre(axis, i) < v {
            i += 1;
        }
        i
    }

    /// How many voxel centres on `axis` lie at or below `v`, in [0, dims].
    fn centres_at_or_below(&self, axis: usize, v: f64) -> u32 {
        let n = self.dims[axis];
        let mut i = ((v - self.origin[axis]) / self.h + 0.5).floor().clamp(0.0, f64::from(n)) as u32;
        while i > 0 && self.centre(axis, i - 1) > v {
            i -= 1;
        }
        while i < n && self.centre(axis, i) <= v {
            i += 1;
        }
        i
    }

    fn validate(&self) -> Result<(), MeshError> {
        if !(self.h.is_finite() && self.h > 0.0) {
            return Err(MeshError::BadGrid(format!("the voxel size {} is not a positive number", self.h)));
        }
        for a in 0..3 {
            let lo = self.origin[a];
            let hi = lo + f64::from(self.dims[a]) * self.h;
            if !(lo.is_finite() && hi.is_finite()) {
                return Err(MeshError::BadGrid("its origin or extent is not finite".into()));
            }
            // Neighbouring centres must differ for the half-open rule to
            // mean anything: the voxel size must not vanish against the
            // coordinates.
            if self.h < 1e-12 * lo.abs().max(hi.abs()) {
                return Err(MeshError::BadGrid(format!("the voxel size {} is too small for coordinates near {}", self.h, lo.abs().max(hi.abs()))));
            }
        }
        Ok(())
    }
}

/// What [`check_closed`] found on a closed mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClosedReport {
    /// Distinct positions after welding.
    pub vertices: u64,
    /// Vertices merged into an earlier one with the same position.
    pub vertices_welded: u64,
    /// Triangles kept (after dropping the degenerate ones).
    pub triangles: u64,
    /// Triangles dropped: two corners at one position, or zero area.
    pub degenerate_dropped: u64,
}

/// Checks that `mesh` bounds a solid: after welding vertices with
/// bit-identical positions (−0 and +0 are one) and dropping degenerate
/// triangles (two corners welded together, or exactly zero area), every
/// undirected edge must be used by exactly two triangles, in opposite
/// directions. Otherwise the error counts the boundary edges (holes),
/// non-manifold edges (three or more triangles) and inconsistently
/// oriented edges (two triangles, same direction: a flipped triangle),
/// and gives one edge of each kind by its end points.
///
/// Whether the normals point in or out does not matter (the voxeliser
/// does not use them).
pub fn check_closed(mesh: &TriMesh) -> Result<ClosedReport, MeshError> {
    check_indices(mesh)?;
    check_positions(mesh)?;
    // Weld: one representative vertex per bit pattern.
    let mut by_bits: HashMap<[u64; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    let mut canon = Vec::with_capacity(mesh.positions.len());
    for (i, p) in mesh.positions.iter().enumerate() {
        // x + 0.0 turns −0 into +0 and changes nothing else.
        let key = p.map(|v| (v + 0.0).to_bits());
        canon.push(*by_bits.entry(key).or_insert(i as u32));
    }
    let vertices = by_bits.len() as u64;
    drop(by_bits);

    // Per undirected edge (lo, hi): how many triangles use it, and how
    // many of those run lo → hi.
    let mut edges: HashMap<(u32, u32), (u32, u32)> = HashMap::with_capacity(mesh.triangles.len() * 3 / 2 + 1);
    let (mut kept, mut dropped) = (0u64, 0u64);
    for t in &mesh.triangles {
        let w = t.map(|i| canon[i as usize]);
        if w[0] == w[1] || w[1] == w[2] || w[2] == w[0] || zero_area(w.map(|i| mesh.positions[i as usize])) {
            dropped += 1;
            continue;
        }
        kept += 1;
        for e in 0..3 {
            let (a, b) = (w[e], w[(e + 1) % 3]);
            let entry = edges.entry((a.min(b), a.max(b))).or_insert((0, 0));
            entry.0 += 1;
            if a < b {
                entry.1 += 1;
            }
        }
    }
    if kept == 0 {
        return Err(MeshError::NoTriangles);
    }

    let (mut boundary, mut non_manifold, mut inconsistent) = (0u64, 0u64, 0u64);
    let (mut boundary_at, mut non_manifold_at, mut inconsistent_at) = (None, None, None);
    let at = |(a, b): (u32, u32)| Some([mesh.positions[a as usize], mesh.positions[b as usize]]);
    // Sorted, so that the example edges are the same from run to run.
    let mut sorted: Vec<_> = edges.into_iter().collect();
    sorted.sort_unstable_by_key(|&(e, _)| e);
    for (e, (uses, forward)) in sorted {
        match uses {
            1 => {
                boundary += 1;
                boundary_at = boundary_at.or(at(e));
            }
            2 if forward != 1 => {
                inconsistent += 1;
                inconsistent_at = inconsistent_at.or(at(e));
            }
            2 => {}
            _ => {
                non_manifold += 1;
                non_manifold_at = non_manifold_at.or(at(e));
            }
        }
    }
    if boundary + non_manifold + inconsistent > 0 {
        return Err(MeshError::NotClosed(Box::new(EdgeDefects { boundary, non_manifold, inconsistent, boundary_at, non_manifold_at, inconsistent_at })));
    }
    Ok(ClosedReport { vertices, vertices_welded: mesh.positions.len() as u64 - vertices, triangles: kept, degenerate_dropped: dropped })
}

/// Whether a triangle has exactly zero area: all three coordinate-plane
/// projections have zero signed area (exact).
fn zero_area([a, b, c]: [[f64; 3]; 3]) -> bool {
    [(0, 1), (1, 2), (2, 0)].iter().all(|&(u, v)| orient2d_sign([a[u], a[v]], [b[u], b[v]], [c[u], c[v]]) == 0)
}

fn check_indices(mesh: &TriMesh) -> Result<(), MeshError> {
    let n = mesh.positions.len();
    // Vertex and triangle numbers are kept in u32 here.
    if n > u32::MAX as usize || mesh.triangles.len() > u32::MAX as usize {
        return Err(MeshError::Unsupported("the mesh has more than 4 billion vertices or triangles".into()));
    }
    if mesh.colours.len() != n {
        return Err(MeshError::Malformed(format!("the mesh has {} colours for {n} vertices", mesh.colours.len())));
    }
    if let Some(t) = mesh.triangles.iter().find(|t| t.iter().any(|&i| i as usize >= n)) {
        return Err(MeshError::Malformed(format!("triangle {t:?} refers past the {n} vertices")));
    }
    Ok(())
}

fn check_positions(mesh: &TriMesh) -> Result<(), MeshError> {
    for (i, p) in mesh.positions.iter().enumerate() {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(MeshError::NonFinite { what: "the mesh".into(), vertex: i as u64, position: *p });
        }
        if p.iter().any(|v| v.abs() > MAX_ABS) {
            return Err(MeshError::Unsupported(format!("vertex {i} is at {p:?}, beyond ±1e150: scale the mesh down")));
        }
    }
    Ok(())
}

/// A triangle ready for the row sweep.
struct Prepared {
    tri: u32,
    /// Rows it may cross: j in [j0, j1), k in [k0, k1).
    j0: u32,
    j1: u32,
    k0: u32,
    k1: u32,
    /// Orientation of its y/z projection: +1 or −1 (never 0).
    sign: i8,
}

/// A surface crossing on one row.
#[derive(Clone, Copy)]
struct Crossing {
    x: f64,
    colour: [f32; 3],
    /// Breaks ties in x so the output does not depend on sort internals.
    tri: u32,
}

/// The voxels of `grid` whose centres are inside `mesh`, with their linear
/// colour, in (z, y, x) row order: sorted by k, then j, then i.
///
/// A voxel's colour is the vertex colour interpolated (barycentrically)
/// at the nearer of the two surface crossings that bound its inside
/// interval along x, ties going to the lower one: the colour of the
/// surface it is closest to along its row, a cheap stand-in for "nearest
/// surface point" that keeps a painted skin's colour on the skin's voxels.
///
/// The mesh should have passed [`check_closed`]; a row with an odd number
/// of crossings (an open mesh) is an error. Voxels outside the grid are
/// clipped. More than `max_voxels` inside voxels is an error, raised
/// before more than `max_voxels` are stored.
pub fn voxelise(mesh: &TriMesh, grid: &SolidGrid, max_voxels: u64) -> Result<Vec<InsideVoxel>, MeshError> {
    grid.validate()?;
    check_indices(mesh)?;
    check_positions(mesh)?;
    let yz = |i: u32| {
        let p = mesh.positions[i as usize];
        [p[1], p[2]]
    };

    // Each triangle with its rows, sorted by its first z row.
    let mut prepared: Vec<Prepared> = Vec::new();
    for (n, t) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = t.map(yz);
        let sign = orient2d_sign(a, b, c);
        if sign == 0 {
            // Parallel to x (or degenerate): the moved rays never cross it.
            continue;
        }
        let (ylo, yhi) = (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]));
        let (zlo, zhi) = (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]));
        // Rows whose centre lies in the closed box; the predicate decides
        // the ones on its edges.
        let (j0, j1) = (grid.centres_below(1, ylo), grid.centres_at_or_below(1, yhi));
        let (k0, k1) = (grid.centres_below(2, zlo), grid.centres_at_or_below(2, zhi));
        if j0 < j1 && k0 < k1 {
            prepared.push(Prepared { tri: n as u32, j0, j1, k0, k1, sign });
        }
    }
    prepared.sort_unstable_by_key(|p| (p.k0, p.tri));

    let mut out: Vec<InsideVoxel> = Vec::new();
    let mut active: Vec<usize> = Vec::new();
    // (j << 32 | index into `prepared`) for the active triangles' rows.
    let mut entries: Vec<u64> = Vec::new();
    let mut crossings: Vec<Crossing> = Vec::new();
    let mut next = 0usize;
    let mut k = 0u32;
    loop {
        if active.is_empty() {
            // Skip the z rows no triangle reaches.
            match prepared.get(next) {
                Some(p) => k = k.max(p.k0),
                None => break,
            }
        }
        if k >= grid.dims[2] {
            break;
        }
        while next < prepared.len() && prepared[next].k0 <= k {
            active.push(next);
            next += 1;
        }
        active.retain(|&p| prepared[p].k1 > k);
        entries.clear();
        for &p in &active {
            let pr = &prepared[p];
            entries.extend((pr.j0..pr.j1).map(|j| (u64::from(j) << 32) | p as u64));
        }
        entries.sort_unstable();

        let zc = grid.centre(2, k);
        let mut e = 0;
        while e < entries.len() {
            let j = (entries[e] >> 32) as u32;
            let yc = grid.centre(1, j);
            crossings.clear();
            while e < entries.len() && (entries[e] >> 32) as u32 == j {
                let pr = &prepared[(entries[e] & 0xffff_ffff) as usize];
                e += 1;
                let t = mesh.triangles[pr.tri as usize];
                let [a, b, c] = t.map(yz);
                let p = [yc, zc];
                if side(a, b, p) == pr.sign && side(b, c, p) == pr.sign && side(c, a, p) == pr.sign {
                    crossings.push(crossing(mesh, t, p, pr.tri));
                }
            }
            if crossings.len() % 2 == 1 {
                return Err(MeshError::OddCrossings { y: yc, z: zc });
            }
            crossings.sort_unstable_by(|u, v| u.x.total_cmp(&v.x).then(u.tri.cmp(&v.tri)));
            for pair in crossings.chunks_exact(2) {
                let (lo, hi) = (pair[0], pair[1]);
                // Centres c with lo.x ≤ c < hi.x have one crossing at or
                // before them: inside.
                let (i0, i1) = (grid.centres_below(0, lo.x), grid.centres_below(0, hi.x));
                if i0 >= i1 {
                    continue;
                }
                let run = u64::from(i1 - i0);
                let len = out.len() as u64;
                if len + run > max_voxels {
                    return Err(MeshError::TooManyVoxels { max: max_voxels });
                }
                // Grow geometrically, but never past the cap.
                if out.capacity() < out.len() + run as usize {
                    let want = (len + run.max(len).max(4096)).min(max_voxels).max(len + run);
                    out.reserve_exact((want - len) as usize);
                }
                for i in i0..i1 {
                    let xc = grid.centre(0, i);
                    let colour = if xc - lo.x <= hi.x - xc { lo.colour } else { hi.colour };
                    out.push(([i, j, k], colour));
                }
            }
        }
        k += 1;
    }
    Ok(out)
}

/// Where the row through `p` = (y, z) crosses triangle `t` (whose
/// projection contains the moved `p`), and the colour there. Barycentric
/// weights in f64, clamped to the triangle (the exact point may sit on
/// its edge), so x stays within the triangle's x range.
fn crossing(mesh: &TriMesh, t: [u32; 3], p: [f64; 2], tri: u32) -> Crossing {
    let v = t.map(|i| mesh.positions[i as usize]);
    let q = v.map(|a| [a[1], a[2]]);
    let area = orient2d_fast(q[0], q[1], q[2]);
    let mut w = [orient2d_fast(q[1], q[2], p), orient2d_fast(q[2], q[0], p), orient2d_fast(q[0], q[1], p)];
    // Same sign as the area inside; rounding may flip a tiny one.
    for x in &mut w {
        *x = if area < 0.0 { (-*x).max(0.0) } else { x.max(0.0) };
    }
    let sum = w[0] + w[1] + w[2];
    if !(sum > 0.0 && sum.is_finite()) {
        w = [1.0; 3];
    }
    let sum = w[0] + w[1] + w[2];
    let (xs, cs) = (v.map(|a| a[0]), t.map(|i| mesh.colours[i as usize]));
    let x = if xs[0] == xs[1] && xs[1] == xs[2] {
        // A face on a plane of constant x: exactly that plane.
        xs[0]
    } else {
        let x = (w[0] * xs[0] + w[1] * xs[1] + w[2] * xs[2]) / sum;
        x.clamp(xs[0].min(xs[1]).min(xs[2]), xs[0].max(xs[1]).max(xs[2]))
    };
    let colour = [0, 1, 2].map(|a| ((w[0] * f64::from(cs[0][a]) + w[1] * f64::from(cs[1][a]) + w[2] * f64::from(cs[2][a])) / sum) as f32);
    Crossing { x, colour, tri }
}

/// Which side of the directed edge a → b (in the y/z plane) the moved
/// point p + (ε, ε²) lies on: +1 left, −1 right, never 0 unless a = b.
/// The orientation of (a, b, p + (ε, ε²)) is
/// orient(a, b, p) − ε·(b.z − a.z) + ε²·(b.y − a.y): its sign is that of
/// the first nonzero term.
fn side(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> i8 {
    let o = orient2d_sign(a, b, p);
    if o != 0 {
        return o;
    }
    // Exact: comparing two doubles.
    if b[1] != a[1] {
        return if b[1] > a[1] { -1 } else { 1 };
    }
    if b[0] != a[0] {
        return if b[0] > a[0] { 1 } else { -1 };
    }
    0
}

/// (b − a) × (c − a) in plain f64 (for weights, not for signs).
fn orient2d_fast(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// The exact sign of (b − a) × (c − a): +1 if a, b, c turn left
/// (counter-clockwise), −1 right, 0 collinear. Shewchuk's orient2d
/// ("Adaptive Precision Floating-Point Arithmetic and Fast Robust
/// Geometric Predicates", 1997): a floating-point filter with his error
/// bound, then, when the filter cannot tell, the determinant summed
/// exactly as an expansion of the twelve halves of its six exact products.
pub(crate) fn orient2d_sign(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> i8 {
    let detleft = (a[0] - c[0]) * (b[1] - c[1]);
    let detright = (a[1] - c[1]) * (b[0] - c[0]);
    let det = detleft - detright;
    let detsum = if detleft > 0.0 {
        if detright <= 0.0 {
            return sign(det);
        }
        detleft + detright
    } else if detleft < 0.0 {
        if detright >= 0.0 {
            return sign(det);
        }
        -detleft - detright
    } else {
        return sign(det);
    };
    // ccwerrboundA = (3 + 16ε)ε with ε = 2^-53.
    const EPS: f64 = f64::EPSILON * 0.5;
    const BOUND: f64 = (3.0 + 16.0 * EPS) * EPS;
    if det.abs() > BOUND * detsum {
        return sign(det);
    }
    orient2d_exact(a, b, c)
}

fn sign(v: f64) -> i8 {
    if v > 0.0 {
        1
    } else if v < 0.0 {
        -1
    } else {
        0
    }
}

/// det = ax·by − ax·cy − cx·by − ay·bx + ay·cx + cy·bx, each product split
/// exactly into p + e (fused multiply-add), all twelve summed into a
/// nonoverlapping expansion (Shewchuk's Grow-Expansion), whose most
/// significant nonzero component has the sign of the sum.
fn orient2d_exact(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> i8 {
    let products = [(a[0], b[1], 1.0), (a[0], c[1], -1.0), (c[0], b[1], -1.0), (a[1], b[0], -1.0), (a[1], c[0], 1.0), (c[1], b[0], 1.0)];
    let mut expansion = [0.0f64; 12];
    let mut len = 0;
    for (x, y, s) in products {
        let p = x * y;
        let e = x.mul_add(y, -p);
        for v in [s * e, s * p] {
            // Grow-Expansion: add v to the expansion, keeping it
            // nonoverlapping and in increasing magnitude.
            let mut q = v;
            for item in expansion.iter_mut().take(len) {
                let (s, h) = two_sum(q, *item);
                *item = h;
                q = s;
            }
            expansion[len] = q;
            len += 1;
        }
    }
    expansion[..len].iter().rev().find(|&&v| v != 0.0).map_or(0, |&v| sign(v))
}

/// s + e = a + b exactly (Knuth's TwoSum).
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orient2d_is_exact_where_floats_round() {
        // Points on the line y = x, nudged by one ulp: the naive formula
        // rounds these to zero or the wrong sign; the exact one may not.
        let a = [0.5, 0.5];
        let b = [12.0, 12.0];
        let ulp = f64::EPSILON * 0.5;
        for (c, want) in [([24.0, 24.0], 0), ([0.5 + ulp, 0.5], -1), ([0.5, 0.5 + ulp], 1)] {
            assert_eq!(orient2d_sign(a, b, c), want, "{c:?}");
        }
        // Shewchuk's classic failure: a grid of points near a line.
        let (p, q) = ([12.0, 12.0], [24.0, 24.0]);
        for i in 0..64 {
            for j in 0..64 {
                let r = [0.5 + f64::from(i) * ulp, 0.5 + f64::from(j) * ulp];
                let want = match i.cmp(&j) {
                    std::cmp::Ordering::Less => 1,
                    std::cmp::Ordering::Equal => 0,
                    std::cmp::Ordering::Greater => -1,
                };
                assert_eq!(orient2d_sign(r, p, q), want, "{i} {j}");
            }
        }
    }

    #[test]
    fn half_open_centre_counts() {
        let g = SolidGrid { origin: [-0.125; 3], h: 0.25, dims: [8; 3] };
        assert_eq!(g.centre(0, 0), 0.0);
        assert_eq!(g.centres_below(0, 0.0), 0);
        assert_eq!(g.centres_at_or_below(0, 0.0), 1);
        assert_eq!(g.centres_below(0, 1.0), 4);
        assert_eq!(g.centres_at_or_below(0, 1.0), 5);
        assert_eq!(g.centres_below(0, -5.0), 0);
        assert_eq!(g.centres_below(0, 50.0), 8);
        assert_eq!(g.centres_at_or_below(0, f64::NAN), 0);
    }
}

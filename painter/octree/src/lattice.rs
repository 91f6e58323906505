//! The canvas geometry (spec 1): the root array, the integer lattice of the
//! finest depth, and canvas units. Everything here is exact: lattice
//! coordinates are integers and every per-depth length is a power of two
//! times `root_size`.

use glam::DVec3;

use octopaint_model::Canvas;

/// Deepest `max_depth` a canvas may have (spec 1.2).
pub const DEPTH_LIMIT: u32 = 28;

/// Faces in the normative order of spec 3.2: (axis, sign) for −x, +x, −y,
/// +y, −z, +z.
pub const FACES: [(usize, i32); 6] = [(0, -1), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1)];

#[derive(Clone, Debug)]
pub struct Lattice {
    pub roots: [u32; 3],
    pub max_depth: u32,
    pub root_size: f64,
    pub n_roots: u32,
    /// `n_roots` rounded up to a unit: the used length of a new tree (P).
    pub padded: u32,
    /// Canvas units per lattice unit: `root_size · 2^-D`, exact.
    pub lattice_unit: f64,
    /// Lattice units per axis, `R_a · 2^D` (may equal 2^32).
    pub extent: [u64; 3],
    /// Per depth: half an edge in lattice units, `2^(D-d) · 0.5`.
    pub half_lattice: [f64; DEPTH_LIMIT as usize + 1],
    /// Per depth: the edge in canvas units, `2^(D-d) · lattice_unit`.
    pub size_canvas: [f64; DEPTH_LIMIT as usize + 1],
    /// Per depth: the reach radius `HALF_DIAG · (size_canvas[d] −
    /// size_canvas[D])`, the farthest any centre of a cell inside the cell
    /// (the cell's own, its descendants') lies from its centre (spec 8.7).
    pub reach_radius: [f64; DEPTH_LIMIT as usize + 1],
}

/// `2^e` for small integer `e`, exactly.
fn exp2i(e: i32) -> f64 {
    f64::from_bits(((1023 + e) as u64) << 52)
}

impl Lattice {
    pub fn new(c: &Canvas) -> Self {
        let d = c.max_depth;
        let n_roots = c.roots[0] * c.roots[1] * c.roots[2];
        let lattice_unit = c.root_size * exp2i(-(d as i32));
        let mut half_lattice = [0.0; DEPTH_LIMIT as usize + 1];
        let mut size_canvas = [0.0; DEPTH_LIMIT as usize + 1];
        for depth in 0..=d {
            let edge = exp2i((d - depth) as i32);
            half_lattice[depth as usize] = edge * 0.5;
            size_canvas[depth as usize] = edge * lattice_unit;
        }
        let mut reach_radius = [0.0; DEPTH_LIMIT as usize + 1];
        for depth in 0..=d as usize {
            reach_radius[depth] = octopaint_model::HALF_DIAG * (size_canvas[depth] - size_canvas[d as usize]);
        }
        Lattice {
            roots: c.roots,
            max_depth: d,
            root_size: c.root_size,
            n_roots,
            padded: n_roots.div_ceil(8) * 8,
            lattice_unit,
            extent: c.roots.map(|r| u64::from(r) << d),
            half_lattice,
            size_canvas,
            reach_radius,
        }
    }

    /// Edge of a cell of depth `d` in lattice units.
    #[inline]
    pub fn edge_lattice(&self, d: u32) -> u32 {
        // 2^(D-d) <= 2^28 always fits.
        1u32 << (self.max_depth - d)
    }

    /// Centre of a cell in canvas units: `(origin + half) · lattice_unit`
    /// (spec 1.3: the sum is exact, the product rounds once).
    #[inline]
    pub fn centre(&self, origin: [u32; 3], depth: u32) -> DVec3 {
        let h = self.half_lattice[depth as usize];
        DVec3::from_array(origin.map(|o| (f64::from(o) + h) * self.lattice_unit))
    }

    /// Root (x, y, z) of a root index.
    #[inline]
    pub fn root_xyz(&self, r: u32) -> [u32; 3] {
        let [rx, ry, _] = self.roots;
        [r % rx, (r / rx) % ry, r / (rx * ry)]
    }

    #[inline]
    pub fn root_index(&self, xyz: [u32; 3]) -> u32 {
        xyz[0] + self.roots[0] * (xyz[1] + self.roots[1] * xyz[2])
    }

    /// Lattice origin of root `r`.
    #[inline]
    pub fn root_origin(&self, r: u32) -> [u32; 3] {
        // (R_a - 1) · 2^D < 2^32: fits.
        self.root_xyz(r).map(|v| v << self.max_depth)
    }

    /// The root across face `f` of root `r`, or None past the array (spec 1.1).
    pub fn root_neighbour(&self, r: u32, f: usize) -> Option<u32> {
        let (a, s) = FACES[f];
        let mut xyz = self.root_xyz(r);
        let v = i64::from(xyz[a]) + i64::from(s);
        if v < 0 || v >= i64::from(self.roots[a]) {
            return None;
        }
        xyz[a] = v as u32;
        Some(self.root_index(xyz))
    }

    /// The lattice point of a canvas point, or None outside the canvas
    /// (spec 1.3: one rounded division, then floor).
    pub fn lattice_point(&self, p: [f64; 3]) -> Option<[u32; 3]> {
        let mut q = [0u32; 3];
        for a in 0..3 {
            let x = p[a] / self.lattice_unit;
            if !(0.0 <= x && x < self.extent[a] as f64) {
                return None;
            }
            q[a] = x.floor() as u32;
        }
        Some(q)
    }

    /// Whether a cell of depth `d` is coarser than the target depth of
    /// radius `r`, i.e. `d < target_depth(r)`, in O(1): edges shrink with
    /// depth, so `d` is below the first small-enough depth exactly when its
    /// own edge `root_size·2^-d` (= `size_canvas[d]`, exact) is still larger
    /// than `r/10`, and no depth is below D's target when `d = D`.
    #[inline]
    pub fn coarser_than_target(&self, d: u32, r: f64) -> bool {
        d < self.max_depth && self.size_canvas[d as usize] > r / octopaint_model::CELLS_PER_RADIUS
    }

    /// Target depth of radius `r` (spec 8.7): the smallest `d` in [0, D] with
    /// `root_size · 2^-d <= r / 10`, or D if there is none.
    #[inline]
    pub fn target_depth(&self, r: f64) -> u32 {
        let t = r / octopaint_model::CELLS_PER_RADIUS;
        let mut d = 0;
        while d < self.max_depth && self.root_size * exp2i(-(d as i32)) > t {
            d += 1;
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_depth_lengths_are_exact_powers_of_two() {
        let lat = Lattice::new(&Canvas { roots: [4, 4, 4], max_depth: 25, root_size: 10000.0, capacity: 1 << 24 });
        assert_eq!(lat.lattice_unit, 10000.0 / 33554432.0);
        assert_eq!(lat.size_canvas[0], 10000.0);
        assert_eq!(lat.size_canvas[25], lat.lattice_unit);
        assert_eq!(lat.half_lattice[25], 0.5);
        assert_eq!(lat.extent, [4 << 25; 3]);
        assert_eq!(lat.centre([0, 0, 0], 25), DVec3::splat(0.5 * lat.lattice_unit));
    }

    #[test]
    fn target_depth_is_the_first_small_enough_cell() {
        let lat = Lattice::new(&Canvas { roots: [1, 1, 1], max_depth: 10, root_size: 1.0, capacity: 64 });
        assert_eq!(lat.target_depth(10.0), 0);
        assert_eq!(lat.target_depth(5.0), 1);
        assert_eq!(lat.target_depth(2.5), 2);
        assert_eq!(lat.target_depth(2.4999), 3);
        assert_eq!(lat.target_depth(1e-9), 10);
    }

    #[test]
    fn coarser_than_target_agrees_with_target_depth() {
        for (d_max, root_size) in [(10, 1.0), (25, 10000.0), (0, 3.0), (28, 1e-9)] {
            let lat = Lattice::new(&Canvas { roots: [1, 1, 1], max_depth: d_max, root_size, capacity: 64 });
            for i in 0..400 {
                let r = root_size * (2f64).powf(-(i as f64) * 0.1 + 4.0);
                for d in 0..=d_max {
                    assert_eq!(lat.coarser_than_target(d, r), d < lat.target_depth(r), "{d_max} {root_size} {r} {d}");
                }
            }
        }
    }

    #[test]
    fn canvas_points_outside_have_no_lattice_point() {
        let lat = Lattice::new(&Canvas { roots: [2, 1, 1], max_depth: 3, root_size: 1.0, capacity: 64 });
        assert_eq!(lat.lattice_point([1.99, 0.0, 0.5]), Some([15, 0, 4]));
        assert_eq!(lat.lattice_point([2.0, 0.0, 0.5]), None);
        assert_eq!(lat.lattice_point([-1e-300, 0.0, 0.5]), None);
    }
}

//! Brush primitives, reach, coverage and the five blend modes (spec 8).
//! Reference twin: reference/octopaint_ref/brush.py.
//!
//! Reach decides topology, so its arithmetic is exact f64 in the order the
//! spec writes it (and as numpy evaluates it in the reference): no fused
//! multiply-add, no reassociation. Coverage and blending feed colours, which
//! conformance compares within one step (the reference evaluates them in
//! XLA, whose results may differ by an ulp).

use glam::{DMat3, DVec3};

use crate::noise;
use octopaint_model::{Brush, Mode, Shape};

pub use octopaint_model::limits::{CELLS_PER_RADIUS, HALF_DIAG, TINY};
pub const RADIUS_PRESSURE_FLOOR: f64 = 0.25;
pub const OPACITY_CLAMP: f64 = 0.999;

/// Radius of a sample of the given pressure (spec 8.1).
#[inline]
pub fn pressure_radius(brush: &Brush, pressure: f64) -> f64 {
    brush.radius * (RADIUS_PRESSURE_FLOOR + (1.0 - RADIUS_PRESSURE_FLOOR) * pressure)
}

/// Extinction that gives α of opacity across one nominal radius.
pub fn sigma_brush(opacity: f64, radius: f64) -> f64 {
    -(-opacity.min(OPACITY_CLAMP)).ln_1p() / radius
}

/// Rotation matrix, local to canvas, of a quaternion `[x, y, z, w]`,
/// normalised first (spec 8.2), as rows `R[i][j]`.
pub fn quat_to_rows(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [x, y, z, w] = q;
    let n = (x * x + y * y + z * z + w * w).sqrt();
    let (x, y, z, w) = (x / n, y / n, z / n, w / n);
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// The same rotation as a glam matrix (columns are R's columns), so that
/// `transpose_mul_vec3(δ)` is the local point `l_i = R[0][i]·δ0 + R[1][i]·δ1
/// + R[2][i]·δ2`, summed left to right as the spec writes it.
pub fn quat_to_matrix(q: [f64; 4]) -> DMat3 {
    let r = quat_to_rows(q);
    DMat3::from_cols(DVec3::new(r[0][0], r[1][0], r[2][0]), DVec3::new(r[0][1], r[1][1], r[2][1]), DVec3::new(r[0][2], r[1][2], r[2][2]))
}

fn qnorm(q: [f64; 4]) -> f64 {
    (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt()
}

/// Normalised linear interpolation along the short arc (spec 8.4).
pub fn nlerp(q0: [f64; 4], q1: [f64; 4], u: f64) -> [f64; 4] {
    let n0 = qnorm(q0);
    let q0 = q0.map(|v| v / n0);
    let n1 = qnorm(q1);
    let mut q1 = q1.map(|v| v / n1);
    if q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0.0 {
        q1 = q1.map(|v| -v);
    }
    let q = [0, 1, 2, 3].map(|i| q0[i] + (q1[i] - q0[i]) * u);
    let n = qnorm(q);
    q.map(|v| v / n)
}

/// Radius, in brush radii, of a ball around a stamp's centre that holds the
/// stamp (bounding boxes, spec 8.7).
pub fn stamp_extent(shape: Shape, aspect: [f64; 3]) -> f64 {
    let [ax, ay, az] = aspect;
    match shape {
        Shape::Noise | Shape::Sphere => 1.0,
        Shape::Box => (ax * ax + ay * ay + az * az).sqrt(),
        Shape::Cylinder | Shape::Cone => {
            let m = ax.max(ay);
            (m * m + az * az).sqrt()
        }
    }
}

/// A tapered capsule between two samples (spec 8.3).
#[derive(Clone, Copy, Debug)]
pub struct Capsule {
    pub p0: DVec3,
    pub p1: DVec3,
    pub r0: f64,
    pub r1: f64,
    pub f0: f64,
    pub f1: f64,
    /// The start is open (spec 8.3): the previous capsule of the same
    /// path covers every point behind the start plane at least as much,
    /// so this one covers nothing there.
    pub open: bool,
    /// `p1 − p0`, its squared length and length, and the reach slack K
    /// (spec 8.7).
    pub(crate) d: DVec3,
    pub(crate) dd: f64,
    pub(crate) dn: f64,
    pub(crate) slack: f64,
}

/// The projection of a point on a capsule: distance to the axis point and
/// the parameter `u` there; `t = (x − p0)·(p1 − p0)` before the division
/// and clamping, and `w1 = |x − p0|₁` (the open start's tests, spec 8.3,
/// 8.7).
#[derive(Clone, Copy, Debug)]
pub struct CapsulePoint {
    pub dist: f64,
    pub u: f64,
    pub r: f64,
    pub t: f64,
    pub w1: f64,
}

impl Capsule {
    pub fn new(p0: DVec3, p1: DVec3, r0: f64, r1: f64, f0: f64, f1: f64) -> Self {
        let d = p1 - p0;
        let dd = d.dot(d);
        let dn = dd.sqrt();
        let slack = if dd < TINY { 1.0 } else { 1.0 + (r1 - r0).abs() / dn };
        Capsule { p0, p1, r0, r1, f0, f1, open: false, d, dd, dn, slack }
    }

    /// The capsule that follows `prev` on a path, from its end (spec 8.3):
    /// its start is open when it is a segment (`|d|² >= TINY`) and `prev`
    /// neither grows nor gains flow toward its end, so that `prev`'s own
    /// coverage is at least this one's behind the start plane.
    pub fn after(prev: &Capsule, p1: DVec3, r1: f64, f1: f64) -> Self {
        let mut c = Capsule::new(prev.p1, p1, prev.r1, r1, prev.f1, f1);
        c.open = c.dd >= TINY && prev.r0 >= prev.r1 && prev.f0 >= prev.f1;
        c
    }

    /// `capsule_geometry` of the reference for one point (exact f64; every
    /// glam operation used here is per component or a dot product summed
    /// x, y, z in order).
    #[inline]
    pub fn project(&self, x: DVec3) -> CapsulePoint {
        let w = x - self.p0;
        let t = w.dot(self.d);
        let u = if self.dd >= TINY { (t / self.dd).clamp(0.0, 1.0) } else { 0.0 };
        let e = x - (self.p0 + self.d * u);
        let s = e.dot(e);
        let dist = if s > 0.0 { s.sqrt() } else { 0.0 };
        let w1 = w.x.abs() + w.y.abs() + w.z.abs();
        CapsulePoint { dist, u, r: self.r0 + (self.r1 - self.r0) * u, t, w1 }
    }

    /// The ball of radius `h` about a point that projects to `cp` lies
    /// behind an open start, with a margin far above the rounding of `t`
    /// (spec 8.7): every point of it has `t < 0`.
    #[inline]
    fn ball_behind(&self, cp: &CapsulePoint, h: f64) -> bool {
        self.open && cp.t < -(h * self.dn + 1e-12 * (cp.w1 + h) * self.dn)
    }

    /// A cell with half-diagonal `h` whose centre projects to `cp` is within
    /// reach (spec 8.7).
    #[inline]
    pub fn within_reach(&self, cp: &CapsulePoint, h: f64) -> bool {
        cp.dist - cp.r <= h * self.slack && !self.ball_behind(cp, h)
    }

    /// Bounds of coverage·flow over the ball of radius `h` about a centre
    /// that projects to `cp` (spec 8.7, settled leaves): `dist` moves at
    /// most `h` and `r(u)` at most `h·(K − 1)` within the ball, the profile
    /// falls as `dist / r` grows, and the flow lies between `f0` and `f1`.
    #[inline]
    pub fn coverage_bounds(&self, cp: &CapsulePoint, h: f64, hardness: f64) -> (f64, f64) {
        let hr = h * (self.slack - 1.0);
        let rho_lo = (cp.dist - h).max(0.0) / (cp.r + hr);
        let r_lo = cp.r - hr;
        let rho_hi = if r_lo > 0.0 { (cp.dist + h) / r_lo } else { f64::INFINITY };
        let lo = coverage_profile(rho_hi, hardness) * self.f0.min(self.f1);
        let hi = coverage_profile(rho_lo, hardness) * self.f0.max(self.f1);
        (lo, hi)
    }

    /// Coverage·flow at a point that projects to `cp` (spec 8.5).
    #[inline]
    pub fn coverage_at(&self, cp: &CapsulePoint, hardness: f64) -> f64 {
        if self.open && cp.t < 0.0 {
            return 0.0; // behind an open start (spec 8.3)
        }
        let flow = self.f0 + (self.f1 - self.f0) * cp.u;
        coverage_profile(cp.dist / cp.r, hardness) * flow
    }

    /// Within reach of a cell with half-diagonal `h` at `x`, and the local
    /// radius there.
    #[inline]
    pub fn reach(&self, x: DVec3, h: f64) -> (bool, f64) {
        let cp = self.project(x);
        (self.within_reach(&cp, h), cp.r)
    }

    #[inline]
    pub fn coverage(&self, x: DVec3, hardness: f64) -> f64 {
        self.coverage_at(&self.project(x), hardness)
    }

    pub fn bounds(&self) -> (DVec3, DVec3) {
        let r = self.r0.max(self.r1);
        (self.p0.min(self.p1) - r, self.p0.max(self.p1) + r)
    }
}

/// An oriented stamp: box, cylinder, cone or noise ball (spec 8.2).
#[derive(Clone, Copy, Debug)]
pub struct Stamp {
    pub c: DVec3,
    pub r: f64,
    pub f: f64,
    /// Local to canvas (see [`quat_to_matrix`]); a mirrored copy's has the
    /// rows of its mirrored axes negated (spec 8.11).
    pub rot: DMat3,
    /// The mirror copy the stamp belongs to (spec 8.11; 0: the stroke
    /// itself): a noise stamp takes its noise at the point mirrored by it.
    pub mirror: u8,
}

impl Stamp {
    /// Local coordinates of canvas point `x` (spec 8.2, summed left to right).
    #[inline]
    pub fn local(&self, x: DVec3) -> DVec3 {
        self.rot.transpose_mul_vec3(x - self.c)
    }

    /// Distance from the centre (noise stamps), as `capsule_geometry` with
    /// `p0 = p1 = c` computes it.
    #[inline]
    fn dist(&self, x: DVec3) -> f64 {
        let e = x - self.c;
        let s = e.dot(e);
        if s > 0.0 { s.sqrt() } else { 0.0 }
    }

    /// Normalised gauge: `rho <= 1` inside (spec 8.2).
    #[inline]
    pub fn gauge(&self, shape: Shape, aspect: [f64; 3], x: DVec3) -> f64 {
        if shape == Shape::Noise {
            return self.dist(x) / self.r;
        }
        self.gauge_local(shape, aspect, self.local(x))
    }

    /// [`Stamp::gauge`] of a shape other than noise, given the point's
    /// local coordinates `l` ([`Stamp::local`]).
    #[inline]
    pub fn gauge_local(&self, shape: Shape, aspect: [f64; 3], l: DVec3) -> f64 {
        let nx = l.x / (aspect[0] * self.r);
        let ny = l.y / (aspect[1] * self.r);
        let nz = l.z / (aspect[2] * self.r);
        match shape {
            Shape::Box => nx.abs().max(ny.abs()).max(nz.abs()),
            _ => {
                let s = nx * nx + ny * ny;
                let radial = if s > 0.0 { s.sqrt() } else { 0.0 };
                if shape == Shape::Cylinder { radial.max(nz.abs()) } else { nz.abs().max(2.0 * radial + nz) }
            }
        }
    }

    /// Within reach of a cell with half-diagonal `h` at `x` (spec 8.7).
    #[inline]
    pub fn reach(&self, shape: Shape, aspect: [f64; 3], geo: &StampReach, x: DVec3, h: f64) -> bool {
        if shape == Shape::Noise {
            return self.dist(x) - self.r <= h;
        }
        self.reach_local(shape, aspect, geo, self.local(x), h)
    }

    /// [`Stamp::reach`] of a shape other than noise, given the point's
    /// local coordinates `l` ([`Stamp::local`]).
    #[inline]
    pub fn reach_local(&self, shape: Shape, aspect: [f64; 3], geo: &StampReach, l: DVec3, h: f64) -> bool {
        let r = self.r;
        let [ax, ay, az] = aspect;
        if shape == Shape::Box {
            return l.x.abs() <= ax * r + h && l.y.abs() <= ay * r + h && l.z.abs() <= az * r + h;
        }
        let nx = l.x / (ax * r);
        let ny = l.y / (ay * r);
        let s = nx * nx + ny * ny;
        let radial = if s > 0.0 { s.sqrt() } else { 0.0 };
        let inside = radial <= 1.0 + h / (geo.m * r) && l.z.abs() <= az * r + h;
        if shape == Shape::Cylinder || !inside {
            return inside;
        }
        let nz = l.z / (az * r);
        2.0 * radial + nz <= 1.0 + h * geo.lip / r
    }

    pub fn bounds(&self, extent: f64) -> (DVec3, DVec3) {
        let e = self.r * extent;
        (self.c - e, self.c + e)
    }
}

/// Per-brush constants of the cylinder and cone reach tests (spec 8.7):
/// `m = min(ax, ay)`, `lip = sqrt(4/(m·m) + 1/(az·az))`.
#[derive(Clone, Copy, Debug)]
pub struct StampReach {
    pub m: f64,
    pub lip: f64,
}

impl StampReach {
    pub fn new(aspect: [f64; 3]) -> Self {
        let m = aspect[0].min(aspect[1]);
        let az = aspect[2];
        StampReach { m, lip: (4.0 / (m * m) + 1.0 / (az * az)).sqrt() }
    }
}

/// 1 for `rho <= hardness`, smoothstep down to 0 at `rho = 1`, 0 beyond.
#[inline]
pub fn coverage_profile(rho: f64, hardness: f64) -> f64 {
    let span = 1.0 - hardness;
    let safe = if span > 0.0 { span } else { 1.0 };
    let t = ((1.0 - rho) / safe).clamp(0.0, 1.0);
    let smooth = t * t * (3.0 - 2.0 * t);
    if rho >= 1.0 {
        0.0
    } else if rho <= hardness {
        1.0
    } else {
        smooth
    }
}

/// The noise factor of a noise stamp at canvas point `x` (spec 8.6).
#[inline]
pub fn noise_factor(perm: &[u16; 512], brush: &Brush, x: DVec3) -> f64 {
    let n = &brush.noise;
    (0.5 + noise::fbm(perm, x.to_array(), n.frequency / brush.radius, n.octaves, n.gain)).clamp(0.0, 1.0)
}

/// What a stroke's blend (spec 8.5) holds fixed for every cell: the mode,
/// the brush density `sigma_b`, the opacity `alpha` and the mix ratio.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlendOf {
    pub mode: Mode,
    pub sigma_b: f64,
    pub alpha: f64,
    pub mix_ratio: f64,
}

/// The value of a cell after a stroke (spec 8.5): `before_rgb` in [0, 1],
/// `colour` the brush colour K of the primitive that gave the stroke
/// maximum `a`. Returns unrounded (rgb, sigma). `a == 0` keeps the cell.
#[inline]
pub fn blend(of: &BlendOf, before_rgb: [f64; 3], bs: f64, colour: [f64; 3], a: f64) -> ([f64; 3], f64) {
    let BlendOf { mode, sigma_b, alpha, mix_ratio } = *of;
    if a == 0.0 {
        return (before_rgb, bs);
    }
    match mode {
        Mode::Paint | Mode::Pickup => {
            let base = if bs == 0.0 { colour } else { before_rgb };
            ([0, 1, 2].map(|i| base[i] + (colour[i] - base[i]) * a), bs + (sigma_b - bs) * a)
        }
        Mode::Erase => (before_rgb, bs * (1.0 - a * alpha)),
        Mode::Recolor => {
            if bs > 0.0 {
                let t = a * alpha;
                ([0, 1, 2].map(|i| before_rgb[i] + (colour[i] - before_rgb[i]) * t), bs)
            } else {
                (before_rgb, bs)
            }
        }
        Mode::Mix => {
            let base = if bs == 0.0 { colour } else { before_rgb };
            let mut wb = mix_ratio * a * sigma_b;
            if wb < TINY {
                wb = 0.0;
            }
            let den = bs + wb;
            let rgb = if den > 0.0 { [0, 1, 2].map(|i| (bs * base[i] + wb * colour[i]) / den) } else { base };
            (rgb, bs + a * sigma_b)
        }
    }
}

/// Store a colour in [0, 1] as u8: `floor(v·255 + 0.5)`, clamped (spec 5).
#[inline]
pub fn quantize_rgb(v: [f64; 3]) -> [u8; 3] {
    [quantize_unit(v[0]), quantize_unit(v[1]), quantize_unit(v[2])]
}

/// One channel of [`quantize_rgb`]: `floor(v·255 + 0.5)` clamped to
/// [0, 255]. Rust's float-to-int cast truncates toward zero and saturates
/// (NaN to 0), which is that exactly: truncation is the floor at or above
/// 0, and everything below 0 (or NaN) gives 0 either way.
#[inline(always)]
pub fn quantize_unit(x: f64) -> u8 {
    (x * 255.0 + 0.5) as u8
}

/// Store a density: the nearest f32, at most the largest finite f32 (spec 5).
#[inline]
pub fn quantize_sigma(s: f64) -> f32 {
    s.min(f64::from(f32::MAX)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_profile_is_one_inside_zero_outside_smooth_between() {
        assert_eq!(coverage_profile(0.0, 0.5), 1.0);
        assert_eq!(coverage_profile(0.5, 0.5), 1.0);
        assert_eq!(coverage_profile(1.0, 0.5), 0.0);
        assert_eq!(coverage_profile(0.75, 0.5), 0.5);
        assert_eq!(coverage_profile(0.999, 1.0), 1.0);
    }

    #[test]
    fn capsule_tapers_and_degenerates_to_a_sphere() {
        let c = Capsule::new(DVec3::ZERO, DVec3::X, 0.1, 0.3, 1.0, 1.0);
        let p = c.project(DVec3::new(0.5, 0.2, 0.0));
        assert_eq!(p.u, 0.5);
        assert!((p.r - 0.2).abs() < 1e-15 && (p.dist - 0.2).abs() < 1e-15);
        let s = Capsule::new(DVec3::ONE, DVec3::ONE, 0.5, 0.5, 1.0, 1.0);
        assert_eq!(s.project(DVec3::new(1.0, 1.0, 1.5)).dist, 0.5);
        assert_eq!(s.slack, 1.0);
    }

    #[test]
    fn erase_with_full_opacity_empties_and_mix_adds_density() {
        let (rgb, s) = blend(&BlendOf { mode: Mode::Erase, sigma_b: 7.0, alpha: 1.0, mix_ratio: 1.0 }, [0.2; 3], 3.0, [1.0; 3], 1.0);
        assert_eq!((rgb, s), ([0.2; 3], 0.0));
        let (rgb, s) = blend(&BlendOf { mode: Mode::Mix, sigma_b: 1.0, alpha: 1.0, mix_ratio: 1.0 }, [1.0, 0.0, 0.0], 1.0, [0.0, 0.0, 1.0], 1.0);
        assert_eq!(rgb, [0.5, 0.0, 0.5]);
        assert_eq!(s, 2.0);
        let (rgb, _) = blend(&BlendOf { mode: Mode::Paint, sigma_b: 2.0, alpha: 1.0, mix_ratio: 1.0 }, [0.0; 3], 0.0, [0.3, 0.6, 0.9], 0.25);
        assert_eq!(rgb, [0.3, 0.6, 0.9], "an empty cell takes the brush colour");
    }

    #[test]
    fn stamp_gauges_are_one_on_the_surface() {
        let st = Stamp { c: DVec3::ZERO, r: 2.0, f: 1.0, rot: quat_to_matrix([0.0, 0.0, 0.0, 1.0]), mirror: 0 };
        let asp = [1.0, 0.5, 2.0];
        assert_eq!(st.gauge(Shape::Box, asp, DVec3::new(0.0, 1.0, 0.0)), 1.0);
        assert_eq!(st.gauge(Shape::Cylinder, asp, DVec3::new(0.0, 0.0, 4.0)), 1.0);
        assert_eq!(st.gauge(Shape::Cone, asp, DVec3::new(2.0, 0.0, -4.0)), 1.0);
        assert_eq!(st.gauge(Shape::Noise, asp, DVec3::new(0.0, 2.0, 0.0)), 1.0);
        // A quarter turn about z maps local x to canvas y.
        let q = [0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2];
        let turned = Stamp { rot: quat_to_matrix(q), ..st };
        assert!((turned.gauge(Shape::Box, asp, DVec3::new(0.0, 2.0, 0.0)) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn a_start_is_open_after_a_capsule_that_does_not_grow() {
        let sphere = Capsule::new(DVec3::ZERO, DVec3::ZERO, 1.0, 1.0, 0.5, 0.5);
        let a = Capsule::after(&sphere, DVec3::X, 1.0, 0.5);
        assert!(a.open, "after the first sample's sphere");
        assert!(Capsule::after(&a, DVec3::new(2.0, 0.0, 0.0), 1.5, 0.5).open, "this one may grow: the last did not");
        let grows = Capsule::new(DVec3::ZERO, DVec3::X, 1.0, 1.2, 0.5, 0.5);
        assert!(!Capsule::after(&grows, DVec3::new(2.0, 0.0, 0.0), 1.2, 0.5).open, "the last grew toward its end");
        let gains = Capsule::new(DVec3::ZERO, DVec3::X, 1.0, 1.0, 0.5, 0.6);
        assert!(!Capsule::after(&gains, DVec3::new(2.0, 0.0, 0.0), 1.0, 0.6).open, "the last gained flow");
        assert!(!Capsule::after(&a, DVec3::X, 1.0, 0.5).open, "no segment: a sphere keeps its start");
        let shrinks = Capsule::new(DVec3::ZERO, DVec3::X, 1.2, 1.0, 0.7, 0.5);
        assert!(Capsule::after(&shrinks, DVec3::new(2.0, 0.0, 0.0), 1.0, 0.5).open);
    }

    /// Behind an open start the capsule covers nothing, the previous
    /// capsule covers at least what the closed one would, and a ball
    /// declared behind holds no point with `t >= 0`.
    #[test]
    fn an_open_start_is_covered_by_the_capsule_before() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut unit = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut behind_balls = 0;
        for _ in 0..200 {
            let mut v = || DVec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * 8.0;
            let (pa, pb, pc) = (v(), v(), v());
            let (ra, rb) = (1.0 + unit(), 0.5 + unit() * 0.5);
            let (fa, fb) = (0.5 + unit() * 0.5, unit() * 0.5);
            let prev = Capsule::new(pa, pb, ra, rb, fa, fb);
            let open = Capsule::after(&prev, pc, 0.5 + unit(), unit());
            assert!(open.open);
            let closed = Capsule { open: false, ..open };
            for _ in 0..200 {
                let x = pb + DVec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * 6.0;
                let cp = open.project(x);
                if cp.t < 0.0 {
                    assert_eq!(open.coverage_at(&cp, 0.3), 0.0);
                    let (was, prev_cov) = (closed.coverage(x, 0.3), prev.coverage(x, 0.3));
                    assert!(prev_cov >= was - 1e-12, "{prev_cov} < {was} at {x}");
                } else {
                    assert_eq!(open.coverage_at(&cp, 0.3), closed.coverage_at(&cp, 0.3));
                }
                let h = unit() * 2.0;
                if open.ball_behind(&cp, h) {
                    behind_balls += 1;
                    assert!(!open.within_reach(&cp, h));
                    for _ in 0..20 {
                        let y = x + DVec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5).normalize_or_zero() * h * unit();
                        assert!(open.project(y).t < 0.0, "a point of a ball behind the start is not behind it");
                    }
                }
            }
        }
        assert!(behind_balls > 1000, "the test saw {behind_balls} balls behind a start");
    }

    #[test]
    fn a_stored_value_rounds_to_itself() {
        for v in 0..=255u8 {
            assert_eq!(quantize_rgb([f64::from(v) / 255.0; 3]), [v; 3]);
        }
        for s in [0.0f32, -0.0, 1e-45, 0.1, 3.5, 1e30, f32::MAX] {
            assert_eq!(quantize_sigma(f64::from(s)).to_bits(), s.to_bits());
        }
    }

    #[test]
    fn quantizing_clamps() {
        assert_eq!(quantize_rgb([-0.1, 0.5, 1.2]), [0, 128, 255]);
        // The cast is floor-and-clamp (spec 5) everywhere: halves, the
        // edges, values far outside, infinities, NaN, and a dense sweep.
        let spec = |x: f64| (x * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8;
        let mut xs = vec![0.0, -0.0, 1.0, -1.0, 0.5, 1e300, -1e300, f64::INFINITY, f64::NEG_INFINITY, f64::NAN, f64::MIN_POSITIVE, -f64::MIN_POSITIVE];
        for v in 0..=256u32 {
            let h = (f64::from(v) - 0.5) / 255.0; // rounds to v exactly at the half
            xs.extend([h, f64::from_bits(h.to_bits() + 1), f64::from_bits(h.to_bits() - 1), f64::from(v) / 255.0]);
        }
        xs.extend((0..200_000).map(|i| -0.1 + 1.2 * f64::from(i) / 200_000.0));
        for x in xs {
            assert_eq!(quantize_unit(x), spec(x), "{x:e}");
        }
        assert_eq!(quantize_sigma(1e300), f32::MAX);
        assert_eq!(quantize_sigma(0.1), 0.1f32);
    }
}

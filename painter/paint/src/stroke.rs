//! From trace samples to brush primitives (spec 8.3, 8.4). Reference twin:
//! reference/octopaint_ref/stroke.py.
//!
//! A sphere stroke is a chain of tapered capsules, one per segment between
//! consecutive samples (the first sample alone is a sphere). Every other
//! shape is stamped along the path every `spacing · r` of arc length. Each
//! `sample` event gives one segment: one capsule, or zero or more stamps.

use glam::DVec3;

use crate::brush::{Capsule, Stamp, nlerp, pressure_radius, quat_to_matrix, stamp_extent};
use octopaint_model::{Brush, Sample, Shape};

#[derive(Clone, Copy, Debug)]
pub enum Geometry {
    Capsule(Capsule),
    Stamp(Stamp),
}

/// One primitive: its geometry, the brush colour K it paints with, and a
/// box outside which its coverage is zero.
#[derive(Clone, Copy, Debug)]
pub struct Prim {
    pub geo: Geometry,
    pub colour: [f64; 3],
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Prim {
    /// The box overlaps `[lo, hi]` (closed on both sides).
    #[inline]
    pub fn overlaps(&self, lo: DVec3, hi: DVec3) -> bool {
        self.hi.cmpge(lo).all() && self.lo.cmple(hi).all()
    }

    /// The box holds `x` (closed). Outside it the primitive covers nothing
    /// (spec 8.5).
    #[inline]
    pub fn holds(&self, x: DVec3) -> bool {
        self.lo.cmple(x).all() && x.cmple(self.hi).all()
    }
}

/// The previous sample of a stroke: position, radius, flow, quaternion.
#[derive(Clone, Copy, Debug)]
struct Previous {
    p: DVec3,
    r: f64,
    f: f64,
    q: [f64; 4],
}

/// `x` mirrored through the planes of `mask` (spec 8.11): on each axis a
/// of the mask, `2·centre_a − x_a` (f64, one rounding).
pub fn mirrored(x: DVec3, mask: u8, centre: [f64; 3]) -> DVec3 {
    let mut v = x.to_array();
    for a in 0..3 {
        if mask >> a & 1 == 1 {
            v[a] = 2.0 * centre[a] - v[a];
        }
    }
    DVec3::from_array(v)
}

/// Turns the samples of one stroke into segments; a mirrored copy of the
/// stroke (spec 8.11) when `mask` is not 0.
#[derive(Clone)]
pub struct StrokePath {
    brush: Brush,
    prev: Option<Previous>,
    /// The last capsule (sphere brushes).
    last: Option<Capsule>,
    /// Arc length from the previous sample to the next stamp.
    carry: f64,
    extent: f64,
    /// The copy: the axes it is mirrored on (bit a: axis a), and the signs
    /// its stamps' rotation rows take (−1 on those axes).
    mask: u8,
    flip: DVec3,
}

impl StrokePath {
    pub fn new(brush: Brush) -> Self {
        StrokePath::mirror(brush, 0)
    }

    /// The copy of the stroke mirrored on the axes of `mask` through the
    /// brush's mirror centre (0: the stroke itself).
    pub fn mirror(brush: Brush, mask: u8) -> Self {
        let flip = DVec3::from_array([0, 1, 2].map(|a| if mask >> a & 1 == 1 { -1.0 } else { 1.0 }));
        StrokePath { brush, prev: None, last: None, carry: 0.0, extent: stamp_extent(brush.shape, brush.aspect), mask, flip }
    }

    /// The stroke and each of its mirrored copies, in the order they paint
    /// (spec 8.11).
    pub fn all(brush: Brush) -> Vec<StrokePath> {
        let copies: Vec<u8> = brush.mirror.map(|m| m.copies().collect()).unwrap_or_default();
        std::iter::once(0).chain(copies).map(|m| StrokePath::mirror(brush, m)).collect()
    }

    /// The primitives of the segment ending at `sample`, painting `colour`.
    pub fn segment(&mut self, sample: &Sample, colour: [f64; 3], out: &mut Vec<Prim>) {
        let b = self.brush;
        let mut p = DVec3::from_array(sample.p);
        if self.mask != 0 {
            p = mirrored(p, self.mask, b.mirror.expect("a copy has a mirror").centre);
        }
        let r = pressure_radius(&b, sample.pressure);
        let f = sample.pressure;
        let q = sample.q;
        let prev = self.prev.replace(Previous { p, r, f, q });
        if b.shape == Shape::Sphere {
            // The first sample is a sphere; each capsule after starts where
            // the last one ended (spec 8.3).
            let cap = match &self.last {
                Some(last) => Capsule::after(last, p, r, f),
                None => Capsule::new(p, p, r, r, f, f),
            };
            self.last = Some(cap);
            let (lo, hi) = cap.bounds();
            out.push(Prim { geo: Geometry::Capsule(cap), colour, lo, hi });
            return;
        }
        let (mask, flip) = (self.mask, self.flip);
        let mut stamp = |c: DVec3, r: f64, f: f64, q: [f64; 4]| {
            let m = quat_to_matrix(q);
            // Row a times flip_a, entry by entry: the mirror image, exactly.
            let rot = glam::DMat3::from_cols(m.x_axis * flip, m.y_axis * flip, m.z_axis * flip);
            let st = Stamp { c, r, f, rot, mirror: mask };
            let (lo, hi) = st.bounds(self.extent);
            out.push(Prim { geo: Geometry::Stamp(st), colour, lo, hi });
        };
        match prev {
            None => {
                stamp(p, r, f, q);
                self.carry = b.spacing * r;
            }
            Some(Previous { p: pa, r: ra, f: fa, q: qa }) => {
                let d = p - pa;
                let length = d.length();
                if length > 0.0 {
                    let mut s = self.carry;
                    while s <= length {
                        let u = s / length;
                        let ru = ra + (r - ra) * u;
                        stamp(pa + d * u, ru, fa + (f - fa) * u, nlerp(qa, q, u));
                        s += b.spacing * ru;
                    }
                    self.carry = s - length;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brush::Stamp;
    use octopaint_model::Mode;

    #[test]
    fn stamps_are_spaced_along_the_path_with_carry() {
        let mut b = Brush::new(Shape::Box, Mode::Paint, 1.0, [1.0; 3], 1.0, 0.5);
        b.spacing = 0.5;
        let mut path = StrokePath::new(b);
        let mut out = Vec::new();
        path.segment(&Sample::at([0.0; 3]), [1.0; 3], &mut out);
        assert_eq!(out.len(), 1);
        path.segment(&Sample::at([1.2, 0.0, 0.0]), [1.0; 3], &mut out);
        let xs: Vec<f64> = out.iter().map(|p| if let Geometry::Stamp(s) = p.geo { s.c.x } else { panic!() }).collect();
        assert_eq!(xs, vec![0.0, 0.5, 1.0]);
        path.segment(&Sample::at([1.2, 0.0, 0.0]), [1.0; 3], &mut out);
        assert_eq!(out.len(), 3, "a zero-length segment places nothing");
        path.segment(&Sample::at([2.0, 0.0, 0.0]), [1.0; 3], &mut out);
        assert_eq!(out.len(), 5);
        assert!(matches!(out[3].geo, Geometry::Stamp(s) if (s.c.x - 1.5).abs() < 1e-12));
    }

    #[test]
    fn mirrored_copies_are_placed_and_turned_as_mirror_images() {
        let mut b = Brush::new(Shape::Box, Mode::Paint, 0.1, [1.0; 3], 1.0, 0.5);
        b.mirror = Some(octopaint_model::Mirror { axes: [true, false, true], centre: [0.5, 0.25, 0.5] });
        let paths = StrokePath::all(b);
        assert_eq!(paths.iter().map(|p| p.mask).collect::<Vec<_>>(), vec![0, 1, 4, 5]);
        let q = [0.2, 0.3, 0.1, 0.9];
        let sample = Sample { p: [0.3, 0.1, 0.6], pressure: 1.0, q };
        let mut out = Vec::new();
        for mut p in paths {
            p.segment(&sample, [1.0; 3], &mut out);
        }
        let stamps: Vec<Stamp> = out.iter().map(|p| if let Geometry::Stamp(s) = p.geo { s } else { panic!() }).collect();
        let r = quat_to_matrix(q);
        for (s, (mask, c)) in stamps.iter().zip([
            (0, [0.3, 0.1, 0.6]),
            (1, [2.0 * 0.5 - 0.3, 0.1, 0.6]),
            (4, [0.3, 0.1, 2.0 * 0.5 - 0.6]),
            (5, [2.0 * 0.5 - 0.3, 0.1, 2.0 * 0.5 - 0.6]),
        ]) {
            assert_eq!((s.mirror, s.c.to_array()), (mask, c));
            let flip = DVec3::from_array([0, 1, 2].map(|a| if mask >> a & 1 == 1 { -1.0 } else { 1.0 }));
            assert_eq!(s.rot, glam::DMat3::from_cols(r.x_axis * flip, r.y_axis * flip, r.z_axis * flip));
        }
        // One plane: a mirror image (det -1); two: a half turn.
        assert!((stamps[1].rot.determinant() + 1.0).abs() < 1e-12 && (stamps[3].rot.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn sphere_strokes_are_capsules_from_the_previous_sample() {
        let b = Brush::new(Shape::Sphere, Mode::Paint, 2.0, [1.0; 3], 1.0, 0.5);
        let mut path = StrokePath::new(b);
        let mut out = Vec::new();
        path.segment(&Sample::at([0.0; 3]), [1.0; 3], &mut out);
        path.segment(&Sample { p: [1.0, 0.0, 0.0], pressure: 0.0, q: [0.0, 0.0, 0.0, 1.0] }, [1.0; 3], &mut out);
        let Geometry::Capsule(c) = out[1].geo else { panic!() };
        assert_eq!((c.p0, c.p1, c.r0, c.r1, c.f0, c.f1), (DVec3::ZERO, DVec3::X, 2.0, 0.5, 1.0, 0.0));
        assert_eq!(out[1].lo, DVec3::splat(-2.0));
    }
}

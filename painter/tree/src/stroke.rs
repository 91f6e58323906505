//! From trace samples to brush primitives (spec 8.3, 8.4). Reference twin:
//! reference/octopaint_ref/stroke.py.
//!
//! A sphere stroke is a chain of tapered capsules, one per segment between
//! consecutive samples (the first sample alone is a sphere). Every other
//! shape is stamped along the path every `spacing · r` of arc length. Each
//! `sample` event gives one segment: one capsule, or zero or more stamps.

use glam::DVec3;

use crate::brush::{Capsule, Stamp, nlerp, pressure_radius, quat_to_matrix, stamp_extent};
use crate::trace::{Brush, Sample, Shape};

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

/// Turns the samples of one stroke into segments.
#[derive(Clone)]
pub struct StrokePath {
    brush: Brush,
    prev: Option<Previous>,
    /// Arc length from the previous sample to the next stamp.
    carry: f64,
    extent: f64,
}

impl StrokePath {
    pub fn new(brush: Brush) -> Self {
        StrokePath { brush, prev: None, carry: 0.0, extent: stamp_extent(brush.shape, brush.aspect) }
    }

    /// The primitives of the segment ending at `sample`, painting `colour`.
    pub fn segment(&mut self, sample: &Sample, colour: [f64; 3], out: &mut Vec<Prim>) {
        let b = self.brush;
        let p = DVec3::from_array(sample.p);
        let r = pressure_radius(&b, sample.pressure);
        let f = sample.pressure;
        let q = sample.q;
        let prev = self.prev.replace(Previous { p, r, f, q });
        if b.shape == Shape::Sphere {
            let Previous { p: p0, r: r0, f: f0, .. } = prev.unwrap_or(Previous { p, r, f, q });
            let cap = Capsule::new(p0, p, r0, r, f0, f);
            let (lo, hi) = cap.bounds();
            out.push(Prim { geo: Geometry::Capsule(cap), colour, lo, hi });
            return;
        }
        let mut stamp = |c: DVec3, r: f64, f: f64, q: [f64; 4]| {
            let st = Stamp { c, r, f, rot: quat_to_matrix(q) };
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
    use crate::trace::Mode;

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

//! Views of a painting from outside: an orbit camera (the desktop
//! window's, `octopaint render`'s and its turntables') and the view that
//! frames everything painted, and the surface under a ray (the brush's
//! point when painting on the surface).

use glam::{DQuat, DVec3, EulerRot};

use crate::pool::Tree;
use crate::trace::Camera;

/// The desktop window's background, and the default of renders.
pub const BACKGROUND: [f64; 3] = [0.06, 0.06, 0.08];

/// The light the desktop window and `octopaint render --lit` start with
/// (spec 6.1): from above, slightly right and in front of the default view.
pub const DEFAULT_LIGHT: crate::trace::Light = crate::trace::Light { on: true, dir: [0.45, 1.0, 0.35], intensity: 0.8, ambient: 0.3, shadows: false };

/// A camera on a sphere around `target`, looking at it: turned by `yaw`
/// about the canvas's y axis, then tilted by `pitch` (radians; negative
/// looks down), `distance` canvas units away, `fov_y` the vertical field
/// of view (radians). `covered` is the share of the image's width that a
/// panel hides on the left (0 to 0.9): the frustum is shifted so that the
/// target sits in the middle of the part that shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    pub target: DVec3,
    pub distance: f64,
    pub yaw: f64,
    pub pitch: f64,
    pub fov_y: f64,
    pub covered: f64,
}

impl OrbitCamera {
    pub fn rotation(&self) -> DQuat {
        DQuat::from_euler(EulerRot::YXZ, self.yaw, self.pitch, 0.0)
    }

    pub fn eye(&self) -> DVec3 {
        self.target + self.rotation() * DVec3::new(0.0, 0.0, self.distance)
    }

    /// The trace camera of an image of `size` pixels (square pixels).
    pub fn camera(&self, size: [u32; 2], background: [f64; 3]) -> Camera {
        let q = self.rotation();
        let aspect = f64::from(size[0]) / f64::from(size[1].max(1));
        let ty = (self.fov_y / 2.0).tan();
        let tx = ty * aspect;
        // Tangents from -(1+s)tx to (1-s)tx: the same width, the centre of
        // the uncovered part [s, 1] of the image on the view axis.
        let s = self.covered.clamp(0.0, 0.9);
        let fov = [(-(1.0 + s) * tx).atan(), ((1.0 - s) * tx).atan(), ty.atan(), -ty.atan()];
        Camera { eye: self.eye().to_array(), q: [q.x, q.y, q.z, q.w], fov, size, background }
    }

    /// The ray through pixel (x, y) of an image of `size`, as spec 7
    /// defines it: (eye, unit direction).
    pub fn ray(&self, size: [u32; 2], x: f64, y: f64) -> (DVec3, DVec3) {
        let c = self.camera(size, BACKGROUND);
        let (l, r, u, d) = (c.fov[0].tan(), c.fov[1].tan(), c.fov[2].tan(), c.fov[3].tan());
        let tx = l + (x + 0.5) / f64::from(size[0]) * (r - l);
        let ty = u - (y + 0.5) / f64::from(size[1]) * (u - d);
        (self.eye(), (self.rotation() * DVec3::new(tx, ty, -1.0)).normalize())
    }
}

/// A camera looking at everything painted (or the whole canvas when
/// nothing is), from a little above, with a 60° vertical field of view.
pub fn frame_painting(tree: &Tree) -> OrbitCamera {
    let (lo, hi) = tree.painted_bounds();
    frame_box(tree, lo, hi)
}

/// The view of the box `lo`..`hi` (canvas units) over `tree`'s canvas: at
/// least one finest cell wide.
fn frame_box(tree: &Tree, lo: DVec3, hi: DVec3) -> OrbitCamera {
    let radius = ((hi - lo).length() / 2.0).max(tree.lat.size_canvas[tree.lat.max_depth as usize]);
    OrbitCamera { target: (lo + hi) / 2.0, distance: radius * 2.2, yaw: 0.5, pitch: -0.35, fov_y: 60f64.to_radians(), covered: 0.0 }
}

/// [`frame_painting`] for several trees (a document's layers): the box
/// around every painted leaf of any of them (the first tree's whole canvas
/// when none is painted).
pub fn frame_trees(trees: &[&Tree]) -> OrbitCamera {
    let painted: Vec<&&Tree> = trees.iter().filter(|t| t.sigma().iter().any(|&s| s > 0.0)).collect();
    let Some(first) = painted.first() else { return frame_painting(trees[0]) };
    let (mut lo, mut hi) = first.painted_bounds();
    for t in &painted[1..] {
        let (l, h) = t.painted_bounds();
        lo = lo.min(l);
        hi = hi.max(h);
    }
    frame_box(first, lo, hi)
}

/// The canvas axes x, y, z as a camera turned by `camera_to_canvas` sees
/// them, for an axes gizmo: each one's direction on the screen (y down)
/// and whether it points away from the viewer.
pub fn axes_seen_from(camera_to_canvas: DQuat) -> [([f32; 2], bool); 3] {
    let inv = camera_to_canvas.inverse();
    [DVec3::X, DVec3::Y, DVec3::Z].map(|a| {
        let v = inv * a;
        ([v.x as f32, -v.y as f32], v.z < 0.0)
    })
}

/// The smallest share of the width and height a view is cast at while it
/// moves (dynamic resolution, docs/desktop.md and docs/vr.md).
pub const MIN_SCALE: f64 = 0.25;

/// Dynamic resolution's step: the share of the width and height to cast
/// the next moving frame at, after one at `scale` took `ms`, aiming at
/// `target_ms`. Time goes roughly with the pixels cast (`scale²`); the
/// step is smoothed and rounded to 1/32 so the size does not flicker.
pub fn follow_frame_time(scale: f64, ms: f64, target_ms: f64) -> f64 {
    let want = (scale * (target_ms / ms.max(0.1)).sqrt()).clamp(MIN_SCALE, 1.0);
    ((0.6 * scale + 0.4 * want) * 32.0).round() / 32.0
}

/// A length in canvas units, read as metres (the scene trace's canvas is
/// 40 km wide in these units), with a unit that keeps it readable.
pub fn length(x: f64) -> String {
    let a = x.abs();
    if !a.is_finite() {
        return format!("{x}");
    }
    let (v, unit) = if a >= 1e3 {
        (x / 1e3, "km")
    } else if a >= 1.0 {
        (x, "m")
    } else if a >= 1e-2 {
        (x * 1e2, "cm")
    } else if a >= 1e-3 || a == 0.0 {
        (x * 1e3, "mm")
    } else {
        (x * 1e6, "µm")
    };
    // Three significant digits.
    let digits = if v.abs() >= 100.0 {
        0
    } else if v.abs() >= 10.0 {
        1
    } else {
        2
    };
    format!("{v:.digits$} {unit}")
}

/// The first point along a ray where the paint's optical depth reaches
/// 0.7 (what looks like its surface), marching leaf to leaf.
pub fn pick(tree: &Tree, eye: DVec3, dir: DVec3) -> Option<f64> {
    let size = DVec3::from_array(tree.lat.roots.map(|r| f64::from(r) * tree.lat.root_size));
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if dir[a].abs() < 1e-300 {
            if eye[a] < 0.0 || eye[a] >= size[a] {
                return None;
            }
            continue;
        }
        let (a0, a1) = ((0.0 - eye[a]) / dir[a], (size[a] - eye[a]) / dir[a]);
        t0 = t0.max(a0.min(a1));
        t1 = t1.min(a0.max(a1));
    }
    if t0 >= t1 {
        return None;
    }
    let mut t = t0;
    let mut tau = 0.0;
    for _ in 0..100_000 {
        if t >= t1 {
            return None;
        }
        let p = eye + dir * t;
        let c = tree.leaf_at(p.to_array())?;
        let d = u32::from(tree.depth()[c as usize]);
        let s = tree.lat.size_canvas[d as usize];
        let lo = DVec3::from_array(tree.origin(c).map(|o| f64::from(o) * tree.lat.lattice_unit));
        let mut exit = f64::INFINITY;
        for a in 0..3 {
            if dir[a] > 0.0 {
                exit = exit.min((lo[a] + s - p[a]) / dir[a]);
            } else if dir[a] < 0.0 {
                exit = exit.min((lo[a] - p[a]) / dir[a]);
            }
        }
        let len = exit.max(0.0);
        let sigma = f64::from(tree.sigma()[c as usize]);
        if sigma > 0.0 {
            if tau + sigma * len >= 0.7 {
                return Some(t + (0.7 - tau) / sigma);
            }
            tau += sigma * len;
        }
        t += len + s * 1e-6;
    }
    None
}

#[cfg(test)]
mod length_tests {
    use super::length;

    #[test]
    fn lengths_read_with_a_unit_and_three_digits() {
        assert_eq!(length(40_000.0), "40.0 km");
        assert_eq!(length(2.5), "2.50 m");
        assert_eq!(length(0.0572), "5.72 cm");
        assert_eq!(length(0.003667), "3.67 mm");
        assert_eq!(length(0.0003), "300 µm");
        assert_eq!(length(0.0), "0.00 mm");
    }
}

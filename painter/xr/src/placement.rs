//! Where the canvas is in the room (docs/vr.md): a similarity transform
//! kept in f64, so that the runtime's poses (f32 metres) become canvas
//! points in f64 and any zoom of the canvas keeps its precision; the box of
//! paint it is placed around, and each eye's camera through it.

use glam::{DQuat, DVec3};
use octopaint_tree::Tree;
use octopaint_tree::layers::Document;
use octopaint_tree::trace::Camera;
use openxr as xr;

/// The box the painted cells of some trees fill, and the finest cell edge
/// (the smallest box a painting is shown at).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub lo: DVec3,
    pub hi: DVec3,
    pub finest: f64,
}

impl Bounds {
    pub fn of(trees: &[&Tree]) -> Bounds {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for t in trees {
            let (a, b) = t.painted_bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        let tree = trees[0];
        Bounds { lo, hi, finest: tree.lat.size_canvas[tree.lat.max_depth as usize] }
    }

    /// What a document shows: its visible layers, or the selected one.
    pub fn shown(doc: &Document) -> Bounds {
        let mut trees: Vec<&Tree> = doc.layers().filter(|l| l.contributes()).map(|l| l.tree()).collect();
        if trees.is_empty() {
            trees.push(doc.current().tree());
        }
        Bounds::of(&trees)
    }
}

/// The canvas in the room: `room = origin + scale · rotation · (canvas − centre)`.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    pub centre: DVec3,
    pub scale: f64,
    pub rotation: DQuat,
    pub origin: DVec3,
}

impl Placement {
    /// A painting's bounding sphere shown 0.5 m wide, 1 m in front of a
    /// head at `head` looking along `forward` (room units), the canvas's up
    /// the room's.
    pub fn in_front(tree: &Tree, head: DVec3, forward: DVec3) -> Placement {
        Placement::in_front_of(&[tree], head, forward)
    }

    /// [`Placement::in_front`] for what several trees (the visible layers
    /// of a document) hold together.
    pub fn in_front_of(trees: &[&Tree], head: DVec3, forward: DVec3) -> Placement {
        Placement::around(&Bounds::of(trees), head, forward)
    }

    /// [`Placement::in_front`] for a box of paint.
    pub fn around(b: &Bounds, head: DVec3, forward: DVec3) -> Placement {
        let radius = ((b.hi - b.lo).length() / 2.0).max(b.finest);
        let f = DVec3::new(forward.x, 0.0, forward.z).try_normalize().unwrap_or(DVec3::NEG_Z);
        Placement { centre: (b.lo + b.hi) / 2.0, scale: 0.25 / radius, rotation: DQuat::IDENTITY, origin: head + f }
    }

    /// The canvas point at room point `p`.
    pub fn to_canvas(&self, p: DVec3) -> DVec3 {
        self.centre + self.rotation.inverse() * (p - self.origin) / self.scale
    }

    /// A room orientation as a canvas orientation.
    pub fn rotate_to_canvas(&self, q: DQuat) -> DQuat {
        self.rotation.inverse() * q
    }
}

/// The head between the two eyes, and the direction the first looks along.
pub fn head_of(views: &[xr::View]) -> (DVec3, DVec3) {
    let (a, q) = crate::pose_of(&views[0].pose);
    ((a + crate::pose_of(&views[1].pose).0) / 2.0, q * DVec3::NEG_Z)
}

/// One eye's camera in canvas units: its pose from the runtime (room,
/// metres) through the placement, its asymmetric field of view as is.
pub fn eye_camera(p: &Placement, view: &xr::View, size: [u32; 2]) -> Camera {
    let (pos, o) = crate::pose_of(&view.pose);
    let eye = p.to_canvas(pos);
    let q = p.rotate_to_canvas(o);
    let f = view.fov;
    Camera {
        eye: eye.to_array(),
        q: [q.x, q.y, q.z, q.w],
        fov: [f64::from(f.angle_left), f64::from(f.angle_right), f64::from(f.angle_up), f64::from(f.angle_down)],
        size,
        background: [0.05, 0.05, 0.07],
    }
}

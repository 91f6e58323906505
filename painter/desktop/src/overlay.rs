//! What the window draws over the view (docs/desktop.md, "Aids"): the
//! brush cursor and its mirror images, the mirror planes, the axes and the
//! scale.

use glam::DVec3;
use octopaint_tree::lattice::Lattice;
use octopaint_tree::trace::{Camera, Shape};
use octopaint_tree::view::{BACKGROUND, OrbitCamera, axes_seen_from};

use crate::brush::BrushUi;

/// The parts of the window's state the overlay is drawn from.
struct View<'a> {
    camera: &'a OrbitCamera,
    cursor: (f64, f64),
    brush: &'a BrushUi,
}

/// What the window draws over the view: the brush cursor, the axes and the
/// scale (docs/desktop.md, "Aids").
pub(crate) struct Overlay {
    /// Window pixels: the cursor, the brush's radius there, its colour and
    /// whether its shape is a box (a square ghost; a disc otherwise).
    cursor: Option<([f32; 2], f32, [f32; 3], bool)>,
    /// The canvas axes x, y, z in the view: screen direction (y down) and
    /// whether the axis points away from the viewer.
    axes: [([f32; 2], bool); 3],
    /// Canvas units per pixel at the brush's distance, the brush radius
    /// and the depth it paints at, with that depth's cell edge.
    pub(crate) scale: (f64, f64, u32, f64),
    /// The cursor's mirror images (spec 8.11): window pixels and radius.
    ghosts: Vec<([f32; 2], f32)>,
    /// The mirror planes as quadrilaterals in window pixels, by axis.
    planes: Vec<([[f32; 2]; 4], usize)>,
}

/// Window pixel and view depth of canvas point `p` for `camera` (spec 6's
/// pixel mapping inverted); None behind the eye.
fn project(camera: &Camera, p: DVec3) -> Option<([f32; 2], f64)> {
    let m = octopaint_tree::brush::quat_to_rows(camera.q);
    let d = p - DVec3::from_array(camera.eye);
    let v = [0, 1, 2].map(|i| m[0][i] * d.x + m[1][i] * d.y + m[2][i] * d.z);
    if v[2] >= -1e-9 {
        return None;
    }
    let (tx, ty) = (v[0] / -v[2], v[1] / -v[2]);
    let [l, r, u, dn] = camera.fov.map(f64::tan);
    let [w, h] = camera.size.map(f64::from);
    Some(([((tx - l) / (r - l) * w) as f32, ((u - ty) / (u - dn) * h) as f32], -v[2]))
}

impl Overlay {
    /// The overlay of a `size` view from `camera` with the mouse at
    /// `cursor` and the brush's point `(eye, dir, depth)` under it.
    pub(crate) fn new(
        camera: &OrbitCamera,
        size: [u32; 2],
        cursor: (f64, f64),
        brush: &BrushUi,
        lat: &Lattice,
        (eye, dir, depth): (DVec3, DVec3, f64),
    ) -> Overlay {
        let r = View { camera, cursor, brush };
        let rot = r.camera.rotation();
        let z = depth * dir.dot(rot * DVec3::NEG_Z);
        // Canvas units per pixel at view depth z (square pixels).
        let per_px = 2.0 * z * (r.camera.fov_y / 2.0).tan() / f64::from(size[1].max(1));
        let radius_px = (r.brush.radius / per_px).clamp(2.0, 4.0 * f64::from(size[1])) as f32;
        let inside = r.cursor.0 >= 0.0 && r.cursor.1 >= 0.0 && r.cursor.0 < f64::from(size[0]) && r.cursor.1 < f64::from(size[1]);
        let cursor = (inside && per_px.is_finite() && per_px > 0.0)
            .then(|| ([r.cursor.0 as f32, r.cursor.1 as f32], radius_px, r.brush.colour, r.brush.shape == Shape::Box));
        let axes = axes_seen_from(rot);
        let d = lat.target_depth(r.brush.radius);
        // Mirror painting: the cursor's images and the planes, faint.
        let (mut ghosts, mut planes) = (Vec::new(), Vec::new());
        if let Some(m) = r.brush.mirror() {
            let camera = r.camera.camera(size, BACKGROUND);
            let p = eye + dir * depth;
            let px_per_unit_depth = f64::from(size[1].max(1)) / (2.0 * (r.camera.fov_y / 2.0).tan());
            if cursor.is_some() {
                for mask in m.copies() {
                    if let Some((at, z)) = project(&camera, octopaint_tree::stroke::mirrored(p, mask, m.centre)) {
                        ghosts.push((at, (r.brush.radius / z * px_per_unit_depth).clamp(2.0, 4.0 * f64::from(size[1])) as f32));
                    }
                }
            }
            let c = DVec3::from_array(m.centre);
            let s = 0.4 * r.camera.distance;
            for a in (0..3).filter(|&a| m.axes[a]) {
                let (u, v) = (DVec3::AXES[(a + 1) % 3] * s, DVec3::AXES[(a + 2) % 3] * s);
                let corners = [c - u - v, c + u - v, c + u + v, c - u + v].map(|q| project(&camera, q));
                if corners.iter().all(Option::is_some) {
                    planes.push((corners.map(|q| q.expect("checked").0), a));
                }
            }
        }
        Overlay { cursor, axes, scale: (per_px, r.brush.radius, d, lat.size_canvas[d as usize]), ghosts, planes }
    }

    /// Draw the cursor and the axes over the view (`view`: the part of the
    /// window the panels leave, in points).
    pub(crate) fn draw(&self, ctx: &egui::Context, view: egui::Rect) {
        let painter = ctx.layer_painter(egui::LayerId::new(egui::Order::Foreground, egui::Id::unique("overlay"))).with_clip_rect(view);
        let ppp = ctx.pixels_per_point();
        let axis_colour = |a: usize, alpha: u8| {
            [
                egui::Color32::from_rgba_unmultiplied(230, 60, 60, alpha),
                egui::Color32::from_rgba_unmultiplied(70, 200, 70, alpha),
                egui::Color32::from_rgba_unmultiplied(70, 120, 240, alpha),
            ][a]
        };
        for (quad, a) in &self.planes {
            let points: Vec<egui::Pos2> = quad.iter().map(|p| egui::pos2(p[0] / ppp, p[1] / ppp)).collect();
            painter.add(egui::Shape::convex_polygon(points, axis_colour(*a, 20), egui::Stroke::new(1.0, axis_colour(*a, 110))));
        }
        if let Some((_, _, colour, _)) = self.cursor {
            let rgb = colour.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
            for (at, radius) in &self.ghosts {
                let centre = egui::pos2(at[0] / ppp, at[1] / ppp);
                painter.circle_stroke(centre, radius / ppp, egui::Stroke::new(1.5, egui::Color32::from_rgba_unmultiplied(rgb[0], rgb[1], rgb[2], 140)));
            }
        }
        if let Some((at, radius, colour, square)) = self.cursor {
            let centre = egui::pos2(at[0] / ppp, at[1] / ppp);
            let rgb = colour.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
            let edge = egui::Color32::from_rgb(rgb[0], rgb[1], rgb[2]);
            let fill = egui::Color32::from_rgba_unmultiplied(rgb[0], rgb[1], rgb[2], 40);
            let r = radius / ppp;
            let stroke = egui::Stroke::new(2.0, edge);
            if square {
                let rect = egui::Rect::from_center_size(centre, egui::vec2(2.0 * r, 2.0 * r));
                painter.rect(rect, 0.0, fill, stroke, egui::StrokeKind::Middle);
            } else {
                painter.circle(centre, r, fill, stroke);
            }
            painter.circle_filled(centre, 1.5, edge);
        }
        // The axes, 36 points long from a corner of the view.
        octopaint_ui::axes_gizmo(&painter, egui::pos2(view.right() - 52.0, view.bottom() - 52.0), 36.0, &self.axes, true);
    }
}

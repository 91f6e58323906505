//! One VR frame's pictures (docs/vr.md): both eyes cast at the size the
//! view layer chose (`octopaint_pipeline::View`: dynamic resolution while
//! something moves, full size once still, then nothing cast and each eye's
//! last cast presented again), drawn into their layers of the swapchain
//! image, the indicators and the palette over them, and for `--capture`
//! read back. Nothing here touches the tree or the document: the frame
//! gets what the engine staged (`Frames::prepare`) and what its stroke
//! thread published.
#![cfg_attr(target_os = "macos", allow(dead_code, unused_imports))]

use std::time::Instant;

use glam::DVec3;
use octopaint_gpu::image::Capture;
use octopaint_gpu::{Blit, Precision, Renderer};
use octopaint_pipeline::{Doing, Frames, Indicator, Prepared, Status, View};
use octopaint_tree::lattice::Lattice;
use octopaint_tree::raycast::RayParams;
use octopaint_tree::view::DEFAULT_LIGHT;
use openxr as xr;

use crate::XrError;
use crate::gestures::Gestures;
use crate::input::{Hand, LEFT, RIGHT};
use crate::placement::{Placement, eye_camera};
use crate::setup::{Eyes, other};

/// What the eyes look at, compared frame to frame to tell a still frame:
/// both eyes' poses, the canvas's place, lit and grid.
pub(crate) struct Look {
    poses: [xr::Posef; 2],
    placement: [f64; 8],
    view: (bool, bool),
}

impl Look {
    pub(crate) fn new(views: &[xr::View], p: &Placement, view: (bool, bool)) -> Look {
        Look {
            poses: [views[0].pose, views[1].pose],
            placement: [p.centre.x, p.centre.y, p.centre.z, p.scale, p.rotation.x, p.rotation.y, p.rotation.z, p.rotation.w],
            view,
        }
    }
}

/// The same look: both eyes within 0.1 mm and about 0.03° of where they
/// were, the canvas where it was, the same view (a tracked head is never
/// exactly still; within this no pixel of a 2064-pixel eye moves).
impl PartialEq for Look {
    fn eq(&self, b: &Look) -> bool {
        let near = |p: &xr::Posef, q: &xr::Posef| {
            let d = (p.position.x - q.position.x).powi(2) + (p.position.y - q.position.y).powi(2) + (p.position.z - q.position.z).powi(2);
            let (o, r) = (p.orientation, q.orientation);
            let dot = (o.x * r.x + o.y * r.y + o.z * r.z + o.w * r.w).abs();
            d < 1e-8 && dot > 1.0 - 1e-7
        };
        near(&self.poses[0], &b.poses[0]) && near(&self.poses[1], &b.poses[1]) && self.placement == b.placement && self.view == b.view
    }
}

/// What a frame shows, gathered by the frame loop.
pub(crate) struct Scene<'a> {
    pub views: &'a [xr::View],
    pub hands: &'a [Hand; 2],
    pub painter: &'a Gestures,
    pub placement: &'a Placement,
    /// What the stroke thread published last.
    pub status: &'a Status,
    pub busy: Option<Indicator>,
    pub doing: Doing,
    pub prepared: &'a Prepared,
    /// Read this frame's eyes back.
    pub capture: bool,
}

/// What drawing a frame gave.
pub(crate) struct Drawn {
    /// Both eyes as drawn (RGB), when captured.
    pub captured: Option<[Vec<u8>; 2]>,
    /// Submit to done for both eyes, ms.
    pub gpu_ms: f64,
}

/// What the frames draw with, kept across them.
pub(crate) struct Drawer {
    blit: Blit,
    hud_ctx: egui::Context,
    hud: egui_wgpu::Renderer,
    pub view: View<Look>,
    lattice: Lattice,
    precision: Precision,
    /// The level of detail of both eyes (spec 7).
    lod: f64,
    /// Both eyes have been cast once (each has a last cast to present).
    cast_once: bool,
}

impl Drawer {
    pub(crate) fn new(renderer: &Renderer, eyes: &Eyes, lattice: Lattice, precision: Precision, lod: f64, view: View<Look>) -> Drawer {
        let blit = Blit::new(&renderer.gpu, eyes.format);
        let hud = egui_wgpu::Renderer::new(&renderer.gpu.device, eyes.format, egui_wgpu::RendererOptions::default());
        Drawer { blit, hud_ctx: egui::Context::default(), hud, view, lattice, precision, lod, cast_once: false }
    }

    /// Draw both eyes into swapchain image `image` (acquired and waited
    /// for) and wait for the GPU.
    pub(crate) fn draw(&mut self, renderer: &mut Renderer, eyes: &Eyes, image: usize, s: &Scene) -> Result<Drawn, XrError> {
        let size = eyes.size;
        let painter = s.painter;
        let placement = s.placement;
        let (lit, grid) = painter.lit_and_grid();
        let mirror = painter.mirror.axes.iter().enumerate().fold(0u8, |m, (a, &on)| m | (u8::from(on) << a));
        // A capture is of the full size, moving or not.
        let planned = self.view.plan(size, Look::new(s.views, placement, (lit, grid)), s.prepared.changed, s.capture, self.cast_once, mirror);
        self.view.log(s.doing, (s.prepared.upload_seconds + s.prepared.g3_seconds) * 1e3);
        let t0 = Instant::now();
        // The indicators, head-locked; the palette at the left hand,
        // where each eye sees it.
        let depth = self.lattice.target_depth(painter.room_radius / placement.scale);
        // The canvas axes as the head sees them (the first eye's pose).
        let axes = octopaint_tree::view::axes_seen_from(placement.rotate_to_canvas(crate::pose_of(&s.views[0].pose).1));
        let st = s.status;
        let hud_status = crate::hud::Status {
            busy: s.busy.clone(),
            in_stroke: painter.in_stroke,
            cells: st.used.min(u64::from(u32::MAX)) as u32,
            capacity: st.capacity,
            bytes: st.bytes,
            painter,
            canvas_per_metre: 1.0 / placement.scale,
            depth,
            edge: self.lattice.size_canvas[depth as usize],
            axes,
            layers: (st.version == 2).then_some((st.layers.as_slice(), st.selected)),
        };
        let mut hud_free = Vec::new();
        let mut captures = Vec::new();
        for (eye, view) in s.views.iter().enumerate().take(2) {
            // Each eye casts into a pixel buffer of its own, kept for the
            // still frames that present it again.
            renderer.ray.cast_into(eye);
            let mut enc = renderer.gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("eye") });
            if planned.cast {
                let camera = eye_camera(placement, view, planned.size);
                // The cut follows the eye's cast size (dynamic resolution).
                let mut params = RayParams::new(&self.lattice, &camera).with_light(lit.then_some(&DEFAULT_LIGHT)).with_lod(&camera, self.lod);
                if grid {
                    params = params.with_grid(camera.eye);
                }
                Frames::encode_cast(renderer, &mut enc, &params, self.precision, s.prepared).map_err(|e| other("ray casting", e))?;
            }
            let gpu = &renderer.gpu;
            // A still frame's size is the full size its last cast had.
            let group = self.blit.bind_scaled(gpu, renderer.ray.pixel_buffer().expect("cast above or before"), planned.size, size);
            let target = eyes.textures[image].create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: eye as u32,
                array_layer_count: Some(1),
                ..Default::default()
            });
            {
                let mut pass = pass_on(&mut enc, &target, wgpu::LoadOp::Clear(wgpu::Color::BLACK));
                self.blit.draw(&mut pass, &group);
            }
            {
                // Only where the eye sees the hand: egui would pull a panel
                // placed off the image back onto its edge.
                let seen = |q: [f32; 2]| (0.0..size[0] as f32).contains(&q[0]) && (0.0..size[1] as f32).contains(&q[1]);
                let palette_at = s.hands[LEFT].pose.and_then(|(p, _)| project(view, size, p)).filter(|&q| seen(q));
                // The brush's ghost at the right controller's tip, where
                // this eye sees it, as wide as the brush there.
                let cursor = s.hands[RIGHT].pose.and_then(|(p, _)| {
                    let centre = project(view, size, p)?;
                    let eye = crate::pose_of(&view.pose).1;
                    let edge = project(view, size, p + eye * DVec3::X * painter.room_radius)?;
                    Some((centre, (edge[0] - centre[0]).hypot(edge[1] - centre[1])))
                });
                let (hud_jobs, hud_screen, free) = crate::hud::prepare(&self.hud_ctx, &mut self.hud, gpu, size, &hud_status, palette_at, cursor);
                hud_free.extend(free);
                self.hud.update_buffers(&gpu.device, &gpu.queue, &mut enc, &hud_jobs, &hud_screen);
                let mut pass = pass_on(&mut enc, &target, wgpu::LoadOp::Load).forget_lifetime();
                self.hud.render(&mut pass, &hud_jobs, &hud_screen);
            }
            if s.capture {
                // The eye's layer of the runtime's image as drawn, then the
                // layer back in the colour-attachment layout the runtime
                // expects at release (an empty pass that loads and stores).
                captures.push(Capture::encode(gpu, &mut enc, &eyes.textures[image], eye as u32, size, eyes.format));
                drop(pass_on(&mut enc, &target, wgpu::LoadOp::Load));
            }
            gpu.queue.submit([enc.finish()]);
        }
        let gpu = &renderer.gpu;
        gpu.wait();
        self.cast_once |= planned.cast;
        for id in &hud_free {
            self.hud.free_texture(id);
        }
        let gpu_ms = t0.elapsed().as_secs_f64() * 1e3;
        self.view.took(&planned, gpu_ms);
        let captured = match captures.as_slice() {
            [a, b] => Some([a.rgb(gpu).map_err(|e| other("reading back", e))?, b.rgb(gpu).map_err(|e| other("reading back", e))?]),
            _ => None,
        };
        Ok(Drawn { captured, gpu_ms })
    }
}

/// Where room point `p` appears in an eye's image (pixels), if in front.
pub(crate) fn project(view: &xr::View, size: [u32; 2], p: DVec3) -> Option<[f32; 2]> {
    let (e, q) = crate::pose_of(&view.pose);
    let v = q.inverse() * (p - e);
    if v.z >= -1e-3 {
        return None;
    }
    let (tx, ty) = (v.x / -v.z, v.y / -v.z);
    let f = view.fov;
    let (l, r, u, d) = (f64::from(f.angle_left).tan(), f64::from(f.angle_right).tan(), f64::from(f.angle_up).tan(), f64::from(f.angle_down).tan());
    Some([((tx - l) / (r - l) * f64::from(size[0])) as f32, ((u - ty) / (u - d) * f64::from(size[1])) as f32])
}

/// A render pass drawing into one eye's layer.
fn pass_on<'a>(enc: &'a mut wgpu::CommandEncoder, target: &wgpu::TextureView, load: wgpu::LoadOp<wgpu::Color>) -> wgpu::RenderPass<'a> {
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("eye"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load, store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// The two eyes side by side (`--capture`).
pub(crate) fn write_side_by_side(path: &std::path::Path, eyes: &[Vec<u8>; 2], size: [u32; 2]) -> std::io::Result<()> {
    let (w, h) = (size[0] as usize, size[1] as usize);
    let mut rgb = vec![0u8; 2 * w * h * 3];
    for (e, img) in eyes.iter().enumerate() {
        for y in 0..h {
            rgb[(y * 2 * w + e * w) * 3..][..w * 3].copy_from_slice(&img[y * w * 3..][..w * 3]);
        }
    }
    octopaint_gpu::image::write_png(path, &rgb, (2 * w) as u32, h as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view_at(x: f32, w: f32) -> xr::View {
        xr::View {
            pose: xr::Posef { orientation: xr::Quaternionf { x: 0.0, y: 0.0, z: 0.0, w }, position: xr::Vector3f { x, y: 0.0, z: 0.0 } },
            fov: xr::Fovf { angle_left: -0.7, angle_right: 0.7, angle_up: 0.7, angle_down: -0.7 },
        }
    }

    #[test]
    fn a_look_is_the_same_within_a_tenth_of_a_millimetre() {
        let p = Placement { centre: DVec3::ZERO, scale: 1.0, rotation: glam::DQuat::IDENTITY, origin: DVec3::ZERO };
        let a = Look::new(&[view_at(0.0, 1.0), view_at(0.064, 1.0)], &p, (true, false));
        let near = Look::new(&[view_at(0.00005, 1.0), view_at(0.06405, 1.0)], &p, (true, false));
        let moved = Look::new(&[view_at(0.001, 1.0), view_at(0.065, 1.0)], &p, (true, false));
        let other_view = Look::new(&[view_at(0.0, 1.0), view_at(0.064, 1.0)], &p, (true, true));
        let placed = Look::new(&[view_at(0.0, 1.0), view_at(0.064, 1.0)], &Placement { scale: 2.0, ..p }, (true, false));
        assert!(a == near);
        assert!(a != moved && a != other_view && a != placed);
    }

    #[test]
    fn a_point_ahead_projects_to_the_image_centre() {
        let v = view_at(0.0, 1.0);
        assert_eq!(project(&v, [100, 80], DVec3::new(0.0, 0.0, -1.0)), Some([50.0, 40.0]));
        assert_eq!(project(&v, [100, 80], DVec3::new(0.0, 0.0, 1.0)), None);
    }
}

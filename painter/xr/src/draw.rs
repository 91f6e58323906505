//! What a VR frame draws with (docs/vr.md): where a room point falls in an
//! eye's image, whether two frames look at the same thing (dynamic
//! resolution casts a still one at full size), a render pass into one
//! eye's layer, and the two eyes side by side for `--capture`.
#![cfg_attr(target_os = "macos", allow(dead_code, unused_imports))]

use glam::DVec3;
use openxr as xr;

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

/// Whether two frames look at the same thing: both eyes within 0.1 mm and
/// about 0.03° of where they were, the canvas where it was, the same view.
pub(crate) fn same_look(a: &([xr::Posef; 2], [f64; 8], (bool, bool)), b: &([xr::Posef; 2], [f64; 8], (bool, bool))) -> bool {
    let near = |p: &xr::Posef, q: &xr::Posef| {
        let d = (p.position.x - q.position.x).powi(2) + (p.position.y - q.position.y).powi(2) + (p.position.z - q.position.z).powi(2);
        let (o, r) = (p.orientation, q.orientation);
        let dot = (o.x * r.x + o.y * r.y + o.z * r.z + o.w * r.w).abs();
        d < 1e-8 && dot > 1.0 - 1e-7
    };
    near(&a.0[0], &b.0[0]) && near(&a.0[1], &b.0[1]) && a.1 == b.1 && a.2 == b.2
}

/// A render pass drawing into one eye's layer.
pub(crate) fn pass_on<'a>(enc: &'a mut wgpu::CommandEncoder, target: &wgpu::TextureView, load: wgpu::LoadOp<wgpu::Color>) -> wgpu::RenderPass<'a> {
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

pub(crate) fn write_side_by_side(path: &std::path::Path, eyes: &[Vec<u8>], size: [u32; 2]) -> std::io::Result<()> {
    let (w, h) = (size[0] as usize, size[1] as usize);
    let mut rgb = vec![0u8; 2 * w * h * 3];
    for (e, img) in eyes.iter().enumerate() {
        for y in 0..h {
            rgb[(y * 2 * w + e * w) * 3..][..w * 3].copy_from_slice(&img[y * w * 3..][..w * 3]);
        }
    }
    octopaint_gpu::image::write_png(path, &rgb, (2 * w) as u32, h as u32)
}

//! The image digest pass (shaders/digest.wgsl) against its CPU port
//! (`digest::rgb_digest`): the same 64 bits for cast images and for
//! synthetic pixel buffers of every shape of dispatch, the alpha byte
//! ignored, and different images told apart.

mod common;

use common::*;
use octopaint_gpu::digest::{ImageDigest, rgb_digest};
use octopaint_gpu::{Backend, Precision};
use octopaint_tree::raycast::RayParams;
use wgpu::util::DeviceExt;

#[test]
fn a_cast_images_digest_is_the_cpu_ports_digest_of_its_pixels() {
    let mut r = renderer(Backend::Vulkan);
    let mut seen = Vec::new();
    for name in ["single_stamp", "shapes_modes"] {
        let (mut painting, camera) = painted(name);
        r.sync(&mut painting.tree).unwrap();
        let params = RayParams::new(&painting.tree.lat, &camera);
        let image = r.cast_params(&params, Precision::F32).unwrap();
        let digest = r.cast_digest(&params, Precision::F32).unwrap();
        assert_eq!(digest, rgb_digest(&image), "{name}");
        seen.push(digest);
    }
    assert_ne!(seen[0], seen[1], "two paintings, one digest");
}

#[test]
fn synthetic_buffers_fold_alike_on_the_gpu_and_the_cpu() {
    let r = renderer(Backend::Vulkan);
    let mut pass = ImageDigest::new(&r.gpu);
    // 1,300,000 pixels need more invocations than the pass dispatches
    // (4,096 workgroups of 256), so each folds several pixels.
    let n = 1_300_000u32;
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let words: Vec<u32> = (0..n)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u32
        })
        .collect();
    let rgb: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()[..3].to_vec()).collect();
    let buf = r.gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("test pixels"),
        contents: bytemuck::cast_slice(&words),
        usage: wgpu::BufferUsages::STORAGE,
    });
    for count in [1u32, 255, 256, 257, 70_001, n] {
        let gpu = pass.digest(&r.gpu, &buf, count).unwrap();
        assert_eq!(gpu, rgb_digest(&rgb[..3 * count as usize]), "{count} pixels");
    }
    // The alpha byte is not part of the image.
    let other_alpha: Vec<u32> = words.iter().map(|w| w ^ 0xff00_0000).collect();
    let buf2 = r.gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("test pixels, other alpha"),
        contents: bytemuck::cast_slice(&other_alpha),
        usage: wgpu::BufferUsages::STORAGE,
    });
    assert_eq!(pass.digest(&r.gpu, &buf2, n).unwrap(), rgb_digest(&rgb));
    // One changed channel of one pixel is a different image.
    let mut changed = words.clone();
    changed[654_321] ^= 0x0001_0000;
    let buf3 = r.gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("test pixels, one changed"),
        contents: bytemuck::cast_slice(&changed),
        usage: wgpu::BufferUsages::STORAGE,
    });
    assert_ne!(pass.digest(&r.gpu, &buf3, n).unwrap(), rgb_digest(&rgb));
    // More pixels than the buffer holds: an error, not a digest of what
    // lies past it.
    assert!(pass.digest(&r.gpu, &buf3, n + 1).is_err());
}

//! A 64-bit digest of a cast image computed on the GPU (shaders/digest.wgsl),
//! so that a benchmark can compare frames with the images it expects without
//! reading them back: the Fig. 9 corruption count captures every frame, and
//! reading back a 2880×1600 image each frame took longer than the frame's
//! ray cast on an H100 (docs/benchmarks-gpu.md).
//!
//! [`rgb_digest`] is the CPU port: the same two words from an image read
//! back as RGB, which the tests hold the shader to.

use bytemuck::{Pod, Zeroable};

use crate::context::{Gpu, GpuError};
use crate::pools::read_through;
use crate::shaders::DIGEST_WGSL;

/// Invocations in a workgroup: the shader's `DIGEST_GROUP`, which must be
/// the same number.
const GROUP: u32 = 256;
/// Workgroups at most; each folds a strided share of the pixels.
const MAX_GROUPS: u32 = 4096;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct DigestParams {
    count: u32,
    stride: u32,
}

/// MurmurHash3's 32-bit finaliser (the shader's `fmix`).
fn fmix(x: u32) -> u32 {
    let mut h = x;
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^= h >> 16;
    h
}

/// One pixel's share of the two words.
fn fold(i: u32, v: u32, (a, b): (u32, u32)) -> (u32, u32) {
    (a ^ fmix(v ^ fmix(i)), b.wrapping_add(fmix(v.wrapping_add(fmix(i ^ 0x9e37_79b9)))))
}

fn join((a, b): (u32, u32)) -> u64 {
    (u64::from(a) << 32) | u64::from(b)
}

/// The digest of an image of `rgb.len() / 3` pixels, 3 sRGB bytes each, row
/// 0 first: what [`ImageDigest::digest`] gives for the same pixels.
pub fn rgb_digest(rgb: &[u8]) -> u64 {
    let mut ab = (0, 0);
    for (i, p) in rgb.chunks_exact(3).enumerate() {
        let v = u32::from(p[0]) | u32::from(p[1]) << 8 | u32::from(p[2]) << 16;
        ab = fold(i as u32, v, ab);
    }
    join(ab)
}

/// The digest pass: its pipeline, and the small buffers it folds into and
/// reads back through (kept between frames).
pub struct ImageDigest {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    folds: wgpu::Buffer,
    readback: wgpu::Buffer,
}

impl ImageDigest {
    pub fn new(gpu: &Gpu) -> ImageDigest {
        let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only }, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("image digest"),
            entries: &[
                storage(0, true),
                storage(1, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
                    count: None,
                },
            ],
        });
        let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("image digest"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module =
            gpu.device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("digest.wgsl"), source: wgpu::ShaderSource::Wgsl(DIGEST_WGSL.into()) });
        let pipeline = gpu.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("image digest"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            cache: None,
        });
        let buffer = |label, size, usage| gpu.device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false });
        let fold_bytes = u64::from(MAX_GROUPS) * 8;
        ImageDigest {
            layout,
            pipeline,
            params: buffer("digest params", 8, wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST),
            folds: buffer("digest folds", fold_bytes, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC),
            readback: buffer("digest read-back", fold_bytes, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST),
        }
    }

    /// The digest of the first `count` pixels of `pixels` (one u32 each,
    /// r | g << 8 | b << 16), after the work already submitted that writes
    /// them. Waits for the GPU; reads back 8 bytes a workgroup.
    pub fn digest(&mut self, gpu: &Gpu, pixels: &wgpu::Buffer, count: u32) -> Result<u64, GpuError> {
        if count == 0 {
            return Ok(join((0, 0)));
        }
        if u64::from(count) * 4 > pixels.size() {
            return Err(GpuError::Readback(format!("a digest of {count} pixels from a buffer of {} bytes", pixels.size())));
        }
        let groups = count.div_ceil(GROUP).min(MAX_GROUPS);
        gpu.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&DigestParams { count, stride: groups * GROUP }));
        let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("image digest"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: pixels.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: self.folds.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: self.params.as_entire_binding() },
            ],
        });
        let mut enc = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("image digest") });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("image digest"), timestamp_writes: None });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(groups, 1, 1);
        }
        gpu.queue.submit([enc.finish()]);
        read_through(gpu, &self.folds, u64::from(groups) * 8, &self.readback, |raw| {
            let ab = raw.chunks_exact(8).fold((0u32, 0u32), |(a, b), w| {
                let x = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
                let y = u32::from_le_bytes([w[4], w[5], w[6], w[7]]);
                (a ^ x, b.wrapping_add(y))
            });
            join(ab)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_changed_byte_or_two_swapped_pixels_change_the_digest() {
        let rgb: Vec<u8> = (0..3 * 1000u32).map(|i| (i * 7 % 251) as u8).collect();
        let d = rgb_digest(&rgb);
        assert_eq!(d, rgb_digest(&rgb.clone()));
        for at in [0, 1, 2, 1500, 2999] {
            let mut c = rgb.clone();
            c[at] ^= 1;
            assert_ne!(rgb_digest(&c), d, "byte {at}");
        }
        let mut swapped = rgb.clone();
        swapped.swap(0, 3);
        swapped.swap(1, 4);
        swapped.swap(2, 5);
        assert_ne!(rgb_digest(&swapped), d);
        assert_ne!(rgb_digest(&rgb[..2997]), d, "a pixel fewer");
    }
}
